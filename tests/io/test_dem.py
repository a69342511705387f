"""Reading reference DEMs onto a grid, voids, geoid conversion, GeoTIFF writing (io.dem)."""
import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

from prismstation.io.dem import grid_coordinates, read_dem, write_dem
from prismstation.io.geoid import to_ellipsoidal


def test_hgt_resampled_to_utm_agrees_with_the_independent_utm_product(shared_data):
    utm = read_dem(shared_data / "srtm" / "N44E005_UTM.tif")
    assert str(utm.crs) == "EPSG:32631" and utm.height_kind == "orthometric"
    geo = read_dem(shared_data / "srtm" / "N44E005.hgt", utm.crs, utm.transform, utm.shape)
    d = geo.heights - utm.heights
    both = np.isfinite(d)
    assert both.mean() > 0.9
    # CNES resampled the same tile, by GDAL's approximate warp: 6 m north of it, hence 1.5 m SD
    assert abs(np.mean(d[both])) < 0.5 and np.std(d[both]) < 2.0
    assert np.isnan(utm.heights).any() and not (utm.heights == -32768).any()
    # Mont Ventoux summit (44.1741 N, 5.2789 E, 1909 m) is the highest cell around it
    from pyproj import Transformer
    x, y = Transformer.from_crs("EPSG:4326", utm.crs, always_xy=True).transform(5.2789, 44.1741)
    col, row = ~utm.transform * (x, y)
    around = utm.heights[int(row) - 2:int(row) + 3, int(col) - 2:int(col) + 3]
    assert 1850 < np.nanmax(around) < 1925
    # the grid says what detail it can hold: 3″ cells at 44.5° N, whatever grid they are read onto
    dx, dy = geo.source_cell_m
    assert dx == pytest.approx(3 / 3600 * 111_320 * np.cos(np.radians(44.5)), rel=0.01)   # m per degree
    assert dy == pytest.approx(92.5, abs=0.5)
    assert utm.source_cell_m == pytest.approx((abs(utm.transform.a), abs(utm.transform.e)))
    # and where its own posts are, and their own noise: the real tile's 3″ posts hold 1.6 m of
    # white noise by Immerkær's estimator (its relief counts as noise where finer than 3 cells)
    assert str(geo.source_crs) == "EPSG:4326" and geo.source_transform.a == pytest.approx(3 / 3600)
    assert 1.0 < geo.source_noise_m < 2.5
    t = geo.source_transform
    cx, cy = t.c + 600.5 * t.a + 300.5 * t.b, t.f + 600.5 * t.d + 300.5 * t.e      # a post: a cell's centre
    e, n = Transformer.from_crs("EPSG:4326", utm.crs, always_xy=True).transform(cx, cy)
    assert geo.source_pixels(np.array([[e, n]]))[:, 0] == pytest.approx([600.5, 300.5], abs=1e-6)


def test_voids_become_nan_and_stay_out_of_the_resampled_grid(tmp_path):
    h = np.full((50, 50), 500, np.int16)
    h[20:30, 20:30] = -32768
    p = tmp_path / "void.tif"
    with rasterio.open(p, "w", driver="GTiff", width=50, height=50, count=1, dtype="int16",
                       crs="EPSG:32631", transform=from_origin(600000, 5000000, 90, 90)) as ds:
        ds.write(h, 1)
    g = read_dem(p)
    assert np.isnan(g.heights[20:30, 20:30]).all() and (g.heights[:10] == 500).all()
    g2 = read_dem(p, "EPSG:32631", from_origin(600000, 5000000, 45, 45), (100, 100))
    assert np.isnan(g2.heights[44:56, 44:56]).all()
    assert np.nanmax(g2.heights) == pytest.approx(500) and np.nanmin(g2.heights) == pytest.approx(500)


class FakeGeoid:
    def undulation(self, E, N, crs):
        return 50.0 + 1e-3 * (np.asarray(E) - 600000.0)


def test_to_ellipsoidal_with_constant_and_with_a_geoid_object(tmp_path):
    assert to_ellipsoidal(np.array([100.0, np.nan]), 55.0)[0] == 155.0
    t = from_origin(600000, 5000000, 100, 100)
    E, N = grid_coordinates(t, (2, 3))
    assert E[0, 0] == 600050 and N[0, 0] == 4999950 and E[1, 2] == 600250
    h = to_ellipsoidal(np.zeros((2, 3)), FakeGeoid(), E, N, "EPSG:32631")
    assert h[0, 0] == pytest.approx(50.05) and h[0, 2] == pytest.approx(50.25)
    p = tmp_path / "d.tif"
    write_dem(p, np.zeros((2, 3)), "EPSG:32631", t)
    g = read_dem(p, geoid=FakeGeoid())
    assert g.height_kind == "ellipsoidal" and g.heights[1, 2] == pytest.approx(50.25)


def test_a_dem_stating_ellipsoidal_heights_goes_through_no_geoid(tmp_path):
    """A reference whose file says its heights are ellipsoidal (a DSM of our own: its HEIGHTS
    tag) is read as it is, whatever the project's geoid; one that says nothing is orthometric."""
    t = from_origin(600000, 5000000, 100, 100)
    stated, plain = tmp_path / "e.tif", tmp_path / "o.tif"
    write_dem(plain, np.full((2, 3), 100.0), "EPSG:32631", t)
    write_dem(stated, np.full((2, 3), 100.0), "EPSG:32631", t)
    with rasterio.open(stated, "r+") as ds:
        ds.update_tags(HEIGHTS="ellipsoidal")
    assert read_dem(plain, geoid=50.0).heights[0, 0] == 150.0
    g = read_dem(stated, geoid=50.0)
    assert g.height_kind == "ellipsoidal" and g.heights[0, 0] == 100.0


def test_write_dem_round_trip_float32_nan(tmp_path):
    h = np.random.default_rng(0).normal(800, 100, (300, 280))
    h[5, 7] = np.nan
    p = tmp_path / "dem.tif"
    write_dem(p, h, "EPSG:32629", from_origin(500000, 4600000, 2.5, 2.5))
    with rasterio.open(p) as ds:
        assert ds.dtypes[0] == "float32" and np.isnan(ds.nodata)
        assert ds.transform == from_origin(500000, 4600000, 2.5, 2.5)
    g = read_dem(p)
    assert np.isnan(g.heights[5, 7])
    assert np.allclose(g.heights, h.astype(np.float32), equal_nan=True)


def test_fine_dem_is_averaged_onto_a_coarse_grid(tmp_path):
    # 10 m checkerboard of 0 / 100 m: averaged onto 90 m cells it is 50 m almost everywhere,
    # point-sampled (bilinear) it would be 0 or 100
    rows, cols = np.mgrid[0:270, 0:270]
    h = np.where((rows + cols) % 2 == 0, 0.0, 100.0)
    p = tmp_path / "fine.tif"
    write_dem(p, h, "EPSG:32631", from_origin(600000, 5000000, 10, 10))
    g = read_dem(p, "EPSG:32631", from_origin(600000, 5000000, 90, 90), (3, 3))
    assert np.allclose(g.heights, 50.0, atol=1.0)

