"""The tiles of the RPC DSM: one output tile of one pair (:func:`run_pair_tile`: window,
local epipolar rectification, SGBM, triangulation, binning) and of every pair, fused
(:func:`run_block_tile`). A tile's spec holds all it needs (image paths, models, grid,
window, height range): tiles run in threads, processes or on ``dask.distributed`` workers
(:func:`prismstation.ops.dsm_tiles.run_tiles`). Map coordinates are metres of the grid's
projected CRS; heights ellipsoidal metres.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

from prismstation.core.lazy_cv2 import cv2  # imported at first use: start-up saving
import numpy as np

from prismstation.core.matching import sgm
from prismstation.core.models.rpc_bias import as_biased
from prismstation.core.surfaces.rpc_epipolar import (grid_heights, ray_lattice, rectify_pair, source_window,
                                            triangulate, warp)
from prismstation.errors import ModelError
from prismstation.io.raster import gdal_env
from prismstation.io.rpc_scene import to_lonlat, to_map
from prismstation.io.windows import open_image, raster_header


def image_shape(path) -> tuple[int, int]:
    """``(rows, cols)`` of the image ``path`` (:func:`~prismstation.io.windows.raster_header`)."""
    width, height, _ = raster_header(path)
    return height, width


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


@dataclass(frozen=True)
class PairTile:
    """One tile of one pair (everything a worker needs): image ``paths`` and ``models``
    (left, right), output cells ``window`` (row0, col0, rows, cols) of ``grid``, the height
    range (m), the disparity margin (px), SGBM's block, the subpixel refinement, and the
    disparity σ (px) for the heights' σ, and the σ (cells) of the Gaussian that spreads each
    triangulated point over the cells around it (:func:`~prismstation.core.surfaces.rpc_epipolar.grid_heights`;
    0: each point in its own cell), and the size of the median filter of the disparities
    (:func:`~prismstation.core.matching.sgm.median_filter`; 0 or 1: none)."""

    paths: tuple
    models: tuple
    grid: Grid
    window: tuple
    height_range: tuple
    margin_px: float = 2.0
    block: int = 5
    refine: bool = True
    sigma_px: float = sgm.SIGMA_DISPARITY_PX
    splat_cells: float = 0.0
    median_px: int = 0


def _read(path, win) -> np.ndarray:
    """Window (x0, y0, w, h) of band 1 as float32, NaN outside the image."""
    with open_image(path, "image") as ds:
        return ds.read_padded(*win)


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
    empty = (np.full((rows, cols), np.nan, np.float32), np.zeros((rows, cols), np.float32),
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
    if spec.median_px > 1:
        d = sgm.median_filter(d, spec.median_px)
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
    h, cnt, mpp = grid_heights(tri.e, tri.n, tri.h, tile_t, (rows, cols), extra=tri.m_per_px,
                               sigma_cells=spec.splat_cells)
    sigma = (spec.sigma_px * mpp / np.sqrt(np.maximum(cnt, 1))).astype(np.float32)
    stats = {"epipolar_error_px": rect.epipolar_error_px, "search": rect.search,
             "height_range": tuple(rect.heights), "px_per_m": rect.px_per_m,
             "matched": float(np.isfinite(d).mean()), "seconds": time.perf_counter() - t0}
    return h, cnt, sigma, stats


def seen_by(models, shapes, grid: Grid, heights, window=None, crop=None) -> np.ndarray:
    """``(n_images, rows, cols)`` bool: which image sees each cell (of ``window`` = (row0, col0,
    rows, cols), default the grid) — its centre at ``heights`` (NaN → their median) inside the
    image — all False outside ``crop`` (col0, row0, cols, rows) of the first image when given."""
    E, N = grid.cell_centres(window)
    lon, lat = to_lonlat(grid.crs)(E, N)
    h = np.where(np.isfinite(heights), heights, np.nanmedian(heights) if np.isfinite(heights).any() else 0.0)
    inside = np.zeros((len(models),) + E.shape, bool)
    for k, (model, (rows, cols)) in enumerate(zip(models, shapes)):
        x, y = as_biased(model).project(lon, lat, h)
        inside[k] = (x >= 0) & (x < cols) & (y >= 0) & (y < rows)
        if k == 0 and crop is not None:
            c0, r0, w, hh = crop
            in_crop = (x >= c0) & (x < c0 + w) & (y >= r0) & (y < r0 + hh)
    if crop is not None:
        inside &= in_crop[None]
    return inside


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
    tile's height range (m), the disparity margin (px), the refinement, the fusion's τ and the
    ``crop`` (col0, row0, cols, rows) of the first image the DSM is limited to (None: all) and
    the gridding's ``splat_cells`` and the disparities' ``median_px`` (:class:`PairTile`)."""

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
    crop: tuple | None = None
    splat_cells: float = 0.0
    median_px: int = 0


def run_block_tile(spec: BlockTile):
    """Every pair of one tile, fused: ``(heights, quality, seen, pair heights, pair σ,
    pair counts, pair stats)`` on the tile's cells (pair arrays (P, rows, cols))."""
    outs = [run_pair_tile(PairTile((spec.paths[i], spec.paths[j]), (spec.models[i], spec.models[j]),
                                   spec.grid, spec.window, spec.height_range, margin_px=spec.margin_px,
                                   refine=spec.refine, splat_cells=spec.splat_cells,
                                   median_px=spec.median_px))
            for i, j in spec.pairs]
    vals = np.stack([o[0] for o in outs])
    counts = np.stack([o[1] for o in outs])
    sig = np.stack([o[2] for o in outs])
    h, q = fuse_pairs(vals, sig, spec.tau, spec.grid.posting)
    with np.errstate(invalid="ignore"):
        where = np.where(np.isfinite(h), h, np.fmax.reduce(vals, axis=0))     # where to look
    inside = seen_by(spec.models, spec.shapes, spec.grid, where, spec.window, spec.crop)
    pair_sees = np.stack([inside[i] & inside[j] for i, j in spec.pairs])
    # a cell one pair alone sees (two images of three) keeps that pair's height, as a pair DSM
    alone = pair_sees.sum(axis=0) == 1
    only = np.take_along_axis(vals, np.argmax(pair_sees, axis=0)[None], 0)[0]       # the one pair seeing
    h[alone], q[alone] = only[alone], np.isfinite(only[alone])
    seen = pair_sees.any(axis=0)
    h[~seen] = np.nan
    q[~seen] = 0
    return h, q, seen, vals, sig, counts, [o[3] for o in outs]
