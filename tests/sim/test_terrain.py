"""The simulator's terrains: smooth hills of the stated slope, a real DEM's heights where the
DEM has them (carried by pyproj), the lowering, the statistics, and bad DEMs refused."""
import json

import numpy as np
import pytest
import rasterio
from pyproj import Transformer
from rasterio.transform import Affine
from scipy import ndimage

from prismstation.cli import main
from prismstation.sim import geometry as geo
from prismstation.sim import simulate
from prismstation.sim.perturb import truth_geometry
from prismstation.sim.scenario import GEOID, build_scenario
from prismstation.sim.scene_terrain import make_terrain
from prismstation.sim.terrain import cell_centres, inside_polygon

SRTM = "srtm/N44E005.hgt"
PLACE = (5.15, 44.40)        # steep hills at about 600 m


def _n_ground(orbit, view_n, size, h):
    """N's image corners on the ground at ellipsoidal height ``h``."""
    xy = np.array([[0, 0], [size, 0], [size, size], [0, size]], float)
    o, d = geo.pixel_rays(orbit, view_n, xy)
    return geo.ray_at_height(o, d, h)


def _slopes_inside(grid, poly):
    gy, gx = np.gradient(grid.values.astype(float), grid.spacing)
    return np.hypot(gx, gy)[inside_polygon(poly, *cell_centres(grid))]


@pytest.mark.parametrize("size,seeds", [(640, (0, 1, 2, 3)), (2000, (0, 1, 2)), (6000, (5,))])
def test_smooth_terrain_has_the_stated_gentle_slope_and_no_small_relief(size, seeds):
    """Mean slope within 4-8 % over N's footprint (at the grid's own cells, not the 30 m cells
    of the statistics), nothing above 30 %, and no small relief: a 20 m Gaussian moves the
    heights by centimetres (their curvature; the fractal terrain's detail: metres)."""
    for seed in seeds:
        sc = build_scenario(np.random.default_rng(seed), size)
        land = make_terrain(sc, "smooth", np.random.default_rng(50 + seed))
        grid = land.ortho
        poly = _n_ground(sc.orbit, sc.views["N"], size, GEOID + float(np.median(grid.values)))
        s = _slopes_inside(grid, poly)
        assert 0.04 <= s.mean() <= 0.08, (size, seed, s.mean())
        assert np.mean(s > 0.3) == 0.0
        stats = land.info["statistics"]
        assert stats["mean_slope_pct"] == pytest.approx(100 * s.mean(), abs=0.2)
        assert stats["slope_over_30pct_share_pct"] == 0.0
        h = grid.values[inside_polygon(poly, *cell_centres(grid))]
        assert stats["height_min_m"] == pytest.approx(h.min(), abs=0.1)
        assert stats["height_max_m"] == pytest.approx(h.max(), abs=0.1)
        assert grid.values.min() >= 150.0 - 1e-3
        assert land.h_min <= GEOID + grid.values.min() and land.h_max >= GEOID + grid.values.max()
        fine = grid.values - ndimage.gaussian_filter(grid.values.astype(float), 20.0 / grid.spacing)
        assert np.sqrt(np.mean(fine[50:-50, 50:-50] ** 2)) < 0.1
    if size > 640:
        return          # the fractal's detail does not depend on the scene's size
    fractal = make_terrain(sc, "fractal", np.random.default_rng(0)).ortho
    fine = fractal.values - ndimage.gaussian_filter(fractal.values.astype(float), 20.0 / fractal.spacing)
    assert np.sqrt(np.mean(fine[50:-50, 50:-50] ** 2)) > 0.5


@pytest.fixture(scope="module")
def dem_scenes(tmp_path_factory, shared_data):
    """The SRTM tile under steep hills as it is and lowered to half its relief."""
    out = tmp_path_factory.mktemp("dem")
    kw = dict(size=640, seed=3, n_icp=10, n_tie=2, terrain="dem",
              terrain_dem=shared_data / SRTM, terrain_centre=PLACE)
    return (simulate(out / "full", **kw), simulate(out / "half", relief_scale=0.5, **kw),
            shared_data / SRTM)


def _srtm_posts_in_scene(srtm, truth, k=200, seed=0):
    """Posts of the SRTM tile inside N's footprint: (lon, lat, height) of their centres."""
    with rasterio.open(srtm) as ds:
        posts, t = ds.read(1).astype(float), ds.transform
    orbit, views, size = truth_geometry(truth)
    poly = _n_ground(orbit, views["N"], size, GEOID + 1000.0)
    lon_lat = Transformer.from_crs(truth["constants"]["crs"], "EPSG:4326",
                                   always_xy=True).transform(*poly.T)
    c, r = ~t @ lon_lat
    rng = np.random.default_rng(seed)
    cols = rng.integers(int(np.min(c)) + 2, int(np.max(c)) - 2, 4 * k)
    rows = rng.integers(int(np.min(r)) + 2, int(np.max(r)) - 2, 4 * k)
    lon, lat = t @ (cols + 0.5, rows + 0.5)
    e, n = Transformer.from_crs("EPSG:4326", truth["constants"]["crs"],
                                always_xy=True).transform(lon, lat)
    keep = inside_polygon(poly, e, n)[:k * 4]
    return e[keep][:k], n[keep][:k], posts[rows, cols][keep][:k]


def _truth_dem_at(path, e, n):
    with rasterio.open(path) as ds:
        h, t = ds.read(1).astype(float), ds.transform
    c, r = ~t @ (e, n)
    return ndimage.map_coordinates(h, [r - 0.5, c - 0.5], order=1)


def test_dem_terrain_reproduces_the_dem_where_it_has_posts(dem_scenes):
    """The scene sits in the SRTM tile in UTM 31N; the truth DEM (ellipsoidal) at the map
    position pyproj gives each SRTM post is that post's height + the geoid, to centimetres
    (bicubic through the posts, then the truth grid's own 5 m bilinear)."""
    full, _, srtm = dem_scenes
    truth = json.loads(full["truth"].read_text())
    assert truth["constants"]["crs"] == "EPSG:32631"
    scene = json.loads(full["scene"].read_text())
    assert scene["crs"] == "EPSG:32631"
    lon, lat = Transformer.from_crs("EPSG:32631", "EPSG:4326", always_xy=True).transform(
        *truth["constants"]["centre"])
    assert (lon, lat) == pytest.approx(PLACE, abs=2e-5)
    e, n, post = _srtm_posts_in_scene(srtm, truth)
    assert len(post) > 100 and np.ptp(post) > 300           # real relief under the scene
    got = _truth_dem_at(full["truth_dem"], e, n)
    assert np.max(np.abs(got - (post + GEOID))) < 0.1
    # ground points lie on that terrain and their orthometric heights are the DEM's
    pts = truth["points"]
    on = _truth_dem_at(full["truth_dem"], np.array([p["E"] for p in pts]),
                       np.array([p["N"] for p in pts]))
    assert np.allclose(on, [p["h"] for p in pts], atol=1e-3)
    assert all(p["H"] == pytest.approx(p["h"] - GEOID) for p in pts)
    stats = truth["terrain"]["statistics"]
    assert stats["mean_slope_pct"] > 15 and stats["height_max_m"] - stats["height_min_m"] > 300


def test_reference_of_a_dem_scene_is_a_degraded_copy_of_its_terrain(dem_scenes, tmp_path):
    """The SRTM-like reference made from the DEM scene's truth: the same UTM zone, orthometric
    (truth − geoid), the truth's 90 m means plus its 2 m noise."""
    from rasterio.enums import Resampling
    from prismstation.sim.reference import make_reference_dem
    full, _, _ = dem_scenes
    ref = make_reference_dem(full["truth_dem"], tmp_path / "ref.tif", seed=4)
    with rasterio.open(ref) as r, rasterio.open(full["truth_dem"]) as t:
        assert r.crs == t.crs and r.crs.to_epsg() == 32631
        got = r.read(1, masked=True)
        mean = t.read(1, out_shape=got.shape, resampling=Resampling.average).astype(float)
    d = (got.astype(float) - (mean - GEOID))[~got.mask]
    assert got.mask.mean() < 0.1
    assert abs(np.mean(d)) < 0.3 and 1.7 < np.std(d) < 2.4


def test_lowering_scales_heights_about_their_mean(dem_scenes):
    """--relief-scale 0.5: every post's height is m + 0.5 (H − m), m the mean over the ground
    N sees (stored in the truth); range and mean slope halve; same place, same images' grid."""
    full, half, srtm = dem_scenes
    tf, th = (json.loads(p["truth"].read_text()) for p in (full, half))
    m = th["terrain"]["scaled_about_m"]
    sf, sh = tf["terrain"]["statistics"], th["terrain"]["statistics"]
    assert sf["height_min_m"] < m < sf["height_max_m"]
    assert m == pytest.approx(sf["height_mean_m"], abs=1.0)
    e, n, post = _srtm_posts_in_scene(srtm, th)
    got = _truth_dem_at(half["truth_dem"], e, n)
    assert np.max(np.abs(got - (GEOID + m + 0.5 * (post - m)))) < 0.1
    assert sh["height_max_m"] - sh["height_min_m"] == pytest.approx(
        0.5 * (sf["height_max_m"] - sf["height_min_m"]), abs=1.0)
    assert sh["mean_slope_pct"] == pytest.approx(0.5 * sf["mean_slope_pct"], rel=0.03)
    assert th["constants"]["centre"] == tf["constants"]["centre"]


def test_dem_in_other_units_and_crs_gives_the_same_terrain(tmp_path, shared_data):
    """Heights in US feet with a band scale and offset, and the UTM 31N copy of the tile:
    the same terrain in metres as the SRTM tile itself."""
    src = shared_data / SRTM
    with rasterio.open(src) as ds:
        h, profile = ds.read(1).astype(float), ds.profile
    foot = 1200.0 / 3937.0
    stored = (h / foot - 100.0) / 0.5
    feet = tmp_path / "feet.tif"
    profile.update(driver="GTiff", dtype="float32", nodata=None)
    with rasterio.open(feet, "w", **profile) as ds:
        ds.write(stored.astype(np.float32), 1)
        ds.scales, ds.offsets, ds.units = (0.5,), (100.0,), ("US survey foot",)
    kw = dict(size=300, seed=1, n_icp=3, n_tie=0, terrain="dem", terrain_centre=PLACE)
    a = simulate(tmp_path / "m", terrain_dem=src, **kw)
    b = simulate(tmp_path / "ft", terrain_dem=feet, **kw)
    with rasterio.open(a["truth_dem"]) as da, rasterio.open(b["truth_dem"]) as db:
        assert np.max(np.abs(da.read(1) - db.read(1))) < 0.01
    # the UTM copy (90 m posts, resampled once already): the same relief to a few metres
    with rasterio.open(shared_data / "srtm/N44E005_UTM.tif") as ds:
        assert ds.crs.to_epsg() == 32631
    e, n = Transformer.from_crs("EPSG:4326", "EPSG:32631", always_xy=True).transform(*PLACE)
    c = simulate(tmp_path / "utm", terrain_dem=shared_data / "srtm/N44E005_UTM.tif",
                 **dict(kw, terrain_centre=(e, n)))
    ta, tc = (json.loads(p["truth"].read_text())["constants"] for p in (a, c))
    assert ta["crs"] == tc["crs"] == "EPSG:32631" and ta["centre"] == tc["centre"]
    ee, nn = np.meshgrid(e + np.linspace(-300, 300, 25), n + np.linspace(-300, 300, 25))
    d = _truth_dem_at(a["truth_dem"], ee, nn) - _truth_dem_at(c["truth_dem"], ee, nn)
    assert abs(np.median(d)) < 3.0 and np.percentile(np.abs(d), 90) < 25.0


def test_cli_prints_the_terrain_statistics(tmp_path, capsys):
    assert main(["simulate", str(tmp_path / "s"), "--size", "300", "--icp", "3", "--ties", "0",
                 "--quiet", "--terrain", "smooth", "--relief-scale", "0.5"]) == 0
    printed = capsys.readouterr().out.strip().splitlines()[-1]
    terrain = json.loads((tmp_path / "s" / "truth.json").read_text())["terrain"]
    s = terrain["statistics"]
    assert terrain["kind"] == "smooth" and terrain["relief_scale"] == 0.5
    assert s["mean_slope_pct"] == pytest.approx(3.0, abs=0.1)
    assert printed.startswith("terrain smooth") and f"mean slope {s['mean_slope_pct']:.1f} %" in printed


def _bad_files(tmp_path, data):
    text = tmp_path / "notes.tif"
    text.write_text("not a raster\n")
    no_crs = tmp_path / "no_crs.tif"
    with rasterio.open(no_crs, "w", driver="GTiff", width=50, height=50, count=1,
                       dtype="float32", transform=Affine(30, 0, 500000, 0, -30, 4900000)) as ds:
        ds.write(np.ones((50, 50), np.float32), 1)
    furlong = tmp_path / "furlong.tif"
    with rasterio.open(furlong, "w", driver="GTiff", width=50, height=50, count=1,
                       dtype="float32", crs="EPSG:32631",
                       transform=Affine(30, 0, 500000, 0, -30, 4900000)) as ds:
        ds.write(np.ones((50, 50), np.float32), 1)
        ds.units = ("furlong",)
    srtm = str(data / SRTM)
    return [
        ([str(tmp_path / "absent.tif")], "not found"),
        ([str(text)], "cannot open"),
        ([str(no_crs)], "no coordinate reference system"),
        ([str(furlong)], "furlong"),
        ([str(data / "srtm/N44E005_not_void_filled.hgt")], "cannot open"),   # GDAL wants the tile's name
        ([str(data / "srtm/N44E005_big_hole.tif")], "void"),
        ([srtm, "--terrain-centre", "5.01", "44.5"], "does not fit"),
        ([srtm, "--terrain-centre", "7", "44.5"], "outside the DEM"),
        ([srtm, "--terrain", "smooth"], "--terrain dem needs --terrain-dem"),
        ([srtm, "--relief-scale", "0"], "--relief-scale"),
        ([srtm, "--relief-scale", "nan"], "--relief-scale"),
    ]


def test_cli_refuses_bad_terrain_dems_in_one_line(tmp_path, capsys, shared_data):
    cases = _bad_files(tmp_path, shared_data) + [
        (None, "--terrain-centre"), ("dem", "--terrain dem needs")]
    for args, expect in cases:
        if args is None:
            argv = ["--terrain-centre", "5", "44"]
        elif args == "dem":
            argv = ["--terrain", "dem"]
        else:
            argv = ["--terrain-dem"] + args
        out = tmp_path / "out"
        code = main(["simulate", str(out), "--size", "1000", "--quiet"] + argv)
        err = capsys.readouterr().err.strip()
        assert code == 2, (argv, err)
        assert len(err.splitlines()) == 1 and "Traceback" not in err, err
        assert expect in err, (expect, err)
        assert not out.exists()                      # nothing written for a refused terrain
