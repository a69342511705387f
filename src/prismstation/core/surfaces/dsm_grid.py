"""North-up grids of the DSM (arrays only): the grid over a footprint, the cells all three
images see, resampling one grid onto another, bridging and filling voids.

A grid is ``(transform, shape)``: ``transform`` in rasterio order ``(a, b, c, d, e, f)`` with
``b = d = 0`` (north-up; ``a`` > 0 east, ``e`` < 0 north, metres of the scene CRS), ``shape``
``(rows, cols)``; cell ``(row, col)`` has its centre at ``(c + a·(col + 0.5), f + e·(row + 0.5))``.
Heights are float32 metres, NaN where void. The grid-sized steps run in strips of rows, so
that memory stays small on a 14,000 px scene at 5 m (~56 million cells).
"""
from __future__ import annotations

import math

from prismstation.core.lazy_cv2 import cv2  # imported at first use: start-up saving
import numpy as np
from scipy import ndimage

from prismstation.core.models.solution import Solution
from prismstation.core.surfaces.stereo_tile import Frame, relief_rate, view_affine
from prismstation.errors import InputError


def grid_over(en: np.ndarray, posting: float) -> tuple[tuple, tuple]:
    """The north-up grid of ``posting`` metres, aligned on multiples of it, covering the
    points ``en`` (n, 2) (E, N): ``(transform, shape)``."""
    lo, hi = en.min(axis=0), en.max(axis=0)
    e0 = math.floor(lo[0] / posting) * posting
    n0 = math.ceil(hi[1] / posting) * posting
    cols = int(math.ceil((hi[0] - e0) / posting))
    rows = int(math.ceil((n0 - lo[1]) / posting))
    return (posting, 0.0, e0, 0.0, -posting, n0), (rows, cols)


def cell_centres(transform, shape) -> np.ndarray:
    """(rows, cols, 2) map coordinates (E, N) of the grid's cell centres."""
    a, _, c, _, e, f = transform
    rows, cols = shape
    x = c + a * (np.arange(cols) + 0.5)
    y = f + e * (np.arange(rows) + 0.5)
    return np.stack(np.meshgrid(x, y), axis=-1)


def seen_by_all(sol: Solution, transform, shape, heights, window, strip: int = 512) -> np.ndarray:
    """Cells whose centre, at ``heights``, falls inside the N ``window`` and the F and B images
    (computed in strips of rows: memory stays small on 14,000 px scenes)."""
    a, _, c, _, e, f = transform
    rows, cols = shape
    ok = np.ones(shape, bool)
    i = np.arange(cols, dtype=np.float32)[None, :]
    for r0 in range(0, rows, strip):
        n = min(strip, rows - r0)
        j = np.arange(n, dtype=np.float32)[:, None]
        grid = Frame((c, f + e * r0), (1.0, 0.0), (0.0, 1.0 if e > 0 else -1.0), a, (n, cols))
        h = heights[r0:r0 + n]
        for v in ("N", "F", "B"):
            G = view_affine(sol, v)
            rr = relief_rate(sol, v, grid) @ G[:, :2].T.astype(np.float32)
            # image pixel = G·(cell centre + h·r): affine in the cell indices, float32 from the
            # strip's first cell (float64) on
            base = G[:, :2] @ np.array([c + 0.5 * a, f + e * (r0 + 0.5)]) + G[:, 2]
            x = np.float32(base[0]) + np.float32(G[0, 0] * a) * i + np.float32(G[0, 1] * e) * j + h * rr[..., 0]
            y = np.float32(base[1]) + np.float32(G[1, 0] * a) * i + np.float32(G[1, 1] * e) * j + h * rr[..., 1]
            if v == "N":
                c0, q0, w, hh = window
            else:
                (hh, w), c0, q0 = sol.scene.views[v].shape, 0, 0
            ok[r0:r0 + n] &= (x >= c0) & (x < c0 + w) & (y >= q0) & (y < q0 + hh)
    return ok


def regrid(grid: np.ndarray, grid_t, transform, shape) -> np.ndarray:
    """A north-up grid resampled (bilinear, edges extended) onto another north-up grid."""
    a, _, c, _, e, f = grid_t
    A, _, C, _, E, F = transform
    # destination index → source index
    m = np.array([[A / a, 0.0, (C + 0.5 * A - c) / a - 0.5], [0.0, E / e, (F + 0.5 * E - f) / e - 0.5]])
    return cv2.warpAffine(np.asarray(grid, np.float32), m, (shape[1], shape[0]),
                          flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_REPLICATE)


#: rows per strip and rows of halo above and below it when a large grid is bridged in strips:
#: a void is bridged from cells at most ``BRIDGE_HALO`` rows away across the strip boundary
BRIDGE_STRIP, BRIDGE_HALO = 1024, 512


def bridge(heights: np.ndarray, smooth_px: int = 5, valid: np.ndarray | None = None) -> np.ndarray:
    """Voids bridged from the nearest valid cell and median-smoothed: a prior, not a product.
    ``valid``: the cells to bridge from (default: the finite ones; a subset of them).

    Grids taller than one strip are done in strips of :data:`BRIDGE_STRIP` rows with
    :data:`BRIDGE_HALO` rows either side (the nearest-cell search needs 8 bytes per cell:
    ~0.6 GB at once on a 14,000 px scene at 5 m); a strip with no valid cell within its halo
    takes the median of the whole grid."""
    ok = np.isfinite(heights) if valid is None else valid
    if not ok.any():
        raise InputError("dense matching found no height anywhere in the window")
    rows = heights.shape[0]
    if rows <= BRIDGE_STRIP + 2 * BRIDGE_HALO:
        return _bridge(heights, ok, smooth_px)
    out = np.empty(heights.shape, np.float32)
    median = None
    for r0 in range(0, rows, BRIDGE_STRIP):
        a, b = max(r0 - BRIDGE_HALO, 0), min(r0 + BRIDGE_STRIP + BRIDGE_HALO, rows)
        r1 = min(r0 + BRIDGE_STRIP, rows)
        if ok[a:b].any():
            out[r0:r1] = _bridge(heights[a:b], ok[a:b], smooth_px)[r0 - a:r1 - a]
        else:
            median = float(np.median(heights[ok])) if median is None else median
            out[r0:r1] = median
    return out


def _bridge(heights, ok, smooth_px):
    idx = ndimage.distance_transform_edt(~ok, return_distances=False, return_indices=True)
    return cv2.medianBlur(np.asarray(heights[tuple(idx)], np.float32), smooth_px)


def fill_voids(heights: np.ndarray, iterations: int = 200) -> np.ndarray:
    """Voids filled by relaxation (repeated 3×3 means of the voids, valid cells fixed), started
    from the nearest valid cell: a smooth membrane across holes. Returns a new array."""
    ok = np.isfinite(heights)
    out = bridge(heights, 3) if (~ok).any() else heights.copy()
    out[ok] = heights[ok]
    for _ in range(iterations):
        out[~ok] = cv2.blur(out, (3, 3))[~ok]
    return out


def drop_unconfirmed(heights, quality, tolerance_m: float) -> None:
    """Cells fewer than three pairs agree on are kept only within ``tolerance_m`` of the
    surface the three-pair cells make around them (bridged, median-smoothed): a pair or two
    agreeing on a false match (at image edges, where the prior was extrapolated) goes. In
    place, in strips of rows (:func:`bridge`)."""
    full = quality >= 3
    if not full.any():
        return
    ref = bridge(heights, valid=full)
    del full
    for r0 in range(0, heights.shape[0], BRIDGE_STRIP):
        h, q, r = (a[r0:r0 + BRIDGE_STRIP] for a in (heights, quality, ref))
        bad = (q < 3) & ~(np.abs(h - r) <= tolerance_m)
        h[bad] = np.nan
        q[bad] = 0


#: cells per side of a block, and of the halo read around it, when a grid's voids are filled
#: block by block (:func:`fill_voids_in_blocks`): a void is filled from cells at most
#: ``FILL_HALO`` cells beyond its block
FILL_BLOCK, FILL_HALO = 1024, 256


def fill_voids_in_blocks(shape, read, write, block: int = FILL_BLOCK, halo: int = FILL_HALO,
                         after=None) -> int:
    """The voids of a grid of ``shape`` (rows, cols), which need not be in memory, filled block
    by block (:func:`fill_voids` over each block and its halo). ``read(r0, c0, rows, cols)``
    returns a window's ``(heights, valid, wanted)``: heights (float32), the cells to fill from
    (matched heights), the voids to fill; ``write(r0, c0, heights, new)`` receives a block's
    heights and the cells filled in it; ``after()`` is called after each block. A block whose
    halo holds no valid cell stays void.
    Returns the number of cells filled. On a grid of one block (and its halo) the result is
    :func:`fill_voids`' of the whole grid."""
    rows, cols = shape
    filled = 0
    for r0 in range(0, rows, block):
        for c0 in range(0, cols, block):
            a, b = max(r0 - halo, 0), min(r0 + block + halo, rows)
            c, d = max(c0 - halo, 0), min(c0 + block + halo, cols)
            h, valid, wanted = read(a, c, b - a, d - c)
            core = (slice(r0 - a, min(r0 + block, rows) - a), slice(c0 - c, min(c0 + block, cols) - c))
            new = wanted[core] & ~valid[core]
            if new.any() and valid.any():
                out = fill_voids(np.where(valid, h, np.nan).astype(np.float32))[core]
                write(r0, c0, np.where(new, out, h[core]), new)
                filled += int(new.sum())
            if after is not None:
                after()
    return filled
