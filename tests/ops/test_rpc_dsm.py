"""The RPC DSM and the orientation from a reference DEM on a synthetic triplet over a known
terrain (forward, nadir and backward views with cubic RPCs, rendered by ray casting), and the
orientation over real relief (SRTM around Mont Ventoux) where the shared data are present."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import rasterio

from prismstation.core.models.rpc_bias import BiasedRpc, metres_per_degree
from prismstation.core.adjustment.stats import nmad
from prismstation.errors import Cancelled, InputError
from prismstation.io.dsm import read_dsm_info, write_dsm
from prismstation.io.rpc_scene import to_lonlat
from prismstation.ops.rpc_dsm import Grid, rpc_dsm, tile_height_range
from prismstation.ops.rpc_orient import orient_from_reference, orient_rpc_from_dem
from tests.ops.rpc_synth import World, analytic_terrain, dem_terrain, make_rpc, render, write_image

LON0, LAT0 = 5.27, 44.17
SIZE, GSD = 300, 4.0
TANS = (0.15, 0.0, -0.15)           # B/H 0.15 (F–N, N–B) and 0.3 (F–B)
SHIFT = np.array([14.0, -9.0, 4.0])  # a block's ground error (E, N, U m) for the orientation


def truth_diff(dsm, world):
    E, N = np.meshgrid(dsm.transform[2] + dsm.transform[0] * (np.arange(dsm.heights.shape[1]) + 0.5),
                       dsm.transform[5] + dsm.transform[4] * (np.arange(dsm.heights.shape[0]) + 0.5))
    lon, lat = to_lonlat(dsm.crs)(E, N)
    return dsm.heights - world.height(lon, lat)


def triplet(tmp_path_factory, world, name):
    d = tmp_path_factory.mktemp(name)
    rpcs, paths = [], []
    for k, t in enumerate(TANS):
        rpc = make_rpc(LON0, LAT0, gsd=GSD, size=SIZE, tan_along=t, h_off=world.h_off,
                       h_scale=world.h_scale, seed=k + 1)
        write_image(d / f"img{k}.tif", render(rpc, world, SIZE))
        rpcs.append(rpc)
        paths.append(d / f"img{k}.tif")
    return world, rpcs, paths


def write_reference(path, world, half_deg=0.012, step=1 / 3600, lon0=LON0):
    """The world's terrain as a 1″ geographic GeoTIFF (~22 × 31 m cells) centred at
    ``(lon0, LAT0)``; its heights are the RPCs', ellipsoidal, and the file says so (a new
    project reads an unstated reference through the EGM96 grid)."""
    n = int(2 * half_deg / step)
    lon = lon0 - half_deg + step * (np.arange(n) + 0.5)
    lat = LAT0 + half_deg - step * (np.arange(n) + 0.5)
    L, P = np.meshgrid(lon, lat)
    with rasterio.open(path, "w", driver="GTiff", width=n, height=n, count=1, dtype="float32",
                       crs="EPSG:4326", transform=rasterio.Affine(step, 0, lon0 - half_deg, 0, -step,
                                                                  LAT0 + half_deg)) as ds:
        ds.write(world.height(L, P).astype(np.float32), 1)
        ds.update_tags(HEIGHTS="ellipsoidal")


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    world = World(LON0, LAT0, analytic_terrain, extent_m=2400, texture_cell_m=2.0)
    world.h_off, world.h_scale = 400.0, 500.0
    return triplet(tmp_path_factory, world, "rpc_triplet")


def test_pair_dsm_finds_the_terrain(synthetic):
    world, rpcs, paths = synthetic
    dsm, pairs = rpc_dsm(paths, rpcs, pairs=[(0, 2)], posting=8.0, height_range=(200.0, 700.0))
    d = truth_diff(dsm, world)
    assert dsm.height_kind == "ellipsoidal" and dsm.crs == "EPSG:32631"
    assert dsm.valid_fraction > 0.85
    # in disparity pixels (B/H 0.3, 4 m pixels): no offset, a tenth of a pixel of scatter
    px = 0.3 / GSD
    assert abs(np.nanmedian(d)) * px < 0.03 and nmad(d) * px < 0.15
    # the σ the pair claims covers its errors (the σ is of a real SGBM disparity: 0.45 px)
    z = d / pairs[0].sigma
    assert 0.2 < nmad(z) < 1.3


def test_a_reference_dem_narrows_the_search(synthetic, tmp_path):
    """Without tie points, a reference DEM's heights ± 40 m set each tile's range (the
    terrain spans 250–600 m; the RPCs' domain −100–900 m)."""
    world, rpcs, paths = synthetic
    write_reference(tmp_path / "ref.tif", world)
    dsm, pairs = rpc_dsm(paths, rpcs, pairs=[(0, 2)], posting=8.0, reference=tmp_path / "ref.tif")
    for t in pairs[0].tiles:
        lo, hi = t["height_range"]
        assert lo > 150 and hi < 700 and hi - lo < 400
    d = truth_diff(dsm, world)
    assert dsm.valid_fraction > 0.85 and abs(np.nanmedian(d)) < 0.4


def test_the_fitted_bias_is_applied(synthetic):
    """An image whose RPC is 2 px off along its lines: the raw RPC puts the DSM metres too
    high or low; the same RPC with the bias that undoes it finds the terrain."""
    world, rpcs, paths = synthetic
    wrong = rpcs[2].shifted(dy=2.0)
    fixed = BiasedRpc(wrong, "shift", np.array([0.0, -2.0]), 150.0, 150.0)
    raw, _ = rpc_dsm(paths, [rpcs[0], rpcs[1], wrong], pairs=[(0, 2)], posting=8.0, height_range=(200.0, 700.0))
    good, _ = rpc_dsm(paths, [rpcs[0], rpcs[1], fixed], pairs=[(0, 2)], posting=8.0, height_range=(200.0, 700.0))
    # 2 px × GSD / (B/H) = 2 × 4 / 0.3 ≈ 27 m
    assert abs(np.nanmedian(truth_diff(raw, world))) > 15.0
    assert abs(np.nanmedian(truth_diff(good, world))) < 0.3


def test_three_pairs_fused(synthetic):
    world, rpcs, paths = synthetic
    dsm, pairs = rpc_dsm(paths, rpcs, posting=8.0, height_range=(200.0, 700.0))
    assert [p.pair for p in pairs] == [(0, 1), (0, 2), (1, 2)]
    agree = dsm.info["pair_agreement"]
    assert len(agree) == 3
    for v in agree.values():
        assert abs(v["median_m"]) < 0.5 and v["nmad_m"] < 2.5 and v["cells"] > 1000
    # without the pair grids kept, the agreement from samples of each tile's differences
    lean, none = rpc_dsm(paths, rpcs, posting=8.0, height_range=(200.0, 700.0), keep_pairs=False)
    assert none == [] and lean.info["agreement_sampled"]
    assert np.array_equal(lean.heights, dsm.heights, equal_nan=True)
    for key, v in lean.info["pair_agreement"].items():
        assert v["nmad_m"] == pytest.approx(agree[key]["nmad_m"], rel=0.1)
    d = truth_diff(dsm, world)
    single = truth_diff(replace(dsm, heights=pairs[1].heights), world)
    # fused: no worse than the widest pair alone, and most cells agreed on by 2 or 3 pairs
    assert nmad(d) <= nmad(single) * 1.05
    assert np.mean(dsm.quality[np.isfinite(dsm.heights)] >= 2) > 0.8


def shifted_block(rpcs, lat0):
    """RPCs whose ground is off by SHIFT: the model of a true point X is the true model at
    X + SHIFT, so their DSM lies at −SHIFT."""
    ke, kn = metres_per_degree(lat0)
    return [replace(r, lon_off=r.lon_off - SHIFT[0] / ke, lat_off=r.lat_off - SHIFT[1] / kn,
                    h_off=r.h_off - SHIFT[2]) for r in rpcs]


def check_orientation(world, rpcs, paths, reference, posting):
    moved = shifted_block(rpcs, LAT0)
    dsm, _ = rpc_dsm(paths, moved, pairs=[(0, 2)], posting=posting,
                     height_range=(world.h_off - world.h_scale, world.h_off + world.h_scale))
    o = orient_from_reference(moved, dsm.heights, dsm.transform, dsm.crs, reference)
    assert o, o.coreg.reason
    s, sig = np.array(o.shift_m), np.array(o.sigma_m)
    assert np.all(np.abs(s - SHIFT) < np.maximum(4 * sig, [1.5, 1.5, 0.75])), (s, sig)
    # the oriented models reproduce the true ones on the ground, within their σ
    x = np.linspace(20, SIZE - 20, 7)
    X, Y = np.meshgrid(x, x)
    for k in (0, 2):
        h = np.full(X.shape, world.h_off)
        for _ in range(15):
            lon, lat = rpcs[k].localize(X, Y, h)
            h = world.height(lon, lat)
        px, py = o.models[k].project(lon, lat, h)
        before = moved[k].project(lon, lat, h)
        assert np.hypot(before[0] - X, before[1] - Y).min() > 2.0      # 3.5 px off before
        err = np.hypot(px - X, py - Y).max()
        assert err < 3 * np.hypot(*o.bias_sigma[k][:2]) + 0.15, (err, o.bias_sigma[k])


def test_orientation_from_a_reference_dem(synthetic, tmp_path):
    world, rpcs, paths = synthetic
    write_reference(tmp_path / "ref.tif", world)
    check_orientation(world, rpcs, paths, tmp_path / "ref.tif", 8.0)


def test_one_call_orientation_and_the_dsm_file(synthetic, tmp_path):
    """What the command line calls: the DSM at 8 pixels and the orientation in one; the DSM
    written as the PRISM DSM's GeoTIFF, its heights ellipsoidal."""
    world, rpcs, paths = synthetic
    write_reference(tmp_path / "ref.tif", world)
    moved = shifted_block(rpcs, LAT0)
    o, dsm = orient_rpc_from_dem(paths, moved, tmp_path / "ref.tif", pairs=[(0, 2)],
                                 height_range=(200.0, 700.0))
    assert dsm.posting_m == pytest.approx(8 * GSD, rel=0.02)
    assert o and np.all(np.abs(np.array(o.shift_m) - SHIFT) < [2.0, 2.0, 1.0])
    write_dsm(tmp_path / "dsm.tif", dsm)
    info = read_dsm_info(tmp_path / "dsm.tif")
    with rasterio.open(tmp_path / "dsm.tif") as ds:
        assert "ellipsoidal" in ds.crs.to_wkt() and ds.count == 3
        h = ds.read(1)
    assert np.allclose(h, dsm.heights, equal_nan=True) and info


def test_orientation_refuses_a_reference_elsewhere(synthetic, tmp_path):
    world, rpcs, paths = synthetic
    dsm, _ = rpc_dsm(paths, rpcs, pairs=[(0, 2)], posting=8.0, height_range=(200.0, 700.0))
    write_reference(tmp_path / "far.tif", world, lon0=LON0 + 0.5)
    with pytest.raises(InputError, match="share"):
        orient_from_reference(rpcs, dsm.heights, dsm.transform, dsm.crs, tmp_path / "far.tif")


@pytest.fixture(scope="module")
def ventoux(tmp_path_factory, shared_data):
    srtm = shared_data / "srtm" / "N44E005.hgt"
    height = dem_terrain(srtm)
    world = World(LON0, LAT0, lambda e, n: 0.0, extent_m=2400, texture_cell_m=2.0)
    world.height = lambda lon, lat: height(lon, lat)
    world.h_off, world.h_scale = 1200.0, 800.0
    return triplet(tmp_path_factory, world, "rpc_ventoux") + (srtm,)


def test_orientation_on_srtm_relief(ventoux):
    """Real relief (SRTM 3″ on the slopes of Mont Ventoux, 1,500–1,900 m), the images rendered on it and
    the same SRTM tile as the reference: the block's 17 m ground error is found. (The
    world's heights are the tile's numbers, so no geoid enters.)"""
    world, rpcs, paths, srtm = ventoux
    check_orientation(world, rpcs, paths, srtm, 8.0)


def test_bad_input_and_cancel(synthetic, tmp_path):
    world, rpcs, paths = synthetic
    with pytest.raises(InputError, match="two or more"):
        rpc_dsm(paths[:1], rpcs[:1])
    with pytest.raises(InputError, match="cannot open|not found"):
        rpc_dsm([paths[0], tmp_path / "missing.tif"], rpcs[:2])
    with pytest.raises(Cancelled):
        rpc_dsm(paths, rpcs, pairs=[(0, 2)], posting=8.0, height_range=(200.0, 700.0),
                progress=lambda fraction, message="": False)


def test_tile_height_range_from_points_and_reference():
    grid = Grid("EPSG:32631", (2.0, 0.0, 1000.0, 0.0, -2.0, 5000.0), (100, 100))
    window = (0, 0, 50, 50)                     # E 1000–1100, N 4900–5000
    e = np.array([1010.0, 1020.0, 1030.0, 1040.0, 1050.0, 1500.0])
    n = np.full(6, 4950.0)
    h = np.array([300.0, 310.0, 320.0, 330.0, 340.0, 900.0])   # the far point is not near
    assert tile_height_range(grid, window, (0.0, 1000.0), None) == (0.0, 1000.0)
    assert tile_height_range(grid, window, (0.0, 1000.0), (e, n, h)) == (280.0, 360.0)
    # too few points near: the stated range
    assert tile_height_range(grid, window, (0.0, 1000.0), (e[:4], n[:4], h[:4])) == (0.0, 1000.0)
    prior = np.full(grid.shape, np.nan, np.float32)
    prior[:40, :40] = 500.0
    assert tile_height_range(grid, window, (0.0, 1000.0), None, prior) == (460.0, 540.0)
    # the union of both, inside the stated range
    assert tile_height_range(grid, window, (0.0, 520.0), (e, n, h), prior) == (280.0, 520.0)


def test_cells_two_images_of_three_see_keep_that_pairs_heights(synthetic, tmp_path):
    """A third image looking 400 m further east: on the grid of the first two, the cells west of
    its footprint are seen by one pair alone and keep that pair's heights (quality 1), as a pair
    DSM would (before, only cells every image sees had a height)."""
    world, rpcs, paths = synthetic
    ke, _ = metres_per_degree(LAT0)
    east = make_rpc(LON0 + 400.0 / ke, LAT0, gsd=GSD, size=SIZE, tan_along=TANS[2], h_off=world.h_off,
                    h_scale=world.h_scale, seed=3)
    write_image(tmp_path / "east.tif", render(east, world, SIZE))
    two, _ = rpc_dsm(paths[:2], rpcs[:2], posting=8.0, height_range=(200.0, 700.0))
    grid = Grid(two.crs, tuple(two.transform)[:6], two.heights.shape)
    dsm, _ = rpc_dsm([*paths[:2], tmp_path / "east.tif"], [*rpcs[:2], east], posting=8.0,
                     height_range=(200.0, 700.0), grid=grid)
    E, N = np.meshgrid(grid.transform[2] + 8.0 * (np.arange(grid.shape[1]) + 0.5),
                       grid.transform[5] - 8.0 * (np.arange(grid.shape[0]) + 0.5))
    lon, lat = to_lonlat(grid.crs)(E, N)
    x, _ = east.project(lon, lat, world.height(lon, lat))
    alone = (x < -2) & two.seen                  # west of the third image: images 0 and 1 only
    assert alone.sum() > 0.2 * two.seen.sum()
    assert np.isfinite(dsm.heights[alone]).mean() > 0.85 and dsm.seen[alone].mean() > 0.97
    assert (dsm.quality[alone & np.isfinite(dsm.heights)] == 1).all()
    d = truth_diff(dsm, world)[alone]
    assert nmad(d[np.isfinite(d)]) * TANS[0] / GSD < 0.2
    assert dsm.info["seen_by"] == "two or more"
