"""DSM validation statistics (hand computations) and the real SRTM tile in two CRSs."""
import json
import math

import numpy as np
import pytest
import rasterio

from prismstation.cli import main
from prismstation.core.surfaces.dsmstats import residual_sd_by_view, sample_stats, validate_dsm, white_noise_sigma
from prismstation.errors import InputError
from prismstation.io.dem import DemGrid, read_dem, resample_to_grid
from prismstation.io.geoid import undulation_on_grid
from prismstation.ops.coregister import coregister_dems
from prismstation.ops.validate import validate_dsm_files


def test_statistics_by_hand():
    dsm = np.array([[11.0, 12.0, np.nan], [13.0, 14.0, 20.0]])
    ref = np.array([[10.0, 10.0, 10.0], [10.0, 10.0, 10.0]])
    ref[1, 1] = np.nan                          # one more invalid cell
    s = validate_dsm(dsm, ref).overall
    # valid differences: 1, 2, 3, 10
    assert s.count == 4
    assert s.bias == pytest.approx(16 / 4)
    assert s.sd == pytest.approx(math.sqrt(((1 - 4) ** 2 + (2 - 4) ** 2 + (3 - 4) ** 2 + 6 ** 2) / 3))
    assert s.rmse == pytest.approx(math.sqrt((1 + 4 + 9 + 100) / 4))
    assert (s.min, s.max, s.median) == (1.0, 10.0, 2.5)
    # |d − 2.5| = 1.5, 0.5, 0.5, 7.5 → median 1.0
    assert s.nmad == pytest.approx(1.4826 * 1.0)
    # linear-interpolated percentiles of 1, 2, 3, 10: p25 at rank 0.75 → 1.75, p75 at 2.25 → 4.75
    assert s.percentiles[25.0] == pytest.approx(1.75)
    assert s.percentiles[75.0] == pytest.approx(4.75)
    assert s.abs_percentiles[95.0] == pytest.approx(3 + 0.85 * 7)
    assert sample_stats([]).count == 0 and math.isnan(sample_stats([]).bias)


def test_per_class_statistics():
    rng = np.random.default_rng(0)
    d = rng.normal(1.0, 2.0, (40, 50))
    classes = np.zeros((40, 50), int)
    classes[:, 25:] = 3
    classes[:5] = 255
    v = validate_dsm(d, np.zeros_like(d), classes=classes, class_nodata=255)
    assert set(v.per_class) == {0, 3}
    left = d[5:, :25]
    assert v.per_class[0].count == left.size
    assert v.per_class[0].bias == pytest.approx(left.mean())
    assert v.per_class[3].rmse == pytest.approx(np.sqrt(np.mean(d[5:, 25:] ** 2)))
    assert v.overall.count == d.size


def test_residual_sd_per_view_table_1():
    views = ["N", "N", "N", "F", "F", "B", "B", "B", "B"]
    r = np.array([[1, 0], [-1, 2], [0, 1], [0.5, 0.5], [-0.5, 0.5], [1, 1], [2, 1], [3, 1], [2, 5]],
                 float)
    rows = {t.view: t for t in residual_sd_by_view(views, r, scenes=list("aabccddde"))}
    assert list(rows) == ["N", "F", "B"]
    assert rows["N"].n_points == 3 and rows["N"].n_scenes == 2
    assert rows["N"].sd_x == pytest.approx(1.0)                   # 1, −1, 0
    assert rows["N"].sd_y == pytest.approx(1.0)                   # 0, 2, 1
    assert rows["F"].sd_x == pytest.approx(math.sqrt(0.5))        # ±0.5 about 0
    assert rows["F"].sd_y == 0.0
    assert rows["B"].sd_x == pytest.approx(math.sqrt(2 / 3))      # 1, 2, 3, 2
    assert rows["B"].sd_y == pytest.approx(2.0)                   # 1, 1, 1, 5


def _write_like(path, src_path, data):
    with rasterio.open(src_path) as ds:
        prof = ds.profile.copy()
    prof.update(dtype="float32", nodata=-9999.0, driver="GTiff")
    with rasterio.open(path, "w", **prof) as out:
        out.write(np.where(np.isfinite(data), data, -9999.0).astype(np.float32), 1)


def test_known_perturbation_of_a_real_dem(shared_data, tmp_path):
    ref_path = shared_data / "srtm" / "N44E005_UTM.tif"
    ref = read_dem(ref_path).heights
    rows, cols = np.mgrid[0:ref.shape[0], 0:ref.shape[1]]
    shift = 2.0 + 0.01 * cols                  # bias + tilt
    dsm = ref + shift
    dsm[:10] = np.nan                          # a hole
    _write_like(tmp_path / "dsm.tif", ref_path, dsm)
    v, info = validate_dsm_files(tmp_path / "dsm.tif", ref_path)
    valid = np.isfinite(dsm) & np.isfinite(ref)
    d = shift[valid]
    o = v.overall
    assert o.count == valid.sum()
    assert o.bias == pytest.approx(d.mean(), abs=1e-4)
    assert o.sd == pytest.approx(d.std(ddof=1), abs=1e-4)
    assert o.min == pytest.approx(2.0, abs=1e-4) and o.max == pytest.approx(d.max(), abs=1e-4)
    assert o.nmad == pytest.approx(1.4826 * np.median(np.abs(d - np.median(d))), abs=1e-3)
    assert info["grid"]["crs"] == "EPSG:32631"


def test_reference_in_another_crs_and_resolution(shared_data, tmp_path):
    """A smooth analytic surface stored in EPSG:4326 at 3″ lands on the UTM 90 m grid of the
    real tile where the formula says; the real .hgt then agrees with its UTM resampling."""
    from pyproj import Transformer

    dsm_path = shared_data / "srtm" / "N44E005_UTM.tif"
    grid = read_dem(dsm_path)

    def surface(lon, lat):
        return 800 + 300 * np.sin(2 * np.pi * (lon - 5) / 0.4) * np.cos(2 * np.pi * (lat - 44) / 0.3)

    step = 1 / 1200
    lon = 4.9 + (np.arange(1700) + 0.5) * step
    lat = 45.1 - (np.arange(1600) + 0.5) * step
    ref = surface(lon[None, :], lat[:, None]).astype(np.float32)
    with rasterio.open(tmp_path / "geo.tif", "w", driver="GTiff", width=1700, height=1600, count=1,
                       dtype="float32", crs="EPSG:4326",
                       transform=rasterio.transform.Affine(step, 0, 4.9, 0, -step, 45.1)) as ds:
        ds.write(ref, 1)
    on_grid = resample_to_grid(tmp_path / "geo.tif", grid)
    rows, cols = np.mgrid[0:grid.shape[0]:7, 0:grid.shape[1]:7]
    g = grid.transform
    e, n = g.c + (cols + 0.5) * g.a, g.f + (rows + 0.5) * g.e
    lo, la = Transformer.from_crs("EPSG:32631", "EPSG:4326", always_xy=True).transform(e, n)
    got = on_grid[rows, cols]
    ok = np.isfinite(got)
    assert ok.mean() > 0.9
    err = got[ok] - surface(lo[ok], la[ok])
    # 300 m amplitude, slopes up to 6 %: a half-pixel misregistration would give metres
    # (GDAL's approximate transformer and kernel leave < 0.1 px, i.e. < 0.5 m here)
    assert abs(err.mean()) < 0.02 and np.abs(err).max() < 0.6 and np.abs(err).mean() < 0.2
    v, _ = validate_dsm_files(dsm_path, shared_data / "srtm" / "N44E005.hgt")
    assert abs(v.overall.bias) < 0.05
    assert v.overall.count > 0.9 * np.isfinite(grid.heights).sum()
    # The UTM tile is the .hgt resampled by GDAL's default warp (its approximate transformer,
    # 0.125 source pixel, on 83 km rows) and rounded to whole metres: read exactly, the .hgt
    # lies 6 m south of it (±0.9 m), so the difference is more than rounding on the slopes;
    # moved by that shift it is rounding again.
    c = coregister_dems(dsm_path, shared_data / "srtm" / "N44E005.hgt", max_shift_m=100.0)
    assert c.result.dy == pytest.approx(6.2, abs=3 * c.result.sigma_dy) and abs(c.result.dx) < 3 * c.result.sigma_dx
    assert v.overall.rmse > 1.0 and c.result.nmad_after < 0.7


def test_height_kinds_and_geoid(shared_data):
    from prismstation.io.geoid import ConstantGeoid, GridGeoid

    dsm_path = shared_data / "srtm" / "N44E005_UTM.tif"
    base, _ = validate_dsm_files(dsm_path, dsm_path)
    assert base.overall.rmse == 0
    v, info = validate_dsm_files(dsm_path, dsm_path, reference_height="orthometric",
                                 geoid=ConstantGeoid(55.0))
    assert v.overall.bias == pytest.approx(-55.0) and v.overall.sd == pytest.approx(0, abs=1e-9)
    v, _ = validate_dsm_files(dsm_path, dsm_path, dsm_height="orthometric",
                              geoid=ConstantGeoid(55.0))
    assert v.overall.bias == pytest.approx(55.0)
    with pytest.raises(InputError, match="geoid"):
        validate_dsm_files(dsm_path, dsm_path, dsm_height="orthometric")
    geoid = GridGeoid(shared_data / "geoid" / "egm96_15.gtx")
    full = read_dem(dsm_path)
    grid = DemGrid(full.heights[:400, :300], full.crs, full.transform, path=full.path)
    coarse = undulation_on_grid(geoid, grid, max_samples=16)
    exact = undulation_on_grid(geoid, grid, max_samples=1000)      # every cell
    assert np.nanmax(np.abs(coarse - exact)) < 0.02
    assert 45 < np.nanmean(exact) < 55          # EGM96 over Provence


def test_validate_dsm_command(shared_data, tmp_path, capsys):
    dsm_path = shared_data / "srtm" / "N44E005_UTM.tif"
    grid = read_dem(dsm_path)
    mask = np.zeros(grid.shape, np.uint8)
    mask[:, grid.shape[1] // 2:] = 2
    with rasterio.open(tmp_path / "mask.tif", "w", driver="GTiff", width=grid.shape[1],
                       height=grid.shape[0], count=1, dtype="uint8", crs=grid.crs,
                       transform=grid.transform) as ds:
        ds.write(mask, 1)
    out = tmp_path / "v.json"
    rc = main(["validate-dsm", str(dsm_path), str(shared_data / "srtm" / "N44E005.hgt"),
               "--json", str(out), "--mask", str(tmp_path / "mask.tif"),
               "--reference-height", "orthometric", "--geoid-constant", "55",
               "--diff-out", str(tmp_path / "d.tif")])
    assert rc == 0
    d = json.loads(out.read_text())
    for key in ("bias", "sd", "rmse", "min", "max", "count", "nmad"):
        assert key in d
    assert d["bias"] == pytest.approx(-55.0, abs=0.05)
    assert set(d["per_class"]) == {"0", "2"}
    assert d["per_class"]["0"]["count"] + d["per_class"]["2"]["count"] == d["count"]
    diff = read_dem(tmp_path / "d.tif").heights
    assert np.nanmean(diff) == pytest.approx(d["bias"], abs=1e-3)
    assert "bias" in capsys.readouterr().out


def test_validate_dsm_command_bad_input(shared_data, tmp_path, capsys):
    dsm_path = shared_data / "srtm" / "N44E005_UTM.tif"
    (tmp_path / "x.tif").write_text("not a raster")
    cases = [[str(tmp_path / "none.tif"), str(dsm_path)],
             [str(dsm_path), str(tmp_path / "x.tif")],
             [str(dsm_path), str(dsm_path), "--dsm-height", "orthometric"]]
    # a reference that does not overlap the DSM
    with rasterio.open(tmp_path / "far.tif", "w", driver="GTiff", width=10, height=10, count=1,
                       dtype="float32", crs="EPSG:32631",
                       transform=rasterio.transform.Affine(90, 0, 100000, 0, -90, 1000000)) as ds:
        ds.write(np.ones((10, 10), np.float32), 1)
    cases.append([str(dsm_path), str(tmp_path / "far.tif")])
    for args in cases:
        rc = main(["validate-dsm", *args, "--json", str(tmp_path / "o.json")])
        err = capsys.readouterr().err.strip()
        assert rc == 2 and len(err.splitlines()) == 1, err


def test_hillshade_and_histogram_by_hand():
    from prismstation.core.surfaces.dsmstats import hillshade, histogram

    rows, cols = np.mgrid[0:20, 0:30]
    flat = np.zeros((20, 30))
    assert np.allclose(hillshade(flat, 10.0), math.sin(math.radians(45)))
    # a plane rising 1 m per 10 m to the east faces west: lit from the west at 45°, the
    # light meets it 5.7° steeper; lit from the east, 5.7° shallower
    east = cols * 1.0
    slope = math.atan(0.1)
    s = hillshade(east, 10.0, azimuth_deg=270, altitude_deg=45)
    assert np.allclose(s, math.sin(math.radians(45) + slope))
    s = hillshade(east, 10.0, azimuth_deg=90, altitude_deg=45)
    assert np.allclose(s, math.sin(math.radians(45) - slope))
    # rising to the north (row numbers grow southwards), lit from the north
    north = -rows * 1.0
    s = hillshade(north, 10.0, azimuth_deg=0, altitude_deg=45)
    assert np.allclose(s, math.sin(math.radians(45) - slope))
    counts, edges = histogram([0, 1, 1, 2, 2, 2, np.nan], bins=3, clip_percent=0)
    assert list(counts) == [1, 2, 3] and edges[0] == 0 and edges[-1] == 2


def test_a_dems_own_white_noise_is_told_from_its_relief():
    rng = np.random.default_rng(3)
    y, x = np.mgrid[0:300, 0:300].astype(float)
    hills = 500.0 + 40.0 * np.sin(x / 30.0) * np.cos(y / 40.0) + 0.02 * (x - 150.0) ** 2 + 0.3 * y
    assert white_noise_sigma(0.01 * (x - 150.0) ** 2 + 0.5 * x * y + 3.0 * y) == pytest.approx(0.0, abs=1e-9)
    assert white_noise_sigma(hills) < 0.05                        # the hills' own curvature, little
    for sigma in (1.0, 4.0):
        noisy = hills + rng.normal(0.0, sigma, hills.shape)
        assert white_noise_sigma(noisy) == pytest.approx(sigma, rel=0.05)
        # rounded to whole metres (as SRTM stores them): the rounding's 0.29 m adds in quadrature
        assert white_noise_sigma(np.round(noisy)) == pytest.approx(math.hypot(sigma, 12 ** -0.5), rel=0.05)
    # voids and what touches them are left out, and so is flat water (one height); too few
    # cells give NaN
    holes = hills + rng.normal(0.0, 4.0, hills.shape)
    holes[100:200, 50:250] = np.nan
    assert white_noise_sigma(holes) == pytest.approx(4.0, rel=0.05)
    coast = np.round(hills + rng.normal(0.0, 4.0, hills.shape))
    coast[:, :200] = 0.0                                      # two thirds of it sea
    assert white_noise_sigma(coast) == pytest.approx(math.hypot(4.0, 12 ** -0.5), rel=0.07)
    assert np.isnan(white_noise_sigma(hills[:8, :8]))
    # a grid too large to read whole is read in 4 × 4 windows spread over it
    big = np.add.outer(np.linspace(0.0, 300.0, 1500), np.linspace(0.0, 200.0, 1300)) + rng.normal(0.0, 2.0, (1500, 1300))
    assert white_noise_sigma(big) == pytest.approx(2.0, rel=0.03)
