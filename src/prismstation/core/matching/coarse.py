"""Coarse-to-fine offsets over the whole range an a-priori uncertainty allows.

Nothing is assumed small: each search radius comes from a stated a-priori σ,
``radius = k·σ_apriori / GSD`` (:func:`search_radius_px`, ``k`` = :data:`K_SIGMA` = 3), and the
coarse step covers all of it; the fine step then refines to sub-pixel with a formal σ.

Two estimators:

* :func:`image_offset` — two image windows of the same ground in the same geometry (e.g. N, and
  F resampled into N space through the ancillary model and the reference DEM's heights), offset
  by an unknown translation within the radius. Coarse: exhaustive normalised cross-correlation
  (``cv2.matchTemplate``) on a Gaussian pyramid, at the level where the radius is at most
  :data:`COARSE_RADIUS` cells, then ±2 cells at each finer level. Chosen over phase correlation
  because (1) the search is bounded exactly by the a-priori radius (phase correlation searches
  the whole periodic window and wraps), (2) the NCC peak gives an interpretable score and a
  second-peak ambiguity test, (3) the coarse levels average out noise and JPEG blocks. Fine:
  least-squares matching of a translation with radiometric gain and offset on the full
  overlap, cubic-spline resampling; σ = ``σ0²·N⁻¹`` times the residuals' correlation area
  (neighbouring pixels' errors are correlated through the PSF), plus a 0.01 px floor.
* :func:`dem_offset` — the N side against the reference DEM, height to height (the paper's way:
  heights do not depend on illumination or albedo, which an image-to-shaded-DEM correlation
  would): exhaustive search of the horizontal offset minimising the robust spread of the height
  difference on a pyramid level where the radius is at most :data:`COARSE_RADIUS` cells, then
  :func:`prismstation.core.matching.coreg.coregister` (least-squares surface matching) from there.

Conventions: arrays ``(rows, cols)``; an offset ``(dx, dy)`` in pixels (x column, y row) means
``moving(x + dx, y + dy) ≈ gain·reference(x, y) + bias``: the reference's content at ``(x, y)``
is found in ``moving`` at ``(x + dx, y + dy)``.
"""
from __future__ import annotations

from dataclasses import dataclass

from dataclasses import replace

from prismstation.core.lazy_cv2 import cv2  # imported at first use: start-up saving
import numpy as np
from scipy import ndimage

from prismstation.core.matching.coreg import CoregResult, block_mean, coregister, correlation_area, shift_grid
from prismstation.core.adjustment.stats import nmad

#: k of ``radius = k·σ_apriori / GSD``
K_SIGMA = 3.0
#: the coarse exhaustive search runs where the radius is at most this many cells
COARSE_RADIUS = 8
#: smallest template side (cells) at the coarse level
MIN_TEMPLATE = 24
#: σ floor (px) of a sub-pixel offset: cubic resampling and model error
SIGMA_FLOOR_PX = 0.01
#: the sub-pixel adjustment stops when a step moves less than this (px; a tenth of the σ floor)
LSM_TOL_PX = 1e-3
#: side (px) of the central region the sub-pixel adjustment uses at most
LSM_SIDE = 320
#: the sub-pixel adjustment may move this far (px) from the integer NCC peak (a broad peak:
#: residual parallax of views warped through an approximate DEM), else ``diverged``
MAX_LSM_MOVE_PX = 3.0

OK, LOW_SCORE, AMBIGUOUS, AT_EDGE, DIVERGED, TOO_SMALL = (
    "ok", "low_score", "ambiguous", "at_edge", "diverged", "too_small")


def search_radius_px(sigma_apriori_m: float, gsd_m: float, k: float = K_SIGMA) -> float:
    """Search radius (px) that covers ``k``·σ of an a-priori offset uncertainty ``σ`` (m).
    For the offset between two views with independent errors of σ each, pass σ·√2."""
    if not (sigma_apriori_m >= 0 and gsd_m > 0):
        raise ValueError(f"need σ ≥ 0 and GSD > 0, got {sigma_apriori_m}, {gsd_m}")
    return k * float(sigma_apriori_m) / float(gsd_m)


@dataclass(frozen=True)
class Offset:
    """Result of :func:`image_offset` (see the module docstring for the sign convention).

    dx, dy, sigma_dx, sigma_dy : pixels; ``cov`` the 2×2 covariance (px²).
    score : NCC at the integer peak at full resolution (at the coarse level if it failed
        there); ``second`` the coarse NCC of the next local maximum.
    level : pyramid level of the coarse search (0 = full resolution; cells of 2^level px).
    radius_px : the search radius used.
    status, reason : ``"ok"`` or why not (``low_score``, ``ambiguous``, ``at_edge``,
        ``diverged``, ``too_small``); the estimate is still given when there is one.
    """

    dx: float
    dy: float
    sigma_dx: float
    sigma_dy: float
    cov: tuple
    score: float
    second: float
    level: int
    radius_px: float
    status: str
    reason: str = ""

    @property
    def ok(self) -> bool:
        return self.status == OK


def _pyramid(a: np.ndarray, levels: int) -> list[np.ndarray]:
    out = [np.ascontiguousarray(a, np.float32)]
    for _ in range(levels):
        out.append(cv2.pyrDown(out[-1]))
    return out


def _ncc(ref, mov, cx: int, cy: int, r: int):
    """NCC of the reference's core against ``mov`` over integer offsets ``(cx ± r, cy ± r)``:
    returns the score map ``[(2r+1), (2r+1)]`` (row = dy) or None if the core is too small."""
    b = r + max(abs(cx), abs(cy))
    h, w = ref.shape
    if h - 2 * b < 8 or w - 2 * b < 8 or mov.shape != ref.shape:
        return None
    t = ref[b:h - b, b:w - b]
    m = mov[b + cy - r:h - b + cy + r, b + cx - r:w - b + cx + r]
    if t.std() < 1e-6:
        return None
    return cv2.matchTemplate(m, t, cv2.TM_CCOEFF_NORMED)


def _peak(scores):
    """Best cell ``(i, j, best, second)``: ``second`` is the highest OTHER local maximum (3×3),
    not the flank of the best peak, so a broad coarse peak is not taken for two."""
    j, i = np.unravel_index(int(np.argmax(scores)), scores.shape)
    best = float(scores[j, i])
    local = (scores == ndimage.maximum_filter(scores, size=3, mode="constant", cval=-np.inf))
    local[j, i] = False
    second = float(scores[local].max()) if local.any() else -1.0
    return int(i), int(j), best, second


def image_offset(reference: np.ndarray, moving: np.ndarray, radius_px: float, *,
                 min_score: float = 0.3, max_second_ratio: float = 0.9, subpixel: bool = True) -> Offset:
    """Offset of ``moving`` relative to ``reference`` (same shape and geometry) anywhere within
    ``radius_px`` (a disc's bounding square), coarse to fine (see the module docstring).

    The windows should be at least ~3 radii wide (the template is the reference's core, the
    window shrunk by the radius on each side at the coarse level). ``min_score`` is the least
    coarse NCC accepted; a second peak above ``max_second_ratio`` × the best is ambiguous.
    ``subpixel=False``: the integer peak only (no σ), for a first estimate to be refined.
    """
    ref = np.asarray(reference, np.float32)
    mov = np.asarray(moving, np.float32)
    nan = float("nan")

    def fail(status, reason, dx=nan, dy=nan, score=nan, second=nan, level=0):
        return Offset(dx, dy, nan, nan, ((nan, nan), (nan, nan)), score, second, level,
                      float(radius_px), status, reason)

    if ref.shape != mov.shape or ref.ndim != 2:
        raise ValueError(f"reference {ref.shape} and moving {mov.shape} must be 2-D, one shape")
    radius = max(float(radius_px), 1.0)
    level = 0
    while radius / 2 ** level > COARSE_RADIUS and min(ref.shape) / 2 ** (level + 1) >= MIN_TEMPLATE + 2 * COARSE_RADIUS:
        level += 1
    r = int(np.ceil(radius / 2 ** level)) + 1
    if min(ref.shape) / 2 ** level < 2 * r + MIN_TEMPLATE:
        return fail(TOO_SMALL, f"windows of {min(ref.shape)} px are too small for a search "
                    f"radius of {radius:.0f} px (need about {2 ** level * (2 * r + MIN_TEMPLATE)} px)")
    pr, pm = _pyramid(ref, level), _pyramid(mov, level)
    scores = _ncc(pr[level], pm[level], 0, 0, r)
    if scores is None:
        return fail(TOO_SMALL, "the reference window has no texture")
    i, j, best, second = _peak(scores)
    cx, cy = i - r, j - r
    if best < min_score:
        return fail(LOW_SCORE, f"coarse NCC {best:.2f} < {min_score}", score=best, second=second,
                    level=level)
    if second > max_second_ratio * best:
        return fail(AMBIGUOUS, f"two peaks: NCC {best:.2f} and {second:.2f}",
                    cx * 2 ** level, cy * 2 ** level, best, second, level)
    if max(abs(cx), abs(cy)) >= r - 1 and np.hypot(cx, cy) * 2 ** level > radius:
        return fail(AT_EDGE, "the peak lies on the edge of the a-priori search range: the offset "
                    "may be larger than the a-priori uncertainty allows",
                    cx * 2 ** level, cy * 2 ** level, best, second, level)
    for lv in range(level - 1, -1, -1):                      # refine ±2 cells per level
        cx, cy = 2 * cx, 2 * cy
        s = _ncc(pr[lv], pm[lv], cx, cy, 2)
        if s is None:
            return fail(TOO_SMALL, "the overlap is too small at full resolution")
        i, j, best, _ = _peak(s)
        cx, cy = cx + i - 2, cy + j - 2
    if best < min_score:         # smooth coarse levels correlate well; full resolution decides
        return fail(LOW_SCORE, f"NCC {best:.2f} < {min_score} at full resolution", cx, cy, best,
                    second, level)
    if not subpixel:
        return Offset(float(cx), float(cy), nan, nan, ((nan, nan), (nan, nan)), best, second, level,
                      radius, OK)
    return _lsm_translation(ref, mov, float(cx), float(cy), best, second, level, radius)


def _lsm_translation(ref, mov, dx, dy, score, second, level, radius, max_iter=20) -> Offset:
    """Gauss–Newton on ``ref(x) = g·mov(x + d) + b`` over the overlap (its central
    :data:`LSM_SIDE`² at most); σ from the adjustment."""
    h, w = ref.shape
    b = int(np.ceil(max(abs(dx), abs(dy)))) + 3
    r0, r1 = max(b, h // 2 - LSM_SIDE // 2), min(h - b, h // 2 + LSM_SIDE // 2)
    c0, c1 = max(b, w // 2 - LSM_SIDE // 2), min(w - b, w // 2 + LSM_SIDE // 2)
    # the moving crop that the overlap can reach, spline-filtered once
    m0r, m0c = max(0, int(np.floor(r0 + dy)) - 4), max(0, int(np.floor(c0 + dx)) - 4)
    m1r, m1c = min(h, int(np.ceil(r1 + dy)) + 5), min(w, int(np.ceil(c1 + dx)) + 5)
    coeffs = ndimage.spline_filter(mov[m0r:m1r, m0c:m1c].astype(np.float64), order=3)
    yy, xx = np.mgrid[r0:r1, c0:c1].astype(float)
    yy, xx = yy - m0r, xx - m0c
    t = ref[r0:r1, c0:c1].astype(np.float64)
    x0, y0 = dx, dy
    nan = float("nan")
    cov = np.full((2, 2), nan)
    for _ in range(max_iter):
        s = ndimage.map_coordinates(coeffs, [yy + dy, xx + dx], order=3, prefilter=False, mode="nearest")
        gy, gx = np.gradient(s)
        A = np.column_stack([s.ravel(), np.ones(s.size)])
        g, c = np.linalg.lstsq(A, t.ravel(), rcond=None)[0]
        v = t - (g * s + c)
        J = np.column_stack([(g * gx).ravel(), (g * gy).ravel(), s.ravel(), np.ones(s.size)])
        N = J.T @ J
        try:
            delta = np.linalg.solve(N, J.T @ v.ravel())
        except np.linalg.LinAlgError:
            break
        dx, dy = dx + delta[0], dy + delta[1]
        if np.hypot(dx - x0, dy - y0) > MAX_LSM_MOVE_PX:
            return Offset(dx, dy, nan, nan, ((nan, nan), (nan, nan)), score, second, level,
                          radius, DIVERGED, "the sub-pixel adjustment left the coarse peak")
        if np.hypot(delta[0], delta[1]) < LSM_TOL_PX:
            break
    s = ndimage.map_coordinates(coeffs, [yy + dy, xx + dx], order=3, prefilter=False, mode="nearest")
    A = np.column_stack([s.ravel(), np.ones(s.size)])
    g, c = np.linalg.lstsq(A, t.ravel(), rcond=None)[0]
    v = t - (g * s + c)
    gy, gx = np.gradient(s)
    J = np.column_stack([(g * gx).ravel(), (g * gy).ravel(), s.ravel(), np.ones(s.size)])
    dof = max(v.size - 4, 1)
    q = np.linalg.inv(J.T @ J)[:2, :2]
    cov = float((v ** 2).sum()) / dof * q * correlation_area(v) + np.eye(2) * SIGMA_FLOOR_PX ** 2
    return Offset(float(dx), float(dy), float(np.sqrt(cov[0, 0])), float(np.sqrt(cov[1, 1])),
                  tuple(map(tuple, cov.tolist())), score, second, level, radius, OK)


# ------------------------------------------------------------------ heights against heights
def coarse_dem_shift(reference: np.ndarray, dem: np.ndarray, radius_cells: float):
    """Exhaustive integer search of ``(dcol, drow)`` within ``radius_cells`` minimising the NMAD
    of ``reference − dem shifted`` (coreg's sign convention), on a block-mean pyramid level
    where the radius is at most :data:`COARSE_RADIUS` cells. Returns ``(dcol, drow, level,
    best_nmad, second_nmad)`` with the shift in full-resolution cells (``second`` is the best
    NMAD of another local minimum: close to ``best`` means an ambiguous match)."""
    ref = np.asarray(reference, float)
    dm = np.asarray(dem, float)
    f = 1
    while radius_cells / f > COARSE_RADIUS and min(ref.shape) / (2 * f) >= 24:
        f *= 2
    rl, dl = block_mean(ref, f), block_mean(dm, f)
    r = int(np.ceil(radius_cells / f)) + 1
    cost = np.full((2 * r + 1, 2 * r + 1), np.inf)
    for j in range(2 * r + 1):
        for i in range(2 * r + 1):
            if np.hypot(i - r, j - r) > r + 0.5:
                continue
            d = rl - shift_grid(dl, i - r, j - r)
            if np.isfinite(d).sum() >= max(20, 0.25 * np.isfinite(rl).sum()):
                cost[j, i] = nmad(d)
    if not np.isfinite(cost).any():
        return np.nan, np.nan, int(np.log2(f)), np.nan, np.nan
    i, j, best, second = _peak(-cost)
    return float((i - r) * f), float((j - r) * f), int(np.log2(f)), -best, -second


def dem_offset(reference: np.ndarray, dem: np.ndarray, transform, radius_m: float, **kw) -> CoregResult:
    """3-D shift laying ``dem`` on ``reference`` (one grid; ``transform`` metric, as for
    :func:`prismstation.core.matching.coreg.coregister`) anywhere within ``radius_m``: the coarse
    exhaustive search (:func:`coarse_dem_shift`), then least-squares surface matching from it,
    bounded by the same radius. Returns a :class:`prismstation.core.matching.coreg.CoregResult`."""
    a, b, _, d, e, _ = (float(t) for t in tuple(transform)[:6])
    pixel = np.sqrt(abs(a * e - b * d))
    radius = float(radius_m) / pixel
    c0, r0, _, _, _ = coarse_dem_shift(reference, dem, radius)
    if not np.isfinite([c0, r0]).all():
        c0 = r0 = 0.0
    moved = shift_grid(np.asarray(dem, float), c0, r0)
    res = coregister(reference, moved, transform, max_shift=max(4.0 * pixel, radius_m), **kw)
    dcol, drow = res.dcol + c0, res.drow + r0
    out = replace(res, dcol=dcol, drow=drow, dx=a * dcol + b * drow, dy=d * dcol + e * drow,
                  nmad_before=nmad(np.asarray(reference, float) - np.asarray(dem, float)))
    if out.converged and np.hypot(dcol, drow) > 1.5 * radius + 1:
        out = replace(out, converged=False, reason=f"the shift ({np.hypot(dcol, drow) * pixel:.0f} m) "
                      f"leaves the a-priori radius ({radius_m:.0f} m)")
    return out
