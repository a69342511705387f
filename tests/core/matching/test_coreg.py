"""DEM co-registration against known shifts of the real SRTM tile, and the affine shift field."""
import json

import numpy as np
import pytest
import rasterio
from scipy import ndimage

from prismstation.cli import main
from prismstation.core.matching.coreg import coregister, shift_grid
from prismstation.core.orientation.shift_field import fit_shift_field


@pytest.fixture(scope="module")
def tile(shared_data):
    with rasterio.open(shared_data / "srtm" / "N44E005_UTM.tif") as ds:
        h = ds.read(1).astype(float)
        h[h == ds.nodata] = np.nan
        return h, ds.transform, ds.crs, ds.profile


def moved(h, dcol, drow, dz, noise=0.0, seed=0):
    """A DEM whose content sits (dcol, drow) px left/up of the reference's: dem(c, r) = h(c+dcol, r+drow) - dz."""
    rr, cc = np.mgrid[0:h.shape[0], 0:h.shape[1]].astype(float)
    filled = np.where(np.isfinite(h), h, np.nanmean(h))
    out = ndimage.map_coordinates(filled, [rr + drow, cc + dcol], order=3, mode="constant", cval=np.nan)
    void = ndimage.map_coordinates(np.isnan(h).astype(float), [rr + drow, cc + dcol], order=1,
                                   mode="constant", cval=1.0) > 0
    out[void] = np.nan
    return out - dz + np.random.default_rng(seed).normal(0, noise, out.shape)


@pytest.mark.parametrize("method", ["lsm", "nuth-kaab"])
def test_cli_sign_convention_on_an_integer_shifted_tile(tile, tmp_path, method):
    h, transform, crs, profile = tile
    # content 3 columns left of and 5 rows above where the reference has it, 10 m low
    dem = np.full_like(h, np.nan)
    dem[:-5, :-3] = h[5:, 3:] - 10.0
    profile = dict(profile, dtype="float32", nodata=np.nan)
    ref_path, dem_path = tmp_path / "ref.tif", tmp_path / "dem.tif"
    with rasterio.open(ref_path, "w", **profile) as ds:
        ds.write(h.astype(np.float32), 1)
    with rasterio.open(dem_path, "w", **profile) as ds:
        ds.write(dem.astype(np.float32), 1)
    out = tmp_path / "shift.json"
    assert main(["coregister", str(ref_path), str(dem_path), "--json", str(out),
                 "--method", method]) == 0
    doc = json.loads(out.read_text())
    assert doc["shift_px"]["dcol"] == pytest.approx(3.0, abs=0.02)
    assert doc["shift_px"]["drow"] == pytest.approx(5.0, abs=0.02)
    assert doc["shift_crs"]["dx"] == pytest.approx(3 * 90.0, abs=1.0)     # east
    assert doc["shift_crs"]["dy"] == pytest.approx(-5 * 90.0, abs=1.0)    # rows go south
    assert doc["dz"] == pytest.approx(10.0, abs=0.05)
    for key in ("sigma_px", "sigma_crs"):
        assert all(0 <= v < 0.1 * (90 if key == "sigma_crs" else 1) for v in doc[key].values())
    assert 0 <= doc["sigma_dz"] < 0.5


@pytest.mark.parametrize("dcol, drow, dz", [(0.3, -0.45, 2.0), (-6.7, 4.2, -25.0)])
def test_known_subpixel_and_multipixel_shifts_with_noise_and_voids(tile, dcol, drow, dz):
    h, transform, _, _ = tile
    ref = h[300:800, 200:700].copy()
    dem = moved(h, dcol, drow, dz, noise=3.0)[300:800, 200:700]
    dem[100:160, 50:140] = np.nan                       # a void
    r = coregister(ref, dem, tuple(transform)[:6])
    assert r.converged
    assert r.dcol == pytest.approx(dcol, abs=0.03)      # 0.03 px = 2.7 m
    assert r.drow == pytest.approx(drow, abs=0.03)
    assert r.dz == pytest.approx(dz, abs=0.3)
    assert r.dx == pytest.approx(90 * r.dcol) and r.dy == pytest.approx(-90 * r.drow)
    assert r.nmad_after < 5.0 < r.nmad_before
    assert r.sigma_dcol > 0 and r.sigma_dz > 0


def test_shift_grid_matches_slicing_and_linear_interpolation():
    a = np.arange(60, dtype=float).reshape(6, 10)          # linear in col and row
    s = shift_grid(a, 2, 1)
    assert np.array_equal(s[1:, 2:], a[:-1, :-2]) and np.isnan(s[0]).all()
    s = shift_grid(a, 0.25, -0.5)                          # out(c, r) = a(c - 0.25, r + 0.5)
    assert s[2, 4] == pytest.approx(a[2, 4] - 0.25 + 0.5 * 10)


def test_affine_shift_field_recovers_a_known_field():
    rng = np.random.default_rng(3)
    x, y = rng.uniform(0, 8000, 30), rng.uniform(0, 8000, 30)
    truth = np.array([[12.0, 1e-3, -2e-3], [-40.0, 5e-4, 1e-3], [3.0, 0.0, 2e-4]])
    shifts = truth[:, 0] + np.outer(x, truth[:, 1]) + np.outer(y, truth[:, 2])
    noisy = shifts + rng.normal(0, 0.5, shifts.shape)
    f = fit_shift_field(x, y, noisy, sigmas=np.full(shifts.shape, 0.5))
    A = np.column_stack([np.ones_like(x), x, y])
    for k in range(3):                                     # independent reference: plain lstsq
        p, *_ = np.linalg.lstsq(A, noisy[:, k], rcond=None)
        assert f.params[k] == pytest.approx(p, rel=1e-6, abs=1e-9)
        v = noisy[:, k] - A @ p
        cov = (v @ v) / (30 - 3) * np.linalg.inv(A.T @ A)
        assert f.component_cov[k] == pytest.approx(cov, rel=1e-6, abs=1e-15)
    assert np.abs(f.predict(x, y) - shifts).max() < 1.0
    assert f.predict_sigma(4000.0, 4000.0).shape == (3,)
    with pytest.raises(ValueError):
        fit_shift_field([0, 1, 2], [0, 1, 2], np.zeros((3, 3)))


@pytest.mark.parametrize("dcol, drow, dz", [(0.3, -0.45, 2.0), (-4.4, 2.6, 12.0)])
def test_nuth_kaab_finds_the_same_known_shifts(tile, dcol, drow, dz):
    from prismstation.core.matching.coreg import nuth_kaab
    h, transform, _, _ = tile
    ref = h[300:800, 200:700].copy()
    dem = moved(h, dcol, drow, dz, noise=3.0, seed=1)[300:800, 200:700]
    r = nuth_kaab(ref, dem, tuple(transform)[:6])
    assert r.converged
    assert r.dcol == pytest.approx(dcol, abs=0.05)
    assert r.drow == pytest.approx(drow, abs=0.05)
    assert r.dz == pytest.approx(dz, abs=0.5)
    assert r.sigma_dcol > 0 and r.sigma_dz > 0


def test_cli_fine_dem_on_its_own_grid_against_the_90m_reference(tile, tmp_path):
    """A 30 m DEM of a 27 km square, content 50 m east and 30 m south of the reference's,
    7 m low: it must be laid on the reference by dx = -50 m, dy = +30 m, dz = +7 m."""
    from rasterio.transform import from_origin

    from prismstation.io.dem import write_dem
    h, transform, crs, profile = tile
    r0, c0, n = 400, 300, 300                       # reference crop (90 m cells)
    ref = h[r0:r0 + n, c0:c0 + n]
    ref_t = transform * transform.translation(c0, r0)
    ref_path = tmp_path / "ref.tif"
    write_dem(ref_path, ref, crs, ref_t)
    e0, n0 = ref_t * (50, 50)                        # DEM grid: 900 x 900 cells of 30 m
    dem_t = from_origin(e0, n0, 30.0, 30.0)
    rows, cols = np.mgrid[0:900, 0:900].astype(float)
    E, N = dem_t * (cols + 0.5, rows + 0.5)
    col, row = ~ref_t * (E - 50.0, N + 30.0)         # where the reference has this content
    filled = np.where(np.isfinite(ref), ref, np.nanmean(ref))   # a few voids in the crop
    dem = ndimage.map_coordinates(filled, [row - 0.5, col - 0.5], order=3, mode="nearest") - 7.0
    dem_path = tmp_path / "dem.tif"
    write_dem(dem_path, dem, crs, dem_t)
    out = tmp_path / "shift.json"
    assert main(["coregister", str(ref_path), str(dem_path), "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc["shift_crs"]["dx"] == pytest.approx(-50.0, abs=3.0)
    assert doc["shift_crs"]["dy"] == pytest.approx(30.0, abs=3.0)
    assert doc["shift_px"]["dcol"] == pytest.approx(-50 / 90, abs=0.035)
    assert doc["shift_px"]["drow"] == pytest.approx(-30 / 90, abs=0.035)
    assert doc["dz"] == pytest.approx(7.0, abs=0.5)
