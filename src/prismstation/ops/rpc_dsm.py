"""A DSM from images with RPCs: each pair matched on local epipolar tiles, the pairs fused.

For every pair of images and every tile of the output grid (north-up, a UTM zone by default,
ellipsoidal heights), the left image's window seeing the tile is rectified with the right
image (:func:`prismstation.core.rpc_epipolar.rectify_pair`, through the biased RPCs), matched
by OpenCV's StereoSGBM with the ZNCC subpixel refinement of the PRISM DSM
(:mod:`prismstation.core.sgm`), triangulated through the RPCs and binned into the tile's cells.
Tiles are independent Dask tasks (:func:`prismstation.ops.dsm_tiles.run_tiles`); each reads its
own windows, so a tile runs in a thread, a process or on a ``dask.distributed`` worker.

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
import warnings
from dataclasses import dataclass, field
from functools import lru_cache

import cv2
import numpy as np
import pyproj
import rasterio
from rasterio.errors import NotGeoreferencedWarning
from rasterio.windows import Window

from prismstation.core import sgm
from prismstation.core.rpc_bias import as_biased
from prismstation.core.rpc_epipolar import (grid_heights, ray_lattice, rectify_pair, source_window,
                                            triangulate, warp)
from prismstation.core.stats import nmad
from prismstation.errors import InputError, ModelError
from prismstation.io.dem import read_dem
from prismstation.io.raster import gdal_env
from prismstation.ops.dsm import MASK_MATCHED, Dsm
from prismstation.ops.dsm_tiles import run_tiles

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


@lru_cache(maxsize=16)
def _transformer(crs: str, inverse: bool) -> pyproj.Transformer:
    a, b = ("EPSG:4326", crs) if not inverse else (crs, "EPSG:4326")
    return pyproj.Transformer.from_crs(a, b, always_xy=True)


def to_map(crs: str):
    """``(lon°, lat°) → (E, N)`` of ``crs``."""
    t = _transformer(str(crs), False)
    return lambda lon, lat: t.transform(lon, lat)


def to_lonlat(crs: str):
    t = _transformer(str(crs), True)
    return lambda e, n: t.transform(e, n)


def utm_crs(lon: float, lat: float) -> str:
    """The WGS 84 UTM zone's CRS at ``(lon, lat)``."""
    zone = int(np.floor((lon + 180.0) / 6.0)) % 60 + 1
    return f"EPSG:{(32600 if lat >= 0 else 32700) + zone}"


def _open(path):
    """rasterio's dataset of an image; an image whose RPCs are in a side file is not
    georeferenced in GDAL's sense, which is no reason for a warning."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        return rasterio.open(path)


def image_shape(path) -> tuple[int, int]:
    try:
        with _open(path) as ds:
            return ds.height, ds.width
    except rasterio.errors.RasterioError as exc:
        raise InputError(f"cannot open the image ({exc})", path) from None


def rpc_height_domain(models) -> tuple[float, float]:
    """The heights every RPC is valid for (``h_off ± h_scale``, intersected), metres."""
    m = [as_biased(v).rpc for v in models]
    lo = max(r.h_off - abs(r.h_scale) for r in m)
    hi = min(r.h_off + abs(r.h_scale) for r in m)
    if not hi > lo:
        raise ModelError("the images' RPC height domains do not overlap")
    return lo, hi


@dataclass(frozen=True)
class Grid:
    """North-up output grid: ``crs`` (string), ``transform`` (a, 0, c, 0, e, f), ``shape``."""

    crs: str
    transform: tuple
    shape: tuple

    @property
    def posting(self) -> float:
        return float(self.transform[0])

    def cell_centres(self, window=None):
        r0, c0, rows, cols = window or (0, 0) + tuple(self.shape)
        a, _, c, _, e, f = self.transform
        E = c + a * (c0 + np.arange(cols) + 0.5)
        N = f + e * (r0 + np.arange(rows) + 0.5)
        return np.meshgrid(E, N)


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


@dataclass(frozen=True)
class PairTile:
    """One tile of one pair (everything a worker needs): image ``paths`` and ``models``
    (left, right), output cells ``window`` (row0, col0, rows, cols) of ``grid``, the height
    range (m), the disparity margin (px), SGBM's block, the subpixel refinement, and the
    disparity σ (px) for the heights' σ."""

    paths: tuple
    models: tuple
    grid: Grid
    window: tuple
    height_range: tuple
    margin_px: float = 2.0
    block: int = 5
    refine: bool = True
    sigma_px: float = sgm.SIGMA_DISPARITY_PX


def _read(path, win) -> np.ndarray:
    """Window (x0, y0, w, h) of band 1 as float32, NaN outside the image."""
    x0, y0, w, h = win
    out = np.full((h, w), np.nan, np.float32)
    with _open(path) as ds:
        c0, r0 = max(x0, 0), max(y0, 0)
        c1, r1 = min(x0 + w, ds.width), min(y0 + h, ds.height)
        if c1 > c0 and r1 > r0:
            out[r0 - y0:r1 - y0, c0 - x0:c1 - x0] = ds.read(1, window=Window(c0, r0, c1 - c0, r1 - r0),
                                                            out_dtype="float32")
    return out


def left_window(spec: PairTile, shape_a):
    """The left image's window (x0, y0, w, h) px seeing the tile's cells over its height
    range, clipped to the image; None if it sees none of it."""
    r0, c0, rows, cols = spec.window
    a, _, c, _, e, f = spec.grid.transform
    E = c + a * np.array([c0, c0 + cols, c0, c0 + cols, c0 + cols / 2])
    N = f + e * np.array([r0, r0, r0 + rows, r0 + rows, r0 + rows / 2])
    lon, lat = to_lonlat(spec.grid.crs)(E, N)
    m = as_biased(spec.models[0])
    xs, ys = [], []
    for h in spec.height_range:
        x, y = m.project(lon, lat, h)
        xs.append(x), ys.append(y)
    x, y = np.concatenate(xs), np.concatenate(ys)
    x0, y0 = max(0.0, np.floor(x.min())), max(0.0, np.floor(y.min()))
    x1, y1 = min(float(shape_a[1]), np.ceil(x.max())), min(float(shape_a[0]), np.ceil(y.max()))
    if x1 - x0 < 16 or y1 - y0 < 16:
        return None
    return (x0, y0, x1 - x0, y1 - y0)


def run_pair_tile(spec: PairTile):
    """Match one tile of one pair: ``(heights, counts, sigma, stats)`` on the tile's cells
    (float32 mean ellipsoidal height, samples per cell, the height's σ in metres from the
    disparity σ; NaN where none) and a dict of what happened (rectification error, search,
    matched share, seconds)."""
    cv2.setNumThreads(1)
    t0 = time.perf_counter()
    rows, cols = spec.window[2], spec.window[3]
    empty = (np.full((rows, cols), np.nan, np.float32), np.zeros((rows, cols), np.int32),
             np.full((rows, cols), np.nan, np.float32))
    with gdal_env():
        shape_a = image_shape(spec.paths[0])
        win = left_window(spec, shape_a)
        if win is None:
            return empty + ({"skipped": "outside the left image"},)
        a, b = (as_biased(m) for m in spec.models)
        try:
            rect = rectify_pair(a, b, win, spec.height_range, margin_px=spec.margin_px)
        except ModelError as exc:
            return empty + ({"skipped": str(exc)},)
        views = []
        for path, aff in ((spec.paths[0], rect.left), (spec.paths[1], rect.right)):
            sw = source_window(aff, rect.shape)
            views.append(warp(_read(path, sw), sw[:2], aff, rect.shape))
    valid = [np.isfinite(v) for v in views]
    u8 = [sgm.to_uint8(v, ok) for v, ok in zip(views, valid)]
    d = sgm.sgbm(u8[0], u8[1], *rect.search, block=spec.block)
    if spec.refine:
        f32 = [np.where(ok, v, 0).astype(np.float32) for v, ok in zip(views, valid)]
        d = sgm.refine_subpixel(f32[0], f32[1], d)
    # no match within two blocks of either image's edge (SGBM's paths run through the blank)
    kernel = np.ones((2 * spec.block, 2 * spec.block), np.uint8)
    bad = [cv2.dilate((~ok).astype(np.uint8), kernel) for ok in valid]
    xr = np.arange(rect.shape[1], dtype=np.float32)[None, :] - d
    yy = np.repeat(np.arange(rect.shape[0], dtype=np.float32)[:, None], rect.shape[1], 1)
    bad_r = cv2.remap(bad[1], xr, yy, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT, borderValue=1)
    d[(bad[0] > 0) | (bad_r > 0)] = np.nan
    lattice = ray_lattice(a, b, rect, to_map(spec.grid.crs))
    tri = triangulate(rect, lattice, d)
    r0, c0 = spec.window[:2]
    gt = spec.grid.transform
    tile_t = (gt[0], 0.0, gt[2] + gt[0] * c0, 0.0, gt[4], gt[5] + gt[4] * r0)
    h, cnt, mpp = grid_heights(tri.e, tri.n, tri.h, tile_t, (rows, cols), extra=tri.m_per_px)
    sigma = (spec.sigma_px * mpp / np.sqrt(np.maximum(cnt, 1))).astype(np.float32)
    stats = {"epipolar_error_px": rect.epipolar_error_px, "search": rect.search,
             "height_range": tuple(rect.heights), "px_per_m": rect.px_per_m,
             "matched": float(np.isfinite(d).mean()), "seconds": time.perf_counter() - t0}
    return h, cnt, sigma, stats


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


def seen_by_all(models, shapes, grid: Grid, heights, window=None) -> np.ndarray:
    """Cells (of ``window`` = (row0, col0, rows, cols), default the grid) whose centre at
    ``heights`` (NaN → their median) falls inside every image."""
    E, N = grid.cell_centres(window)
    lon, lat = to_lonlat(grid.crs)(E, N)
    h = np.where(np.isfinite(heights), heights, np.nanmedian(heights) if np.isfinite(heights).any() else 0.0)
    seen = np.ones(E.shape, bool)
    for model, (rows, cols) in zip(models, shapes):
        x, y = as_biased(model).project(lon, lat, h)
        seen &= (x >= 0) & (x < cols) & (y >= 0) & (y < rows)
    return seen


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


def fuse_pairs(vals, sig, tau: float, posting: float):
    """Fused heights and quality (pairs agreeing) of pair heights ``vals`` (P, rows, cols)
    with σ ``sig`` (module docstring of :func:`rpc_dsm`)."""
    if len(vals) == 1:
        h = vals[0].copy()
        return h, np.where(np.isfinite(h), 1, 0).astype(np.uint8)
    h, q = sgm.fuse(vals, sig, tau)
    finite = np.isfinite(sig)
    tol = max(tau * 2 * float(np.median(sig[finite])) if finite.any() else 0.0, 3 * posting)
    return sgm.resolve_single(h, q, vals, tol)


@dataclass(frozen=True)
class BlockTile:
    """One output tile of every pair (what a worker needs): the images' ``paths``,
    ``models`` and ``shapes``, the index ``pairs``, the cells ``window`` of ``grid``, the
    tile's height range (m), the disparity margin (px), the refinement and the fusion's τ."""

    paths: tuple
    models: tuple
    shapes: tuple
    pairs: tuple
    grid: Grid
    window: tuple
    height_range: tuple
    margin_px: float = 2.0
    refine: bool = True
    tau: float = 3.0


def run_block_tile(spec: BlockTile):
    """Every pair of one tile, fused: ``(heights, quality, seen, pair heights, pair σ,
    pair counts, pair stats)`` on the tile's cells (pair arrays (P, rows, cols))."""
    outs = [run_pair_tile(PairTile((spec.paths[i], spec.paths[j]), (spec.models[i], spec.models[j]),
                                   spec.grid, spec.window, spec.height_range, margin_px=spec.margin_px,
                                   refine=spec.refine))
            for i, j in spec.pairs]
    vals = np.stack([o[0] for o in outs])
    counts = np.stack([o[1] for o in outs])
    sig = np.stack([o[2] for o in outs])
    h, q = fuse_pairs(vals, sig, spec.tau, spec.grid.posting)
    seen = seen_by_all(spec.models, spec.shapes, spec.grid, h, spec.window)
    h[~seen] = np.nan
    q[~seen] = 0
    return h, q, seen, vals, sig, counts, [o[3] for o in outs]


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
