"""A DSM from images with RPCs: each pair matched on local epipolar tiles, the pairs fused.

For every pair of images and every tile of the output grid (north-up, a UTM zone by default,
ellipsoidal heights), the left image's window seeing the tile is rectified with the right
image (:func:`prismstation.core.surfaces.rpc_epipolar.rectify_pair`, through the biased RPCs), matched
by OpenCV's StereoSGBM with the ZNCC subpixel refinement of the PRISM DSM
(:mod:`prismstation.core.matching.sgm`), triangulated through the RPCs and binned into the tile's cells.
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

from prismstation.core.models.rpc_bias import as_biased
from prismstation.core.adjustment.stats import nmad
from prismstation.errors import InputError, ModelError
from prismstation.io.dem import read_dem
from prismstation.io.rpc_scene import to_lonlat, to_map, utm_crs
from prismstation.core.surfaces.dsm_grid import fill_voids_in_blocks
from prismstation.ops.dsm import MASK_FILLED, MASK_MATCHED, Dsm, grid_dsm
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
#: a posting under this many of the first image's pixels is fine (a cell holds a few samples,
#: some none): each triangulated point is spread over the cells around it by a Gaussian of
#: :data:`SPLAT_CELLS` cells (:func:`~prismstation.core.surfaces.rpc_epipolar.grid_heights`:
#: no holes between the scattered points, each cell the mean of its neighbourhood) and the
#: disparities pass a :data:`MEDIAN_PX` median filter (the usual SGM chain's outlier filter,
#: :func:`~prismstation.core.matching.sgm.median_filter`); a coarser posting averages enough
#: samples per cell for neither to matter
FINE_POSTING_PX = 2.5
SPLAT_CELLS = 0.5
MEDIAN_PX = 3


def rpc_height_domain(models) -> tuple[float, float]:
    """The heights every RPC is valid for (``h_off ± h_scale``, intersected), metres."""
    m = [as_biased(v).rpc for v in models]
    lo = max(r.h_off - abs(r.h_scale) for r in m)
    hi = min(r.h_off + abs(r.h_scale) for r in m)
    if not hi > lo:
        raise ModelError("the images' RPC height domains do not overlap")
    return lo, hi


def footprint_grid(models, shapes, posting: float, height: float, crs: str | None = None,
                   window=None) -> Grid:
    """The grid (``posting`` m) over the ground all images see at ``height`` (the intersection
    of their footprints' bounding boxes: the corners of skewed footprints in it are seen by a
    pair only), the first image's limited to ``window`` (col0, row0, cols, rows) px when given;
    ``crs`` default the UTM zone of the centre."""
    boxes, centres = [], []
    for k, (model, (rows, cols)) in enumerate(zip(models, shapes)):
        m = as_biased(model)
        x0, y0 = 0, 0
        if k == 0 and window is not None:
            x0, y0, cols, rows = window
        x = x0 + np.array([0, cols, 0, cols, cols / 2])
        y = y0 + np.array([0, 0, rows, rows, rows / 2])
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
                      prior_margin_m: float = PRIOR_MARGIN_M, prior_step: int = 1) -> tuple[float, float]:
    """The tile's a-priori height range, inside ``height_range``: the union of

    - the heights of ``points`` (E, N, h arrays) within the tile widened by half its size on
      every side, widened by ``max(POINT_MARGIN_M, 25 % of their spread)`` (when
      :data:`MIN_TILE_POINTS` or more are near);
    - the reference DEM ``prior`` (an array on ``grid`` taken every ``prior_step`` cells: cell
      ``(i, j)`` of it covers the grid's rows ``i·step …`` and columns ``j·step …``; NaN void)
      over the same cells, widened by ``prior_margin_m``;

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
        k = int(prior_step)
        sub = prior[max(0, r0 - rows // 2) // k:-(-(r0 + rows + rows // 2) // k),
                    max(0, c0 - cols // 2) // k:-(-(c0 + cols + cols // 2) // k)]
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
#: the agreement comes from a sample of at most :data:`AGREEMENT_SAMPLES` differences per two
#: pairs, spread over the tiles
KEEP_PAIRS_CELLS = 30_000_000
AGREEMENT_SAMPLES = 200_000
#: the reference DEM is read onto the grid taken every k cells, k the smallest that keeps it
#: to this many cells (a reference of 30–90 m cells, read at 0.5 m, adds nothing but memory)
PRIOR_CELLS = 4_000_000


@dataclass(frozen=True)
class RpcDsmPlan:
    """What every step of :func:`rpc_dsm` shares: the images (``paths``, their ``models`` —
    :class:`Rpc` / :class:`BiasedRpc`, fitted biases applied — and ``shapes`` (rows, cols)),
    the index ``pairs`` matched, the output ``grid``, the whole DSM's a-priori
    ``height_range`` (lo, hi) ellipsoidal m, the matching (``margin_px``, ``refine``) and the
    fusion's ``tau``, the tiling (``tile_cells``), whether the pair DSMs are kept whole
    (``keep_pairs``), the ``crop`` (col0, row0, cols, rows) of the first image the DSM is
    limited to (None: the images' whole common footprint), and the gridding's ``splat_cells``
    and the disparities' ``median_px`` (:data:`FINE_POSTING_PX`)."""

    paths: tuple
    models: tuple
    shapes: tuple
    pairs: tuple
    grid: Grid
    height_range: tuple
    margin_px: float
    refine: bool
    tau: float
    tile_cells: int
    keep_pairs: bool
    crop: tuple | None = None
    splat_cells: float = 0.0
    median_px: int = 0


def check_crop(window, shape) -> tuple:
    """``window`` (col0, row0, cols, rows) as integers, inside an image of ``shape`` (rows,
    cols) and at least 16 px a side; else an :class:`InputError` saying why."""
    c0, r0, w, h = (int(v) for v in window)
    rows, cols = shape
    if w < 16 or h < 16:
        raise InputError(f"the window {c0} {r0} {w} {h} is too small: at least 16 × 16 pixels")
    if c0 < 0 or r0 < 0 or c0 + w > cols or r0 + h > rows:
        raise InputError(f"the window {c0} {r0} {w} {h} is not inside the first image ({cols} × {rows} px)")
    return c0, r0, w, h


def plan_rpc_dsm(paths, models, *, posting: float = 1.0, pairs=None, height_range=None,
                 grid: Grid | None = None, crs: str | None = None, margin_px: float = 2.0,
                 tile_cells: int = TILE_CELLS, refine: bool = True, tau: float = 3.0,
                 keep_pairs: bool | None = None, window=None, splat_cells: float | None = None,
                 median_px: int | None = None) -> RpcDsmPlan:
    """The plan (:func:`rpc_dsm` says what each argument is): the images' shapes, the height
    range (default the RPCs' own domain), the grid (default their common footprint at
    ``posting``, the first image's limited to ``window``), the pairs (default every pair), the
    pair DSMs kept up to :data:`KEEP_PAIRS_CELLS`, the splat and the median filter at a fine
    posting (:data:`FINE_POSTING_PX`) unless given."""
    if len(paths) != len(models) or len(paths) < 2:
        raise InputError("a DSM needs two or more images, each with its RPC model")
    if not (posting > 0 and np.isfinite(posting)):
        raise InputError(f"the posting must be a positive number of metres, got {posting}")
    shapes = tuple(image_shape(p) for p in paths)
    crop = check_crop(window, shapes[0]) if window is not None else None
    height_range = tuple(height_range) if height_range is not None else rpc_height_domain(models)
    if grid is None:
        grid = footprint_grid(models, shapes, posting, 0.5 * sum(height_range), crs, crop)
    pairs = tuple(tuple(map(int, p)) for p in pairs) if pairs is not None else \
        tuple(itertools.combinations(range(len(paths)), 2))
    cells = grid.shape[0] * grid.shape[1]
    keep = keep_pairs if keep_pairs is not None else cells * len(pairs) <= KEEP_PAIRS_CELLS
    fine = grid.posting < FINE_POSTING_PX * pixel_size_m(models[0], shapes[0], 0.5 * sum(height_range))
    splat = (SPLAT_CELLS if fine else 0.0) if splat_cells is None else float(splat_cells)
    median = (MEDIAN_PX if fine else 0) if median_px is None else int(median_px)
    return RpcDsmPlan(tuple(str(p) for p in paths), tuple(models), shapes, pairs, grid, height_range,
                      margin_px, refine, tau, tile_cells, keep, crop, splat, median)


def pixel_size_m(model, shape, height: float) -> float:
    """The ground size (m) of a pixel at the image's centre at ``height``: the geometric mean of
    its steps along the row and the column."""
    rows, cols = shape
    x = np.array([cols / 2, cols / 2 + 1, cols / 2])
    y = np.array([rows / 2, rows / 2, rows / 2 + 1])
    lon, lat = as_biased(model).localize(x, y, np.full(3, float(height)))
    e, n = to_map(utm_crs(float(lon[0]), float(lat[0])))(lon, lat)
    e, n = np.asarray(e), np.asarray(n)
    return float(np.sqrt(np.hypot(e[1] - e[0], n[1] - n[0]) * np.hypot(e[2] - e[0], n[2] - n[0])))


def reference_prior(plan: RpcDsmPlan, reference, geoid=None):
    """The reference DEM file ``reference`` read onto the plan's grid taken every ``step``
    cells (the smallest step that keeps it to :data:`PRIOR_CELLS`), ellipsoidal (``geoid`` for
    an orthometric one): ``(heights, step)`` (float32, NaN void), or None without one."""
    if reference is None:
        return None
    rows, cols = plan.grid.shape
    step = max(1, int(np.ceil(np.sqrt(rows * cols / PRIOR_CELLS))))
    a, b, c, d, e, f = plan.grid.transform
    heights = read_dem(reference, plan.grid.crs, (a * step, b, c, d, e * step, f),
                       (-(-rows // step), -(-cols // step)), geoid=geoid, what="reference DEM").heights
    return heights.astype(np.float32), step


def tile_specs(plan: RpcDsmPlan, prior=None, points=None) -> list:
    """Every tile of the grid (:func:`tile_windows`) as a :class:`BlockTile`, each with its own
    a-priori heights (:func:`tile_height_range`) from ``points`` (lon°, lat°, ellipsoidal h m
    arrays: the bias fit's tie points) and the reference ``prior`` (:func:`reference_prior`)."""
    grid = plan.grid
    if points is not None:
        lon, lat, hp = (np.asarray(v, float).ravel() for v in points)
        points = (*(np.asarray(v) for v in to_map(grid.crs)(lon, lat)), hp)
    heights, step = prior if prior is not None else (None, 1)
    return [BlockTile(plan.paths, plan.models, plan.shapes, plan.pairs, grid, win,
                      tile_height_range(grid, win, plan.height_range, points, heights, prior_step=step),
                      margin_px=plan.margin_px, refine=plan.refine, tau=plan.tau, crop=plan.crop,
                      splat_cells=plan.splat_cells, median_px=plan.median_px)
            for win in tile_windows(grid, plan.tile_cells) if not unseen_tile(plan, win)]


def unseen_tile(plan: RpcDsmPlan, window, margin_px: float = 8.0) -> bool:
    """Whether no pair of the plan sees the tile ``window`` (the first image only within its
    ``crop``): an image misses it when its corners at both ends of the height range all lie more
    than ``margin_px`` beyond one edge of that image. Such a tile is not matched: its cells
    stay void and unseen."""
    r0, c0, rows, cols = window
    a, _, c, _, e, f = plan.grid.transform
    E = c + a * np.array([c0, c0 + cols, c0, c0 + cols] * 2, float)
    N = f + e * np.array([r0, r0, r0 + rows, r0 + rows] * 2, float)
    h = np.repeat(np.asarray(plan.height_range, float), 4)
    lon, lat = to_lonlat(plan.grid.crs)(E, N)
    sees = []
    for k, (model, (ih, iw)) in enumerate(zip(plan.models, plan.shapes)):
        x0, y0, x1, y1 = (0, 0, iw, ih) if k or plan.crop is None else \
            (plan.crop[0], plan.crop[1], plan.crop[0] + plan.crop[2], plan.crop[1] + plan.crop[3])
        x, y = as_biased(model).project(lon, lat, h)
        sees.append(not ((x < x0 - margin_px).all() or (x > x1 + margin_px).all() or
                         (y < y0 - margin_px).all() or (y > y1 + margin_px).all()))
    if plan.crop is not None and not sees[0]:
        return True
    return not any(sees[i] and sees[j] for i, j in plan.pairs)


@dataclass
class TileSums:
    """What the tiles of :func:`match_tiles` add up to, grids aside (those go to the caller's
    ``put``): the cells a pair of images sees (``seen``) and with a height (``matched``); the pair
    DSMs (``pairs``, :class:`PairDsm`, when kept) or a sample of their differences per two
    pairs (``samples``); the matched cells of each pair (``filled``), the largest epipolar
    error (px) and the matching's ``seconds``."""

    pairs: list
    samples: dict
    filled: np.ndarray
    seen: int = 0
    matched: int = 0
    epipolar_px: float = 0.0
    seconds: float = 0.0


def match_tiles(plan: RpcDsmPlan, specs: list, put, *, scheduler=None, workers=None, progress=None) -> TileSums:
    """Every tile matched and fused (:func:`~prismstation.ops.rpc_dsm_tiles.run_block_tile`,
    as Dask tasks through :func:`~prismstation.ops.dsm_tiles.run_tiles`), each result handed
    to ``put(window, heights, quality, seen)`` as it arrives (``window`` (row0, col0, rows,
    cols); heights float32 ellipsoidal m, NaN void; quality uint8 pairs agreeing; seen bool):
    only the kept pair grids are held whole here."""
    shape = plan.grid.shape
    combos = list(itertools.combinations(range(len(plan.pairs)), 2))
    sums = TileSums([PairDsm(pr, np.full(shape, np.nan, np.float32), np.zeros(shape, np.float32),
                             np.full(shape, np.nan, np.float32)) for pr in plan.pairs] if plan.keep_pairs else [],
                    {c: ([], []) for c in combos}, np.zeros(len(plan.pairs), np.int64))
    per_tile = max(64, -(-AGREEMENT_SAMPLES // max(len(specs), 1)))
    rng = np.random.default_rng(0)
    t0 = time.perf_counter()

    def consume(k, res):
        th, tq, ts, vals, sig, cnt, stats = res
        r0, c0, nr, nc = win = specs[k].window
        put(win, th, tq, ts)
        sums.seen += int(ts.sum())
        sums.matched += int((np.isfinite(th) & ts).sum())
        sums.filled[:] += np.isfinite(vals[:, ts]).sum(axis=1)
        sums.epipolar_px = max([sums.epipolar_px] + [st.get("epipolar_error_px", 0.0) for st in stats])
        sl = (slice(r0, r0 + nr), slice(c0, c0 + nc))
        for p, r in enumerate(sums.pairs):
            r.heights[sl], r.counts[sl], r.sigma[sl] = vals[p], cnt[p], sig[p]
            r.tiles.append(dict(stats[p], window=win))
        if not plan.keep_pairs:
            for a, b in combos:
                d, z = _differences(vals[a], vals[b], sig[a], sig[b])
                if d.size > per_tile:
                    pick = rng.choice(d.size, per_tile, replace=False)
                    d, z = d[pick], z[pick]
                sums.samples[(a, b)][0].append(d.astype(np.float32))
                sums.samples[(a, b)][1].append(z.astype(np.float32))

    run_tiles(specs, consume, scheduler=scheduler, workers=workers, progress=progress, fn=run_block_tile)
    sums.seconds = time.perf_counter() - t0
    for r in sums.pairs:
        r.seconds = sums.seconds
    return sums


def dsm_info(plan: RpcDsmPlan, sums: TileSums, n_tiles: int) -> dict:
    """The record of a DSM: the pairs' agreement (exact from the kept pair DSMs, else from the
    samples), each pair's fill, the largest epipolar error, the height range, the tiles."""
    pairs = plan.pairs
    if plan.keep_pairs:
        agreement = pair_agreement(sums.pairs)
    else:
        agreement = {f"{pairs[a]}-{pairs[b]}": _agreement(np.concatenate(d or [np.zeros(0)]),
                                                          np.concatenate(z or [np.zeros(0)]))
                     for (a, b), (d, z) in sums.samples.items()}
    return {"pairs": [list(p) for p in pairs], "seen_by": "both" if len(plan.paths) == 2 else "two or more",
            "pair_agreement": agreement,
            "agreement_sampled": not plan.keep_pairs,
            "pair_fill": [float(f) / sums.seen if sums.seen else 0.0 for f in sums.filled],
            "seconds": sums.seconds, "epipolar_error_px": sums.epipolar_px, "height_range": list(plan.height_range),
            "tiles": n_tiles}


def fill_grid(heights, mask, seen) -> int:
    """The voids of the seen cells filled in place
    (:func:`~prismstation.core.surfaces.dsm_grid.fill_voids_in_blocks`, as the DSM written
    tile by tile is), their mask :data:`MASK_FILLED`; returns the cells filled."""
    def read(r0, c0, rows, cols):
        sl = (slice(r0, r0 + rows), slice(c0, c0 + cols))
        return heights[sl], mask[sl] == MASK_MATCHED, seen[sl]

    def write(r0, c0, h, new):
        sl = (slice(r0, r0 + h.shape[0]), slice(c0, c0 + h.shape[1]))
        heights[sl] = h
        mask[sl][new] = MASK_FILLED
    return fill_voids_in_blocks(heights.shape, read, write)


def rpc_dsm(paths, models, *, posting: float = 1.0, pairs=None, height_range=None, points=None,
            reference=None, geoid=None, grid: Grid | None = None, crs: str | None = None,
            margin_px: float = 2.0, tile_cells: int = TILE_CELLS, refine: bool = True, tau: float = 3.0,
            keep_pairs: bool | None = None, window=None, fill: bool = False, splat_cells: float | None = None,
            median_px: int | None = None, scheduler=None, workers=None, progress=None) -> tuple[Dsm, list]:
    """The fused DSM of two or more images with RPCs, in memory, and the pair DSMs it came
    from (:mod:`prismstation.ops.rpc_dsm_export` writes one of any size tile by tile).

    ``paths`` image files; ``models`` their :class:`Rpc` / :class:`BiasedRpc` (fitted
    biases applied); ``pairs`` index pairs (default every pair); ``posting`` metres;
    ``grid`` (default: the images' common footprint in the UTM zone of its centre, or
    ``crs``; the first image's limited to ``window`` (col0, row0, cols, rows) px).
    ``height_range``, ``points`` (lon°, lat°, ellipsoidal h m arrays: the bias fit's
    tie points), ``margin_px``, ``reference`` (a reference DEM
    file; ``geoid`` makes an orthometric one ellipsoidal): the module docstring. ``fill``:
    voids filled by interpolation (mask 2, :func:`fill_grid`). ``splat_cells``, ``median_px``:
    the gridding and the disparities' filter (default: :data:`FINE_POSTING_PX`).

    Each tile matches every pair and fuses them as the PRISM DSM does
    (:func:`prismstation.core.matching.sgm.fuse`): the pair heights within ``tau`` σ of their median,
    σ-weighted; a cell with one height (or two that disagree) keeps the one nearest its
    neighbours' fused surface within 3σ or three postings. The
    :class:`~prismstation.ops.dsm.Dsm` holds ellipsoidal heights on ``grid``, ``quality``
    the pairs agreeing (a cell one pair alone sees keeps that pair's height),
    ``seen`` the cells a pair of images sees, ``info["pair_agreement"]``
    (:func:`pair_agreement`), ``info["pair_fill"]`` and the tiles' largest epipolar error.
    The pair DSMs (:class:`PairDsm`) are returned when kept (``keep_pairs``, default: up to
    :data:`KEEP_PAIRS_CELLS`), else an empty list.

    The steps, as the PRISM DSM's (:func:`prismstation.ops.dsm.make_dsm`): :func:`plan_rpc_dsm`,
    :func:`reference_prior`, :func:`tile_specs`, :func:`match_tiles`, :func:`dsm_info`.
    """
    plan = plan_rpc_dsm(paths, models, posting=posting, pairs=pairs, height_range=height_range, grid=grid,
                        crs=crs, margin_px=margin_px, tile_cells=tile_cells, refine=refine, tau=tau,
                        keep_pairs=keep_pairs, window=window, splat_cells=splat_cells, median_px=median_px)
    specs = tile_specs(plan, reference_prior(plan, reference, geoid), points)
    shape = plan.grid.shape
    heights, quality, seen = np.full(shape, np.nan, np.float32), np.zeros(shape, np.uint8), np.zeros(shape, bool)

    def put(win, h, q, s):
        sl = (slice(win[0], win[0] + win[2]), slice(win[1], win[1] + win[3]))
        heights[sl], quality[sl], seen[sl] = h, q, s
    sums = match_tiles(plan, specs, put, scheduler=scheduler, workers=workers, progress=progress)
    mask = (np.isfinite(heights) & seen).astype(np.uint8) * MASK_MATCHED
    if fill:
        fill_grid(heights, mask, seen)
    g = plan.grid
    return grid_dsm(heights, seen, quality, g.transform, g.crs, g.posting, dsm_info(plan, sums, len(specs)),
                    mask=mask), sums.pairs
