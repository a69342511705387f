"""A geographic DEM and the same surface on a UTM grid agree where they are: read onto each
other's grid (``read_dem``), co-registered (``coregister``) and validated (``validate-dsm``),
at latitudes 0–70° and at the edges of a UTM zone, to 0.05 of a 30 m cell (1.5 m).

GDAL's default approximate transformer (0.125 source pixel) laid a 3″ grid about 6 m north
on a 21 km UTM grid at 41° N: every case here off the equator failed so.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from prismstation.cli import main
from prismstation.io.dem import read_dem
from prismstation.io.reproject import ERROR_PX, grid_pixels, warp_array
from prismstation.ops.coregister import coregister_dems
from prismstation.ops.validate import validate_dsm_files
from prismstation.sim.hills import PLACES, TOLERANCE_M, UTM31, Place, shift_m, surface, write

#: the costlier checks (whole coregistrations, whole validations) at a zone's edge low, mid and
#: high (GDAL's default fails them at 41° and 70°); the warp itself is checked at every place
EDGES = [(0.0, 2.95), (41.0, 2.95), (70.0, -2.95)]


@pytest.mark.parametrize("lat,dlon", PLACES)
def test_warp_finds_every_target_cell_where_pyproj_puts_it(lat, dlon):
    """The source's own column and row numbers, warped bilinearly (exact on a linear ramp),
    are where the warp took each target cell from: within ERROR_PX of pyproj's answer."""
    p = Place(lat, dlon)
    rows, cols = np.mgrid[0:p.geo_shape[0], 0:p.geo_shape[1]] + 0.5
    got = [warp_array(v, "EPSG:4326", p.geo_t, UTM31, p.utm_t, p.utm_shape) for v in (cols, rows)]
    want = grid_pixels(*p.utm_en(), UTM31, "EPSG:4326", p.geo_t)
    for g, w in zip(got, want):
        inner = np.isfinite(g)
        inner[:2], inner[-2:], inner[:, :2], inner[:, -2:] = False, False, False, False
        assert inner.mean() > 0.9
        assert np.abs(g - w)[inner].max() <= ERROR_PX + 1e-6


@pytest.mark.parametrize("lat,dlon", PLACES)
def test_read_dem_lays_each_grid_on_the_other_where_it_is(tmp_path, lat, dlon):
    p = Place(lat, dlon).write(tmp_path)
    on_utm = read_dem(p.geo, UTM31, p.utm_t, p.utm_shape).heights
    s = shift_m(on_utm, *p.utm_en(), p.truth)
    assert np.hypot(*s) <= TOLERANCE_M, s
    on_geo = read_dem(p.utm, "EPSG:4326", p.geo_t, p.geo_shape).heights
    s = shift_m(on_geo, *p.geo_en(), p.truth)
    assert np.hypot(*s) <= TOLERANCE_M, s


@pytest.mark.parametrize("lat,dlon", EDGES)
def test_coregister_finds_no_shift_between_the_two_grids(tmp_path, lat, dlon):
    p = Place(lat, dlon).write(tmp_path)
    for ref, dem in ((p.utm, p.geo), (p.geo, p.utm)):
        c = coregister_dems(ref, dem, max_shift_m=100.0)
        assert c, c.reason
        assert np.hypot(c.result.dx, c.result.dy) <= TOLERANCE_M, (ref.name, c.result)


@pytest.mark.parametrize("lat,dlon", EDGES)
def test_validate_dsm_compares_each_cell_with_the_same_ground(tmp_path, lat, dlon):
    p = Place(lat, dlon).write(tmp_path)
    diff = tmp_path / "diff.tif"
    for dsm, ref, en in ((p.utm, p.geo, p.utm_en()), (p.geo, p.utm, p.geo_en())):
        validate_dsm_files(dsm, ref, diff_out=diff)
        d = read_dem(diff).heights          # DSM − reference: the truth minus the reference moved
        s = shift_m(p.truth(*en)[0] - d, *en, p.truth)
        assert np.hypot(*s) <= TOLERANCE_M, (dsm.name, s)


def test_the_foreign_scenes_two_exact_terrains_agree(foreign_data, tmp_path):
    """The true terrain of another simulator's scene on its 3″ reference grid and on a 30 m UTM
    grid: one surface, so reading, co-registering and validating find no shift."""
    d = foreign_data / "smooth_hills_10km"
    geo, utm = d / "reference_exact_3arcsec.tif", d / "terrain_utm30.tif"
    if not (geo.is_file() and utm.is_file()):
        pytest.skip("the foreign scene's exact terrains are not there")
    u = read_dem(utm)
    on_utm = read_dem(geo, u.crs, u.transform, u.shape).heights
    gn, ge = np.gradient(u.heights, u.transform.e, u.transform.a)

    def truth(e, n):
        return u.heights, ge, gn
    assert np.hypot(*shift_m(on_utm, None, None, truth, margin=5)) <= TOLERANCE_M

    out = tmp_path / "c.json"
    assert main(["coregister", str(utm), str(geo), "--json", str(out)]) == 0
    c = json.loads(out.read_text())
    assert abs(c["shift_m"]["dx"]) <= c["sigma_m"]["dx"] and abs(c["shift_m"]["dy"]) <= c["sigma_m"]["dy"], c

    assert main(["validate-dsm", str(utm), str(geo), "--json", str(tmp_path / "v.json"),
                 "--diff-out", str(tmp_path / "diff.tif")]) == 0
    diff = read_dem(tmp_path / "diff.tif").heights
    assert np.hypot(*shift_m(-diff, None, None, lambda e, n: (0 * diff, ge, gn), margin=5)) <= TOLERANCE_M
