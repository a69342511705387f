"""The RPC DSM written tile by tile (:mod:`prismstation.ops.rpc_dsm_export`) on the synthetic
triplet of ``test_rpc_dsm``: the file holds what the in-memory DSM holds, whatever the tiling;
a window of the first image crops it, ``fill`` fills its voids, a cancel leaves no file, and
its memory does not grow with the grid."""
from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
import rasterio

from prismstation.core.adjustment.stats import nmad
from prismstation.core.surfaces.dsm_grid import fill_voids, fill_voids_in_blocks
from prismstation.errors import Cancelled, InputError
from prismstation.ops.rpc_dsm import Grid, rpc_dsm
from prismstation.ops.rpc_dsm_export import write_rpc_dsm
from tests.ops.test_rpc_dsm import synthetic, truth_diff  # noqa: F401  (a fixture)

RANGE = (200.0, 700.0)


def read(path):
    with rasterio.open(path) as ds:
        return ds.read(1), ds.read(2), ds.read(3), tuple(ds.transform)[:6], ds.tags()


def test_the_file_holds_the_in_memory_dsm(synthetic, tmp_path):
    """Tiles of 64 cells written as they finish: the same heights, mask and pairs agreeing as
    the in-memory grid of the same tiles, the same counts."""
    world, rpcs, paths = synthetic
    mem, _ = rpc_dsm(paths, rpcs, posting=8.0, height_range=RANGE, tile_cells=64)
    dsm = write_rpc_dsm(tmp_path / "d.tif", paths, rpcs, posting=8.0, height_range=RANGE, tile_cells=64)
    h, m, q, t, tags = read(tmp_path / "d.tif")
    assert dsm.heights is None and dsm.shape == mem.heights.shape and t == tuple(mem.transform)
    assert np.array_equal(h, mem.heights, equal_nan=True)
    seen = mem.seen
    assert np.array_equal(np.isfinite(m), seen)
    assert np.array_equal(m[seen], mem.mask[seen]) and np.array_equal(q[seen], mem.quality[seen])
    assert dsm.cells("seen") == int(seen.sum()) and dsm.fill_fraction == pytest.approx(mem.fill_fraction)
    assert float(tags["FILL_PERCENT"]) == pytest.approx(100 * mem.fill_fraction, abs=0.01)
    assert dsm.info["agreement_sampled"] and len(dsm.info["pair_agreement"]) == 3


def test_the_tiling_does_not_change_the_dsm(synthetic):
    """Tiles of 32 cells (each its own rectification and height range) against one tile over
    the whole grid: the same surface, within the matching's own scatter."""
    world, rpcs, paths = synthetic
    small, _ = rpc_dsm(paths, rpcs, posting=8.0, height_range=RANGE, tile_cells=32)
    whole, _ = rpc_dsm(paths, rpcs, posting=8.0, height_range=RANGE, tile_cells=4096)
    assert small.info["tiles"] > 9 and whole.info["tiles"] == 1
    d = small.heights - whole.heights
    both = np.isfinite(d)
    assert both.sum() > 0.85 * small.seen.sum()
    assert abs(np.median(d[both])) < 0.1 and nmad(d[both]) < 0.5 * nmad(truth_diff(whole, world)[both]) + 0.3
    assert abs(small.fill_fraction - whole.fill_fraction) < 0.03


def test_a_window_of_the_first_image_crops_the_dsm(synthetic, tmp_path):
    world, rpcs, paths = synthetic
    full = write_rpc_dsm(tmp_path / "full.tif", paths, rpcs, posting=8.0, height_range=RANGE)
    win = (60, 40, 150, 120)                       # col0, row0, cols, rows of image 0
    part = write_rpc_dsm(tmp_path / "part.tif", paths, rpcs, posting=8.0, height_range=RANGE, window=win)
    hf, *_, tf, _ = read(tmp_path / "full.tif")
    hp, mp, _, tp, _ = read(tmp_path / "part.tif")
    assert part.shape[0] < 0.6 * full.shape[0] and part.shape[1] < 0.7 * full.shape[1]
    # the same lattice, inside the full grid
    c0, r0 = round((tp[2] - tf[2]) / 8.0), round((tf[5] - tp[5]) / 8.0)
    assert (tp[2] - tf[2]) / 8.0 == pytest.approx(c0) and c0 >= 0 and r0 >= 0
    sub = hf[r0:r0 + hp.shape[0], c0:c0 + hp.shape[1]]
    d = hp - sub
    assert np.isfinite(d).sum() > 0.8 * np.isfinite(mp).sum() and abs(np.nanmedian(d)) < 0.2
    # every seen cell lies in the window of image 0
    E, N = np.meshgrid(tp[2] + 8.0 * (np.arange(hp.shape[1]) + 0.5), tp[5] - 8.0 * (np.arange(hp.shape[0]) + 0.5))
    from prismstation.io.rpc_scene import to_lonlat
    ok = np.isfinite(mp) & np.isfinite(hp)
    lon, lat = to_lonlat(part.crs)(E[ok], N[ok])
    x, y = rpcs[0].project(lon, lat, hp[ok])
    assert x.min() >= win[0] and x.max() <= win[0] + win[2] and y.min() >= win[1] and y.max() <= win[1] + win[3]
    with pytest.raises(InputError, match="not inside"):
        write_rpc_dsm(tmp_path / "x.tif", paths, rpcs, posting=8.0, window=(250, 0, 100, 100))


def test_fill_fills_the_voids_it_sees(synthetic, tmp_path):
    """``fill``: every seen cell has a height, the filled ones marked 2, the matched ones
    untouched; written tile by tile as in memory."""
    world, rpcs, paths = synthetic
    bare = write_rpc_dsm(tmp_path / "bare.tif", paths, rpcs, posting=4.0, height_range=RANGE)
    full = write_rpc_dsm(tmp_path / "fill.tif", paths, rpcs, posting=4.0, height_range=RANGE, fill=True)
    mem, _ = rpc_dsm(paths, rpcs, posting=4.0, height_range=RANGE, fill=True)
    h0, m0, *_ = read(tmp_path / "bare.tif")
    h1, m1, *_ = read(tmp_path / "fill.tif")
    seen = np.isfinite(m0)
    voids = seen & ~np.isfinite(h0)
    assert voids.sum() > 50                                  # 4 m cells on 4 m pixels: some voids
    assert np.isfinite(h1[seen]).all() and np.all(m1[voids] == 2) and np.all(m1[seen & ~voids] == 1)
    assert np.array_equal(h1[~voids], h0[~voids], equal_nan=True)
    assert np.array_equal(h1, mem.heights, equal_nan=True)
    assert full.cells("filled") == int(voids.sum()) == bare.cells("seen") - bare.cells("matched")
    # the filled heights follow the terrain (smooth hills)
    assert np.nanmedian(np.abs(truth_diff(mem, world)[voids])) < 2.0


def test_voids_filled_in_blocks_as_on_the_whole_grid():
    """Block by block with a halo: the whole grid's membrane where the voids are smaller than
    the halo."""
    rng = np.random.default_rng(1)
    y, x = np.mgrid[0:300, 0:260]
    h = (100 + 0.2 * x + 5 * np.sin(y / 30.0)).astype(np.float32)
    holes = np.zeros(h.shape, bool)
    for r, c in rng.integers(10, 250, (40, 2)):
        holes[r:r + rng.integers(2, 12), c:c + rng.integers(2, 12)] = True
    z = np.where(holes, np.nan, h)
    whole = fill_voids(z)
    out = z.copy()
    seen = np.ones(h.shape, bool)

    def write(r0, c0, hh, new):
        out[r0:r0 + hh.shape[0], c0:c0 + hh.shape[1]] = hh
    n = fill_voids_in_blocks(h.shape, lambda r0, c0, nr, nc: (z[r0:r0 + nr, c0:c0 + nc],
                                                               np.isfinite(z[r0:r0 + nr, c0:c0 + nc]),
                                                               seen[r0:r0 + nr, c0:c0 + nc]),
                             write, block=64, halo=24)
    assert n == holes.sum() and np.isfinite(out).all()
    assert np.abs(out - whole).max() < 0.05


def test_cancel_leaves_the_old_file(synthetic, tmp_path):
    world, rpcs, paths = synthetic
    out = tmp_path / "d.tif"
    out.write_bytes(b"old")
    calls = []

    def progress(fraction, message=""):
        calls.append(fraction)
        return len(calls) < 3                     # cancelled after two tiles
    with pytest.raises(Cancelled):
        write_rpc_dsm(out, paths, rpcs, posting=8.0, height_range=RANGE, tile_cells=32, progress=progress)
    assert out.read_bytes() == b"old" and sorted(p.name for p in tmp_path.iterdir() if p.is_file()) == ["d.tif"]


def test_memory_does_not_grow_with_the_grid(synthetic, tmp_path):
    """A 1,250 × 1,250 grid at 8 m (the images see 1.2 km of its 10 km; the tiles no image
    sees are not matched): in memory its heights, quality and seen grids alone would take
    9.4 MB and the kept pair DSMs 56 MB more; written tile by tile, the Python heap peaks at
    what no grid size changes: the agreement sample (at most 4.8 MB) and a tile's working set
    (64-cell tiles)."""
    world, rpcs, paths = synthetic
    ref, _ = rpc_dsm(paths, rpcs, posting=8.0, height_range=RANGE)
    a, _, c, _, e, f = ref.transform
    grid = Grid(ref.crs, (8.0, 0.0, c - 4400.0, 0.0, -8.0, f + 4400.0), (1250, 1250))
    tracemalloc.start()
    try:
        dsm = write_rpc_dsm(tmp_path / "big.tif", paths, rpcs, posting=8.0, grid=grid, height_range=RANGE,
                            tile_cells=64, scheduler="sync")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert dsm.shape == (1250, 1250) and dsm.cells("matched") > 0.8 * dsm.cells("seen") > 15_000
    assert dsm.info["tiles"] < 100                  # of 400
    assert peak < 8e6, peak / 1e6


def test_processes_give_what_threads_give(synthetic, tmp_path):
    """The tiles run in other processes (Dask's ``processes`` scheduler, as on a cluster):
    the same file."""
    world, rpcs, paths = synthetic
    write_rpc_dsm(tmp_path / "t.tif", paths, rpcs, posting=8.0, height_range=RANGE, tile_cells=64)
    write_rpc_dsm(tmp_path / "p.tif", paths, rpcs, posting=8.0, height_range=RANGE, tile_cells=64,
                  scheduler="processes", workers=2)
    a, b = read(tmp_path / "t.tif"), read(tmp_path / "p.tif")
    assert all(np.array_equal(x, y, equal_nan=True) for x, y in zip(a[:3], b[:3]))
