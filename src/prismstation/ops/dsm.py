"""The DSM of an oriented triplet: coarse to fine, tiled, three pairs fused.

Levels: matching frames of ``g = g_fine·2^L`` metres per pixel (``g_fine = max(GSD,
posting/2)``); the coarsest level is the first whose height search, the stated a-priori height
uncertainty ``±R`` around the prior (the mean height of the fitted points, or a reference DEM),
fits in ±24 px of the F–B pair. Each level's DSM (voids bridged, smoothed) is the prior of the
next, searched within ``±3·g`` of the previous level (16 disparities at the next level); the
level at ``2·g_fine`` is skipped and the finest searches ``±1.8·4·g_fine`` (16 disparities
for F–B too). Only the finest level is refined to subpixel (the coarser ones
only make a smoothed prior). Each level is cut into tiles that overlap by ``overlap_m`` and
are cross-faded (no seams); every tile is an independent Dask task
(:mod:`prismstation.ops.dsm_tiles`).

Output: heights (ellipsoidal, or orthometric through a geoid), the mask of cells all three
images see, which of them matched (mask 1), were filled (2) or stayed void (0), the number of
pairs agreeing per cell, and the fill percentage over the seen cells.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from prismstation.core.lazy_cv2 import cv2  # imported at first use: start-up saving
import numpy as np

from prismstation.core.surfaces.dsm_grid import (BRIDGE_STRIP, bridge, cell_centres, drop_unconfirmed,
                                        fill_voids, grid_over, regrid, seen_by_all)
from prismstation.core.surfaces.dsm_heights import HEIGHT_MODELS, choose_heights, model_height_correction
from prismstation.core.models.solution import Solution
from prismstation.errors import InputError
from prismstation.ops.dsm_tiles import TileSpec, return_freed_memory, run_tiles
from prismstation.ops.progress import checkpoint, scaled

MASK_VOID, MASK_MATCHED, MASK_FILLED = 0, 1, 2
#: a-priori height uncertainty (m) of a reference DEM used as the prior (SRTM-like σ ≈ 10 m,
#: and the orientation's own offset): the coarsest search is ±4σ
REFERENCE_DEM_UNCERTAINTY_M = 40.0
#: a level after the coarsest searches ±this many of the previous level's pixels around it
#: and into the finest level (1.8: the F–B search fits in 16 disparities, not 32; 2,000 px at 5 m:
#: NMAD and RMSE per slope class within 0.02 m of 3; 1.5 lost 1.5 % fill on a 700 px scene)
NEXT_LEVEL_SEARCH_IN_G = 3.0
FINEST_SEARCH_IN_G = 1.8


@dataclass(frozen=True)
class Dsm:
    """A DSM on a north-up grid.

    heights : (rows, cols) float32 metres, NaN where void (or outside what all views see).
    transform : rasterio order (a, b, c, d, e, f). crs : the scene's CRS.
    height_kind : "ellipsoidal" or "orthometric". valid_fraction : filled share of seen cells.
    mask : uint8, 0 void or unseen, 1 matched, 2 filled by interpolation. seen : bool, cells
    that all three images see. quality : uint8, pairs agreeing (0–3; 1 = one pair checked
    against its neighbourhood only). geoid : description of the geoid for orthometric heights.
    counts : a DSM written tile by tile holds no grid (``heights``, ``mask``, ``seen``,
    ``quality`` None; it is in its file): its ``shape`` (rows, cols) and cells ``seen``,
    ``matched`` and ``filled``.
    """

    heights: np.ndarray
    transform: tuple
    crs: str
    height_kind: str
    valid_fraction: float
    mask: np.ndarray = None
    seen: np.ndarray = None
    quality: np.ndarray = None
    posting_m: float = 0.0
    geoid: str | None = None
    info: dict = field(default_factory=dict)
    counts: dict | None = None

    @property
    def shape(self) -> tuple:
        """(rows, cols) of the grid."""
        return tuple(self.heights.shape) if self.heights is not None else tuple(self.counts["shape"])

    def cells(self, what: str) -> int:
        """Cells ``seen`` by every image, ``matched`` or ``filled`` among them."""
        if self.counts is not None:
            return int(self.counts[what])
        if self.seen is None:
            return 0
        if what == "seen":
            return int(self.seen.sum())
        value = MASK_MATCHED if what == "matched" else MASK_FILLED
        return int(((self.mask == value) & self.seen).sum()) if self.mask is not None else 0

    @property
    def fill_fraction(self) -> float:
        """Share of the seen cells with a matched (not filled) height."""
        n = self.cells("seen")
        return self.cells("matched") / n if n else 0.0


def grid_dsm(heights, seen, quality, transform, crs: str, posting_m: float, info: dict, *, mask=None,
             height_kind: str = "ellipsoidal", geoid: str | None = None) -> Dsm:
    """The :class:`Dsm` of ``heights`` on a grid, the last step of every DSM (a triplet's, images
    with RPCs'): ``mask`` (default: :data:`MASK_MATCHED` where a ``seen`` cell has a height,
    :data:`MASK_VOID` elsewhere) and the share of the seen cells with a height."""
    n_seen = int(seen.sum())
    if mask is None:
        mask = (np.isfinite(heights) & seen).astype(np.uint8) * MASK_MATCHED
    valid = float(np.isfinite(heights[seen]).sum() / n_seen) if n_seen else 0.0
    return Dsm(heights, transform, crs, height_kind, valid, mask, seen, quality, posting_m, geoid, info)


def _track_tiles(sol, transform, shape, wanted, size_m: float, overlap_m: float):
    """Rectangles aligned with the flight direction covering the wanted cells: ``(rect, window)``
    with ``rect`` = (origin, t, u, x0, x1, y0, y1) in metres along/across track, overlap
    included, and ``window`` = (row0, col0, rows, cols), the grid cells around it."""
    step = max(1, max(shape) // 1500)               # a subsample is enough to place tiles
    sub = (transform[0] * step, 0.0, transform[2], 0.0, transform[4] * step, transform[5])
    sub_shape = (-(-shape[0] // step), -(-shape[1] // step))
    en = cell_centres(sub, sub_shape)
    pts = en[wanted[::step, ::step]] if wanted is not None else en.reshape(-1, 2)
    origin = pts.mean(axis=0)
    _, t = sol.scene.track.foot(origin)
    u = np.array([-t[1], t[0]])
    x, y = (pts - origin) @ t, (pts - origin) @ u
    a, _, c, _, e, f = transform
    rows, cols = shape
    # as many tiles as the extent needs, evenly sized; each shrunk to the wanted cells in it
    nx = max(1, int(np.ceil((x.max() - x.min()) / size_m)))
    ny = max(1, int(np.ceil((y.max() - y.min()) / size_m)))
    xs = np.linspace(x.min(), x.max(), nx + 1)
    ys = np.linspace(y.min(), y.max(), ny + 1)
    for k in range(nx):
        for m in range(ny):
            core = (x >= xs[k]) & (x <= xs[k + 1]) & (y >= ys[m]) & (y <= ys[m + 1])
            if not core.any():
                continue
            r = (x[core].min() - overlap_m, x[core].max() + overlap_m,
                 y[core].min() - overlap_m, y[core].max() + overlap_m)
            corners = np.array([origin + xx * t + yy * u for xx in r[:2] for yy in r[2:]])
            i0 = max(int(np.floor((corners[:, 0].min() - c) / a)), 0)
            i1 = min(int(np.ceil((corners[:, 0].max() - c) / a)), cols)
            j0 = max(int(np.floor((corners[:, 1].max() - f) / e)), 0)
            j1 = min(int(np.ceil((corners[:, 1].min() - f) / e)), rows)
            if i1 > i0 and j1 > j0:
                yield (tuple(origin), tuple(t), tuple(u)) + r, (j0, i0, j1 - j0, i1 - i0)


def _level(plan, transform, shape, g, half_range, prior, prior_t, *, overlap_m,
           refine, scheduler, workers, progress, wanted=None):
    """One level: heights and quality on (transform, shape) from tiled matching; tiles are
    rectangles along the flight direction (their frames waste no corners), cross-faded over
    ``2·overlap_m``."""
    specs = []
    sol = plan.sol
    reach = 2.5 * half_range + 32 * g      # the prior a frame needs beyond its cells
    for rect, window in _track_tiles(sol, transform, shape, wanted, plan.tile_px * g, overlap_m):
        specs.append(TileSpec(sol, window, transform, g, half_range, *_crop(
            prior, prior_t, transform, window, reach), refine=refine, rect=rect, overlap_m=overlap_m))
    acc = np.zeros(shape, np.float32)
    wsum = np.zeros(shape, np.float32)
    qacc = np.zeros(shape, np.float16)     # Σ w·q ≤ 6: resolution 0.004, rounded to 0–3 below
    z = []

    def add(i, result):
        h, q, w, zn = result
        r0, c0, nr, nc = specs[i].window
        w = w * np.isfinite(h)
        acc[r0:r0 + nr, c0:c0 + nc] += w * np.nan_to_num(h)
        qacc[r0:r0 + nr, c0:c0 + nc] += w * q
        wsum[r0:r0 + nr, c0:c0 + nc] += w
        if zn[1]:
            z.append(zn)

    run_tiles(specs, add, scheduler, workers, progress)
    z_nmad = float(np.average([zn for zn, _ in z], weights=[n for _, n in z])) if z else float("nan")
    # in place and in strips: no grid-sized temporaries (a 14,000 px scene at 5 m has ~56
    # million cells)
    quality = np.zeros(shape, np.uint8)
    for r0 in range(0, shape[0], BRIDGE_STRIP):
        a, w, q = (v[r0:r0 + BRIDGE_STRIP] for v in (acc, wsum, qacc))
        none = w <= 0
        w[none] = 1.0
        np.divide(a, w, out=a)
        a[none] = np.nan
        quality[r0:r0 + BRIDGE_STRIP] = np.where(none, 0, np.rint(q / w))
    del wsum, qacc
    return_freed_memory()
    return acc, quality, len(specs), z_nmad


def _crop(prior, prior_t, transform, window, reach):
    """The part of the prior grid within ``reach`` metres of a tile's cells."""
    a, _, c, _, e, f = transform
    r0, c0, nr, nc = window
    pa, _, pc, _, pe, pf = prior_t
    x0, x1 = c + a * c0 - reach, c + a * (c0 + nc) + reach
    y1, y0 = f + e * r0 + reach, f + e * (r0 + nr) - reach
    rows, cols = prior.shape
    i0, i1 = max(int((x0 - pc) / pa), 0), min(int(math.ceil((x1 - pc) / pa)) + 1, cols)
    j0, j1 = max(int((y1 - pf) / pe), 0), min(int(math.ceil((y0 - pf) / pe)) + 1, rows)
    i1, j1 = max(i1, i0 + 1), max(j1, j0 + 1)
    crop = np.ascontiguousarray(prior[j0:j1, i0:i1], np.float32)
    return crop, (pa, 0.0, pc + pa * i0, 0.0, pe, pf + pe * j0)


def default_uncertainty(sol: Solution) -> float:
    """±R (m) around the mean height when no reference DEM is given: 1.5 × the largest
    departure of the fitted points from their mean, plus 300 m (summits and valleys the points
    do not sample)."""
    hs = [p.ground_est[2] for p in sol.points if p.ground_est is not None]
    spread = max((abs(h - sol.mean_height) for h in hs), default=600.0)
    return 1.5 * spread + 300.0


def _follow_line(sol: Solution, heights: np.ndarray, t, info: dict) -> None:
    """Turn the matching's ray heights (grid ``heights``, transform ``t``) into the model's
    parallax-line heights in place, in strips of rows; the correction's range into ``info``."""
    lo, hi = np.nanpercentile(heights[::7, ::7], [1, 99]) if np.isfinite(heights).any() else (sol.mean_height,) * 2
    corr = model_height_correction(sol, float(lo), float(hi))
    span = []
    for r0 in range(0, heights.shape[0], 512):
        en = cell_centres((t[0], 0.0, t[2], 0.0, t[4], t[5] + t[4] * r0), (min(512, heights.shape[0] - r0), heights.shape[1]))
        dh = corr(en, heights[r0:r0 + 512]).astype(np.float32)
        heights[r0:r0 + 512] += dh
        if np.isfinite(dh).any():
            span += [float(np.nanmin(dh)), float(np.nanmax(dh))]
    info["model_height_correction_m"] = {"min": min(span, default=0.0), "max": max(span, default=0.0),
                                         "per_m_of_height": corr.coef[3]}


@dataclass(frozen=True)
class DsmPlan:
    """What every step of :func:`make_dsm` shares: the solution, the N-image ``window``, the
    output ``posting_m``, the finest matching pixel ``g_fine`` (m), the a-priori ±``R`` (m)
    of the prior, the levels in the order they run (``order``: exponents L of
    ``g = g_fine·2^L``, coarsest first), the ground ``foot`` (n, 2) the window covers between
    ``mean ± R``, and the tiling (``tile_px`` frame pixels a side, ``overlap_m``)."""

    sol: Solution
    window: tuple
    posting_m: float
    g_fine: float
    R: float
    order: tuple
    foot: np.ndarray
    tile_px: int
    overlap_m: float

    def g(self, L: int) -> float:
        return self.g_fine * 2 ** L

    def posting(self, L: int) -> float:
        """The grid posting of level ``L``: the output's at the finest, 2·g above it."""
        return self.posting_m if L == 0 else 2 * self.g(L)


def make_dsm(sol: Solution, window=None, *, posting_m: float = 10.0, orthometric_geoid=None,
             progress=None, reference=None, height_uncertainty_m: float | None = None,
             fill: bool = False, refine: bool = True, scheduler=None, workers: int | None = None,
             tile_px: int = 1024, overlap_m: float | None = None, heights_model: str = "auto") -> Dsm:
    """DSM of the ground seen in the N-image ``window`` (col0, row0, cols, rows; default all).

    ``reference``: optional prior, a ``(heights, transform)`` north-up grid of ellipsoidal
    heights in the scene CRS (a reference DEM read onto a grid). ``height_uncertainty_m``: the
    a-priori ±R of the prior (default :func:`default_uncertainty`, or 40 m with a reference).
    ``fill``: fill voids by interpolation (mask 2). ``refine``: ZNCC subpixel refinement
    after SGBM. ``scheduler``, ``workers``: see :mod:`prismstation.ops.dsm_tiles`.
    ``progress(fraction, message)`` returning False cancels (:class:`Cancelled`).
    ``heights_model``: ``auto``, ``line`` or ``rays`` (:mod:`prismstation.core.surfaces.dsm_heights`);
    the choice and its reason are in ``info["heights"]``.

    The steps: :func:`plan_dsm`, :func:`starting_prior`, :func:`match_levels`,
    :func:`finish_dsm`.
    """
    if heights_model not in HEIGHT_MODELS:
        raise InputError(f"unknown DSM height model {heights_model!r}; choose one of {', '.join(HEIGHT_MODELS)}")
    plan = plan_dsm(sol, window, posting_m, reference is not None, height_uncertainty_m,
                    tile_px=tile_px, overlap_m=overlap_m)
    choice = choose_heights(sol, heights_model)
    prior, prior_t = starting_prior(plan, reference)
    heights, quality, t, info = match_levels(plan, prior, prior_t, refine=refine, scheduler=scheduler,
                                             workers=workers, progress=progress)
    checkpoint(progress, 0.96, "mask and fill")
    info["heights"] = choice.record()
    if choice.model == "line":
        _follow_line(sol, heights, t, info)
    return finish_dsm(plan, heights, quality, t, info, fill=fill, orthometric_geoid=orthometric_geoid,
                      progress=progress)


def plan_dsm(sol: Solution, window, posting_m: float, with_reference: bool,
             height_uncertainty_m: float | None, *, tile_px: int = 1024,
             overlap_m: float | None = None) -> DsmPlan:
    """The levels and the footprint (module docstring): the coarsest level is the first whose
    F–B search of ±R fits in ±24 px; the level at 2·g_fine is skipped."""
    sc = sol.scene
    if not sc.is_triplet or getattr(sol.model, "parallax", None) is None:
        raise InputError("a DSM needs an oriented N, F, B triplet")
    if not (posting_m > 0 and math.isfinite(posting_m)):
        raise InputError(f"the posting must be a positive number of metres, got {posting_m}")
    rows_n, cols_n = sc.views["N"].shape
    window = tuple(int(v) for v in (window or (0, 0, cols_n, rows_n)))
    gsd = sc.views["N"].pixel_size_m
    g_fine = max(gsd, posting_m / 2.0)
    k_fb = sc.views["F"].tan_theta + sc.views["B"].tan_theta
    R = float(height_uncertainty_m or (REFERENCE_DEM_UNCERTAINTY_M if with_reference
                                       else default_uncertainty(sol)))
    levels = 0
    while k_fb * R / (g_fine * 2 ** levels) > 24:
        levels += 1
    c0, r0, w, h = window
    corners = np.array([[c0, r0], [c0 + w, r0], [c0, r0 + h], [c0 + w, r0 + h]], float)
    foot = _shared_ground(sol, np.concatenate([sol.image_to_ground("N", corners, sol.mean_height + d)
                                               for d in (-R, R)]), R)
    # steps of 2 down to 4·g_fine, then straight to g_fine: the level at 2·g_fine cost a
    # quarter of the finest and changed nothing measurable (2000 px, 5 m: NMAD 0.97 → 0.99 m,
    # RMSE 1.34 → 1.36 m, time −27 %)
    order = tuple(L for L in range(levels, -1, -1) if not (L == 1 and levels >= 2))
    size = np.ptp(foot, axis=0) / g_fine
    if size[0] * size[1] > MAX_DSM_CELLS:
        raise InputError(f"a DSM of {size[0]:,.0f} × {size[1]:,.0f} cells at {g_fine:g} m is too large "
                         f"(at most {MAX_DSM_CELLS:,}): choose a window or a coarser posting")
    return DsmPlan(sol, window, posting_m, g_fine, R, order, foot, tile_px, overlap_m or 10 * g_fine)


#: the most cells a DSM grid may have (a 150 km square at 5 m): more is refused, not allocated
MAX_DSM_CELLS = 9 * 10 ** 8


def _shared_ground(sol: Solution, foot: np.ndarray, R: float) -> np.ndarray:
    """The corners of the map box of ``foot`` (N's window on the ground, ``(n, 2)``) cut to the
    boxes of F's and B's whole images at the mean height ± ``R``: the DSM's grid covers only
    ground the three images can share, whatever size N declares. No shared ground, or a grid
    that would still be too large, is an :class:`InputError`."""
    lo, hi = foot.min(axis=0), foot.max(axis=0)
    for v in ("F", "B"):
        rows, cols = sol.scene.views[v].shape
        px = np.array([[0, 0], [cols, 0], [0, rows], [cols, rows]], float)
        g = np.concatenate([sol.image_to_ground(v, px, sol.mean_height + d) for d in (-R, R)])
        lo, hi = np.maximum(lo, g.min(axis=0)), np.minimum(hi, g.max(axis=0))
    if not np.all(hi > lo):
        raise InputError("N (in the window asked for), F and B share no ground: there is no DSM to make")
    return np.array([lo, [hi[0], lo[1]], [lo[0], hi[1]], hi])


def starting_prior(plan: DsmPlan, reference) -> tuple[np.ndarray, tuple]:
    """The prior on the coarsest level's grid: the reference ``(heights, transform)`` (voids
    bridged) resampled onto it, or the mean height of the fitted points."""
    prior_t, prior_shape = grid_over(plan.foot, 2 * plan.g(plan.order[0]))
    if reference is not None:
        return regrid(bridge(np.asarray(reference[0], np.float32), 3), reference[1], prior_t, prior_shape), prior_t
    return np.full(prior_shape, plan.sol.mean_height, np.float32), prior_t


def match_levels(plan: DsmPlan, prior, prior_t, *, refine: bool, scheduler, workers, progress):
    """Every level coarse to fine, each one's DSM (cells two or more pairs agree on, bridged)
    the prior of the next. Returns the finest level's ``(heights, quality, transform, info)``."""
    order = plan.order
    half = plan.R
    info = {"height_uncertainty_m": plan.R, "levels": []}
    total = sum(4 ** -k for k in order)
    for L in order:
        g, posting = plan.g(L), plan.posting(L)
        t, shape = grid_over(plan.foot, posting)
        frac0 = sum(4 ** -k for k in order if k > L)
        part = scaled(progress, 0.95 * frac0 / total, 0.95 * (frac0 + 4 ** -L) / total)
        checkpoint(part, 0.0, f"level {order.index(L) + 1} of {len(order)}: {g:g} m pixels")
        wanted = seen_by_all(plan.sol, t, shape, regrid(prior, prior_t, t, shape), plan.window)
        wanted = cv2.dilate(wanted.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
        heights, quality, n_tiles, z_nmad = _level(plan, t, shape, g, half, prior, prior_t, wanted=wanted,
                                                   overlap_m=max(plan.overlap_m, 4 * posting),
                                                   refine=refine and L == 0, scheduler=scheduler,
                                                   workers=workers, progress=part)
        info["levels"].append({"g_m": g, "posting_m": posting, "half_range_m": half,
                               "tiles": n_tiles, "filled": float(np.isfinite(heights).mean()),
                               "pair_scatter_in_sigma": z_nmad})
        if L:
            # the next prior only from cells two or more pairs agree on (single-pair edges
            # can be off by the whole coarse search range)
            prior, prior_t = bridge(np.where(quality >= 2, heights, np.nan)), t
            half = (FINEST_SEARCH_IN_G if order[order.index(L) + 1] == 0 else NEXT_LEVEL_SEARCH_IN_G) * g
    return heights, quality, t, info


def finish_dsm(plan: DsmPlan, heights, quality, t, info, *, fill: bool, orthometric_geoid,
               progress) -> Dsm:
    """Cells only one or two pairs agree on kept near the three-pair surface, cells the three
    images do not all see cleared, the mask, voids filled (``fill``), heights made orthometric
    (``orthometric_geoid``); in place on ``heights`` and ``quality``."""
    sol, sc, shape = plan.sol, plan.sol.scene, heights.shape
    drop_unconfirmed(heights, quality, max(6.0, plan.posting_m))
    seen = seen_by_all(sol, t, shape, bridge(heights), plan.window)
    heights[~seen] = np.nan
    quality[~seen] = 0
    mask = np.where(np.isfinite(heights), MASK_MATCHED, MASK_VOID).astype(np.uint8)
    if fill and np.isfinite(heights).any():
        filled = fill_voids(heights)
        new = seen & ~np.isfinite(heights)
        heights[new] = filled[new]
        mask[new] = MASK_FILLED
    kind, geoid_name = "ellipsoidal", None
    if orthometric_geoid is not None:
        for r0 in range(0, shape[0], 512):
            en = cell_centres((t[0], 0.0, t[2], 0.0, t[4], t[5] + t[4] * r0), (min(512, shape[0] - r0), shape[1]))
            heights[r0:r0 + 512] -= orthometric_geoid.undulation(en[..., 0], en[..., 1], sc.crs).astype(np.float32)
        kind = "orthometric"
        geoid_name = orthometric_geoid.describe() if hasattr(orthometric_geoid, "describe") else "geoid"
    checkpoint(progress, 1.0, "done")
    return grid_dsm(heights, seen, quality, t, sc.crs, plan.posting_m, info, mask=mask, height_kind=kind,
                    geoid=geoid_name)
