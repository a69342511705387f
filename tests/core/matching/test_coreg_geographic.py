"""`coregister` on DEMs as users have them: the real SRTM tile N44E005 in its native EPSG:4326
grid (.hgt) and in UTM, shifted by known sub-pixel amounts; unrelated DEMs give no result
(exit status 3, a reason, no NaN in the JSON)."""
import json

import numpy as np
import pytest
import rasterio
from scipy import ndimage

from prismstation.cli import main
from prismstation.io.dem import local_metric_transform


def _strict(text):
    def bad(c):
        raise AssertionError(f"{c} in JSON")
    return json.loads(text, parse_constant=bad)


def _shifted(src, dst, dcol, drow, dz, noise=1.5, seed=0):
    """``dst`` = ``src``'s heights with content moved so that the shift laying it back on
    ``src`` is (dcol, drow) px, dz m; the same grid and CRS; float32 GeoTIFF."""
    with rasterio.open(src) as ds:
        h = ds.read(1, masked=True).astype(float).filled(np.nan)
        profile = ds.profile
    h[h <= -32768] = np.nan
    rr, cc = np.mgrid[0:h.shape[0], 0:h.shape[1]].astype(float)
    filled = np.where(np.isfinite(h), h, np.nanmean(h))
    out = ndimage.map_coordinates(filled, [rr + drow, cc + dcol], order=3, mode="constant", cval=np.nan)
    out = out - dz + np.random.default_rng(seed).normal(0, noise, out.shape)
    profile.update(driver="GTiff", dtype="float32", nodata=np.nan)
    with rasterio.open(dst, "w", **profile) as ds:
        ds.write(out.astype(np.float32), 1)
    return dst


@pytest.mark.parametrize("name, dcol, drow, dz", [("N44E005.hgt", 0.37, -0.61, 4.0),
                                                  ("N44E005.hgt", -2.3, 1.45, -12.0),
                                                  ("N44E005_UTM.tif", 0.52, 0.28, 7.0)])
def test_known_shift_recovered_within_its_sigma(shared_data, tmp_path, name, dcol, drow, dz):
    ref = shared_data / "srtm" / name
    dem = _shifted(ref, tmp_path / "dem.tif", dcol, drow, dz)
    out = tmp_path / "shift.json"
    assert main(["coregister", str(ref), str(dem), "--json", str(out)]) == 0
    doc = _strict(out.read_text())
    assert doc["converged"] and doc["reason"] == "" and "nulls" not in doc
    s, sig = doc["shift_px"], doc["sigma_px"]
    for k, want in (("dcol", dcol), ("drow", drow)):
        assert 0 < sig[k] < 0.05
        assert abs(s[k] - want) < 2.5 * sig[k], (k, s[k], want, sig[k])
    assert abs(doc["dz"] - dz) < 2.5 * doc["sigma_dz"] and doc["sigma_dz"] < 1.0
    # metres: east and north in the local frame; 3" of longitude at 44.5° N is 66.3 m
    with rasterio.open(ref) as ds:
        a, b, _, d, e, _ = local_metric_transform(ds.crs, ds.transform, ds.shape)
        geographic = ds.crs.is_geographic
    if geographic:
        assert a == pytest.approx(66.27, abs=0.05) and e == pytest.approx(-92.60, abs=0.05)
        assert abs(doc["shift_crs"]["dx"]) < 1e-2       # degrees
    assert doc["shift_m"]["dx"] == pytest.approx(a * s["dcol"], rel=1e-9)
    assert doc["shift_m"]["dy"] == pytest.approx(e * s["drow"], rel=1e-9)
    assert doc["sigma_m"]["dx"] == pytest.approx(abs(a) * sig["dcol"], rel=1e-6)


def test_formal_sigma_against_empirical_scatter(shared_data):
    """Eight random sub-pixel shifts of random 400² crops of the geographic tile: the
    errors, normalised by their σ, have an RMS at most 1 (σ honest, not optimistic)."""
    from prismstation.core.matching.coreg import coregister
    with rasterio.open(shared_data / "srtm" / "N44E005.hgt") as ds:
        h = ds.read(1).astype(float)
        metric = local_metric_transform(ds.crs, ds.transform, ds.shape)
    h[h <= -32768] = np.nan
    filled = np.where(np.isfinite(h), h, np.nanmean(h))
    rng = np.random.default_rng(4)
    z = []
    for _ in range(8):
        dc, dr = rng.uniform(-2, 2, 2)
        r0, c0 = rng.integers(0, 800, 2)
        rr, cc = np.mgrid[r0:r0 + 400, c0:c0 + 400].astype(float)
        dem = ndimage.map_coordinates(filled, [rr + dr, cc + dc], order=3) + rng.normal(0, 2, rr.shape)
        r = coregister(h[r0:r0 + 400, c0:c0 + 400], dem, metric)
        assert r.converged
        z.append([(r.dcol - dc) / r.sigma_dcol, (r.drow - dr) / r.sigma_drow])
    rms = np.sqrt(np.mean(np.square(z), axis=0))
    assert np.all(rms < 1.0) and np.all(rms > 0.05), rms


@pytest.mark.parametrize("other", ["flipped", "noise"])
def test_unrelated_dems_exit_nonzero_with_a_reason(shared_data, tmp_path, capsys, other):
    from rasterio.windows import Window
    with rasterio.open(shared_data / "srtm" / "N44E005.hgt") as ds:   # a 400² geographic crop
        win = Window(500, 300, 400, 400)
        h = ds.read(1, window=win).astype(float)
        profile = dict(ds.profile, width=400, height=400, transform=ds.window_transform(win))
    h[h <= -32768] = np.nan
    profile.update(driver="GTiff", dtype="float32", nodata=np.nan)
    ref = tmp_path / "ref.tif"
    with rasterio.open(ref, "w", **profile) as ds:
        ds.write(h.astype(np.float32), 1)
    if other == "flipped":
        u = h[::-1, ::-1]
    else:
        u = ndimage.gaussian_filter(np.random.default_rng(1).normal(0, 1, h.shape), 8)
        u = 600 + u / u.std() * np.nanstd(h)
    dem = tmp_path / "other.tif"
    with rasterio.open(dem, "w", **profile) as ds:
        ds.write(u.astype(np.float32), 1)
    out = tmp_path / "shift.json"
    capsys.readouterr()
    assert main(["coregister", str(ref), str(dem), "--json", str(out)]) == 3
    err = capsys.readouterr().err
    assert "no shift" in err and len(err.strip().splitlines()) == 1
    doc = _strict(out.read_text())
    assert doc["converged"] is False and doc["reason"]
    for key, why in doc.get("nulls", {}).items():
        assert why


def test_a_priori_bound_is_a_setting(shared_data, tmp_path):
    """A 6-pixel (400 m) shift is found with the default bound and refused, with its reason,
    under a 150 m a-priori bound."""
    ref = shared_data / "srtm" / "N44E005_UTM.tif"
    dem = _shifted(ref, tmp_path / "dem.tif", 4.4, -4.6, 0.0)
    out = tmp_path / "s.json"
    assert main(["coregister", str(ref), str(dem), "--json", str(out)]) == 0
    assert _strict(out.read_text())["shift_px"]["dcol"] == pytest.approx(4.4, abs=0.05)
    assert main(["coregister", str(ref), str(dem), "--json", str(out), "--max-shift-m", "150"]) == 3
    assert "a-priori" in _strict(out.read_text())["reason"]
    assert main(["coregister", str(ref), str(dem), "--max-shift-m", "-1"]) == 2
