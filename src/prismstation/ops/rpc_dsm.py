"""A DSM from images with RPCs: each pair matched on local epipolar tiles, the pairs fused.

For every pair of images and every tile of the output grid (north-up, a UTM zone by default,
ellipsoidal heights), the left image's window seeing the tile is rectified with the right
image (:func:`prismstation.core.rpc_epipolar.rectify_pair`, through the biased RPCs), matched
by OpenCV's StereoSGBM with the ZNCC subpixel refinement of the PRISM DSM
(:mod:`prismstation.core.sgm`), triangulated through the RPCs and binned into the tile's cells.
Each tile matches every pair and fuses them in one Dask task
(:mod:`prismstation.ops.rpc_dsm_tiles`, run by :func:`prismstation.ops.dsm_tiles.run_tiles`);
it reads its own windows, so it runs in a thread, a process or on a ``dask.distributed``
worker, and only the fused grid is held whole.

A-priori knowledge, stated by the caller and turned into search ranges:

- ``height_range`` (lo, hi) ellipsoidal metres for the whole DSM; per tile it is narrowed to
  the heights of ``points`` (tie points intersected by the bias fit: ``(lon°, lat°, h m)``)
  within and around the tile, widened by ``max(POINT_MARGIN_M, 25 %)`` of their spread, and
  to a reference DEM's heights there ± :data:`PRIOR_MARGIN_M` (the union of the two). Without
  any, the RPCs' own height domain (``h_off ± h_scale``): correct but a wide search.
- ``margin_px`` (2 px): what is left of the images' relative bias along the epipolar lines
  (after the bias fit, a tenth of a pixel; the Pléiades triplet's raw RPCs, a few tenths):
  the disparity range is widened by it. Across the lines nothing absorbs a bias (the raw
  triplet's 0.7–1.2 px there still matched 96–99 % of the cells), and along them it is a
  height error (the raw triplet's pairs lie 2.4–4.8 m apart: docs/benchmarks.md): fit the
  biases first.
"""
from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field

import numpy as np

from prismstation.core.rpc_bias import as_biased
from prismstation.core.stats import nmad
from prismstation.errors import InputError, ModelError
from prismstation.io.dem import read_dem
from prismstation.io.rpc_scene import to_map, utm_crs
from prismstation.ops.dsm import MASK_MATCHED, Dsm
from prismstation.ops.dsm_tiles import run_tiles
from prismstation.ops.rpc_dsm_tiles import BlockTile, Grid, image_shape, run_block_tile

#: smallest widening (m) of a tile's height range beyond its tie points' heights
POINT_MARGIN_M = 20.0
#: tie points a tile needs around it to narrow its height range
MIN_TILE_POINTS = 5
#: widening (m) of a reference DEM's heights over a tile: its own error (SRTM, Copernicus DEM:
#: a few metres to ~15 m in relief) and the block's vertical error before it is oriented
#: (RPCs without GCPs: 10–20 m)
PRIOR_MARGIN_M = 40.0
#: output cells per tile side
TILE_CELLS = 256


def rpc_height_domain(models) -> tuple[float, float]:
    """The heights every RPC is valid for (``h_off ± h_scale``, intersected), metres."""
    m = [as_biased(v).rpc for v in models]
    lo = max(r.h_off - abs(r.h_scale) for r in m)
    hi = min(r.h_off + abs(r.h_scale) for r in m)
    if not hi > lo:
        raise ModelError("the images' RPC height domains do not overlap")
    return lo, hi


def footprint_grid(models, shapes, posting: float, height: float, crs: str | None = None) -> Grid:
    """The grid (``posting`` m) over the ground all images see at ``height`` (the intersection
    of their footprints' bounding boxes); ``crs`` default the UTM zone of the centre."""
    boxes, centres = [], []
    for model, (rows, cols) in zip(models, shapes):
        m = as_biased(model)
        x = np.array([0, cols, 0, cols, cols / 2])
        y = np.array([0, 0, rows, rows, rows / 2])
        lon, lat = m.localize(x, y, np.full(5, float(height)))
        boxes.append((lon, lat))
        centres.append((lon[-1], lat[-1]))
    crs = crs or utm_crs(*np.mean(centres, axis=0))
    fw = to_map(crs)
    lo_e, lo_n, hi_e, hi_n = -np.inf, -np.inf, np.inf, np.inf
    for lon, lat in boxes:
        e, n = fw(lon[:4], lat[:4])
        lo_e, lo_n = max(lo_e, np.min(e)), max(lo_n, np.min(n))
        hi_e, hi_n = min(hi_e, np.max(e)), min(hi_n, np.max(n))
    if not (hi_e > lo_e + posting and hi_n > lo_n + posting):
        raise ModelError("the images' footprints do not overlap")
    c0, f0 = np.floor(lo_e / posting) * posting, np.ceil(hi_n / posting) * posting
    cols = int(np.ceil((hi_e - c0) / posting))
    rows = int(np.ceil((f0 - lo_n) / posting))
    return Grid(str(crs), (float(posting), 0.0, float(c0), 0.0, -float(posting), float(f0)), (rows, cols))


def tile_height_range(grid: Grid, window, height_range, points, prior=None,
                      prior_margin_m: float = PRIOR_MARGIN_M) -> tuple[float, float]:
    """The tile's a-priori height range, inside ``height_range``: the union of

    - the heights of ``points`` (E, N, h arrays) within the tile widened by half its size on
      every side, widened by ``max(POINT_MARGIN_M, 25 % of their spread)`` (when
      :data:`MIN_TILE_POINTS` or more are near);
    - the reference DEM ``prior`` (an array on ``grid``, NaN void) over the same cells,
      widened by ``prior_margin_m``;

    the whole ``height_range`` where neither says anything."""
    lo, hi = (float(v) for v in height_range)
    r0, c0, rows, cols = window
    ranges = []
    if points is not None:
        e, n, h = points
        a, _, c, _, ee, f = grid.transform
        x0, x1 = c + a * (c0 - cols / 2), c + a * (c0 + 1.5 * cols)
        y1, y0 = f + ee * (r0 - rows / 2), f + ee * (r0 + 1.5 * rows)
        near = (e >= x0) & (e <= x1) & (n >= y0) & (n <= y1) & np.isfinite(h)
        if near.sum() >= MIN_TILE_POINTS:
            hmin, hmax = float(h[near].min()), float(h[near].max())
            m = max(POINT_MARGIN_M, 0.25 * (hmax - hmin))
            ranges.append((hmin - m, hmax + m))
    if prior is not None:
        sub = prior[max(0, r0 - rows // 2):r0 + rows + rows // 2, max(0, c0 - cols // 2):c0 + cols + cols // 2]
        if np.isfinite(sub).any():
            ranges.append((float(np.nanmin(sub)) - prior_margin_m, float(np.nanmax(sub)) + prior_margin_m))
    if not ranges:
        return lo, hi
    return max(lo, min(r[0] for r in ranges)), min(hi, max(r[1] for r in ranges))


@dataclass
class PairDsm:
    """One pair's heights on the grid: ``heights`` (rows, cols) float32 ellipsoidal m (NaN
    void), ``counts`` samples per cell, ``sigma`` m; ``tiles`` the per-tile stats."""

    pair: tuple
    heights: np.ndarray
    counts: np.ndarray
    sigma: np.ndarray
    tiles: list = field(default_factory=list)
    seconds: float = 0.0


def _differences(hp, hq, sp, sq):
    """Differences of two pair DSMs where both hold a height, and the same in their σ."""
    d = hp - hq
    ok = np.isfinite(d)
    return d[ok], d[ok] / np.sqrt(sp[ok] ** 2 + sq[ok] ** 2)


def _agreement(d, z) -> dict:
    return {"nmad_m": nmad(d), "median_m": float(np.median(d)) if d.size else float("nan"),
            "cells": int(d.size), "nmad_in_sigma": nmad(z)}


def pair_agreement(pairs: list) -> dict:
    """NMAD (m) of the differences between every two pair DSMs, over the cells both hold,
    their median, and the NMAD of those differences in units of their formal σ (1 when the
    σ are right); keys ``"(i, j)-(k, l)"``."""
    return {f"{p.pair}-{q.pair}": _agreement(*_differences(p.heights, q.heights, p.sigma, q.sigma))
            for p, q in itertools.combinations(pairs, 2)}


def tile_windows(grid: Grid, tile_cells: int = TILE_CELLS) -> list:
    """Windows (row0, col0, rows, cols) of equal tiles of at most ``tile_cells`` a side (no
    thin strips at the edges)."""
    rows, cols = grid.shape
    rb = np.linspace(0, rows, -(-rows // tile_cells) + 1).round().astype(int)
    cb = np.linspace(0, cols, -(-cols // tile_cells) + 1).round().astype(int)
    return [(int(r0), int(c0), int(r1 - r0), int(c1 - c0))
            for r0, r1 in zip(rb[:-1], rb[1:]) for c0, c1 in zip(cb[:-1], cb[1:])]


#: pair grids are kept (and their agreement is exact) up to this many cells × pairs; beyond,
#: the agreement comes from up to :data:`AGREEMENT_SAMPLES` differences per tile
KEEP_PAIRS_CELLS = 30_000_000
AGREEMENT_SAMPLES = 4096


def rpc_dsm(paths, models, *, posting: float = 1.0, pairs=None, height_range=None, points=None,
            reference=None, geoid=None, grid: Grid | None = None, crs: str | None = None,
            margin_px: float = 2.0, tile_cells: int = TILE_CELLS, refine: bool = True, tau: float = 3.0,
            keep_pairs: bool | None = None, scheduler=None, workers=None, progress=None) -> tuple[Dsm, list]:
    """The fused DSM of two or more images with RPCs, and the pair DSMs it came from.

    ``paths`` image files; ``models`` their :class:`Rpc` / :class:`BiasedRpc` (fitted
    biases applied); ``pairs`` index pairs (default every pair); ``posting`` metres;
    ``grid`` (default: the images' common footprint in the UTM zone of its centre, or
    ``crs``). ``height_range``, ``points`` (lon°, lat°, ellipsoidal h m arrays: the bias fit's
    tie points), ``margin_px``, ``reference`` (a reference DEM
    file; ``geoid`` makes an orthometric one ellipsoidal): the module docstring.

    Each tile matches every pair and fuses them as the PRISM DSM does
    (:func:`prismstation.core.sgm.fuse`): the pair heights within ``tau`` σ of their median,
    σ-weighted; a cell with one height (or two that disagree) keeps the one nearest its
    neighbours' fused surface within 3σ or three postings. The
    :class:`~prismstation.ops.dsm.Dsm` holds ellipsoidal heights on ``grid``, ``quality``
    the pairs agreeing, ``seen`` the cells all images see, ``info["pair_agreement"]``
    (:func:`pair_agreement`), ``info["pair_fill"]`` and the tiles' largest epipolar error.
    The pair DSMs (:class:`PairDsm`) are returned when kept (``keep_pairs``, default: up to
    :data:`KEEP_PAIRS_CELLS`), else an empty list.
    """
    if len(paths) != len(models) or len(paths) < 2:
        raise InputError("a DSM needs two or more images, each with its RPC model")
    shapes = tuple(image_shape(p) for p in paths)
    height_range = tuple(height_range) if height_range is not None else rpc_height_domain(models)
    if grid is None:
        grid = footprint_grid(models, shapes, posting, 0.5 * sum(height_range), crs)
    pairs = tuple(tuple(map(int, p)) for p in pairs) if pairs is not None else \
        tuple(itertools.combinations(range(len(paths)), 2))
    prior = None
    if reference is not None:
        prior = read_dem(reference, grid.crs, grid.transform, grid.shape, geoid=geoid,
                         what="reference DEM").heights.astype(np.float32)
    if points is not None:
        lon, lat, hp = (np.asarray(v, float).ravel() for v in points)
        points = (*(np.asarray(v) for v in to_map(grid.crs)(lon, lat)), hp)
    cells = grid.shape[0] * grid.shape[1]
    keep = keep_pairs if keep_pairs is not None else cells * len(pairs) <= KEEP_PAIRS_CELLS
    specs = [BlockTile(tuple(str(p) for p in paths), tuple(models), shapes, pairs, grid, win,
                       tile_height_range(grid, win, height_range, points, prior),
                       margin_px=margin_px, refine=refine, tau=tau)
             for win in tile_windows(grid, tile_cells)]
    del prior
    h = np.full(grid.shape, np.nan, np.float32)
    q = np.zeros(grid.shape, np.uint8)
    seen = np.zeros(grid.shape, bool)
    results = [PairDsm(pr, np.full(grid.shape, np.nan, np.float32), np.zeros(grid.shape, np.int32),
                       np.full(grid.shape, np.nan, np.float32)) for pr in pairs] if keep else []
    combos = list(itertools.combinations(range(len(pairs)), 2))
    samples = {c: ([], []) for c in combos}
    filled = np.zeros(len(pairs), np.int64)
    epipolar = [0.0]
    rng = np.random.default_rng(0)
    t0 = time.perf_counter()

    def consume(k, res):
        th, tq, ts, vals, sig, cnt, stats = res
        r0, c0, nr, nc = specs[k].window
        sl = (slice(r0, r0 + nr), slice(c0, c0 + nc))
        h[sl], q[sl], seen[sl] = th, tq, ts
        filled[:] += np.isfinite(vals[:, ts]).sum(axis=1)
        epipolar[0] = max([epipolar[0]] + [st.get("epipolar_error_px", 0.0) for st in stats])
        for p, r in enumerate(results):
            r.heights[sl], r.counts[sl], r.sigma[sl] = vals[p], cnt[p], sig[p]
            r.tiles.append(dict(stats[p], window=specs[k].window))
        if not keep:
            for a, b in combos:
                d, z = _differences(vals[a], vals[b], sig[a], sig[b])
                if d.size > AGREEMENT_SAMPLES:
                    pick = rng.choice(d.size, AGREEMENT_SAMPLES, replace=False)
                    d, z = d[pick], z[pick]
                samples[(a, b)][0].append(d.astype(np.float32))
                samples[(a, b)][1].append(z.astype(np.float32))

    run_tiles(specs, consume, scheduler=scheduler, workers=workers, progress=progress, fn=run_block_tile)
    seconds = time.perf_counter() - t0
    for r in results:
        r.seconds = seconds
    if keep:
        agreement = pair_agreement(results)
    else:
        agreement = {f"{pairs[a]}-{pairs[b]}": _agreement(np.concatenate(samples[(a, b)][0] or [np.zeros(0)]),
                                                          np.concatenate(samples[(a, b)][1] or [np.zeros(0)]))
                     for a, b in combos}
    n_seen = int(seen.sum())
    info = {"pairs": [list(p) for p in pairs], "pair_agreement": agreement,
            "agreement_sampled": not keep,
            "pair_fill": [float(f) / n_seen if n_seen else 0.0 for f in filled],
            "seconds": seconds, "epipolar_error_px": epipolar[0], "height_range": list(height_range),
            "tiles": len(specs)}
    mask = (np.isfinite(h) & seen).astype(np.uint8) * MASK_MATCHED
    dsm = Dsm(h, grid.transform, grid.crs, "ellipsoidal",
              float(np.isfinite(h[seen]).mean()) if n_seen else 0.0,
              mask=mask, seen=seen, quality=q, posting_m=grid.posting, info=info)
    return dsm, results
