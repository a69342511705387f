"""Point transfer between two images: NCC along a search direction, then least-squares matching.

Coordinates follow docs/model.md §1: image ``x`` = column, ``y`` = row, in pixels, continuous,
origin at the top-left corner of the top-left pixel, so the centre of array element
``[j, i]`` is ``(i + 0.5, j + 0.5)``. Images are 2-D numpy arrays of any numeric dtype.

:func:`match_point` finds where a point of a reference image lies in a search image:

1. normalised cross-correlation (``cv2.matchTemplate``, ``TM_CCOEFF_NORMED``) of a
   ``(2h+1)²`` template over a window elongated along the search direction (the parallax
   direction), the integer peak refined by a parabola in each axis;
2. least-squares matching (Gruen 1985): the template ``T`` is modelled as
   ``r0 + r1·S(a0 + a1·u + a2·v, b0 + b1·u + b2·v)`` with ``(u, v)`` template offsets, ``S``
   the search image resampled bilinearly; Gauss–Newton on the 8 parameters. The formal σ of
   the position comes from ``σ0²·N⁻¹``.

The σ reported (:func:`calibrated_sigma`) is the formal σ calibrated against empirical scatter.
The formal σ assumes independent grey-value residuals and a template that moves as one affine
patch; neither holds: image noise and texture are spatially correlated, and relief inside the
template makes the parallax vary across it, which LSM averages. Calibration (reproduced by
``benchmarks/match_sigma.py``; ``tests/core/matching/test_match_sigma.py`` checks it):

* real independent imagery — the Pléiades triplet crops of ``shared/data/real`` (one pass,
  three look angles), 296 points matched 1→2, 1→3 and 2→3: the closure 1→2→3 − 1→3 has an
  RMS of 0.11 px across and 0.44 px along the parallax (heavy tails), RMS z = closure/σ of
  1.4 and 4.1 with formal σ, 90 % inside the 95 % ellipse;
* simulated PRISM triplets with relief (500 px, seeds 11 and 3, per-view attitude drift):
  ~420 matches each at known truth scatter 0.04 px across and 0.25–0.39 px along the
  parallax (more relief, more scatter), with formal σ near 0.02 px (RMS z 1.8 and 13–16,
  12 % inside the 95 % ellipse).

So ``σ² = (K·σ_formal)² + floor²``, ``K`` = :data:`SIGMA_SCALE`, the floor
:data:`SIGMA_FLOOR_ALONG` along the search (parallax) direction and :data:`SIGMA_FLOOR_ACROSS`
across it (without a direction, the along floor both ways). With it the RMS z is 0.31 / 0.92
(Pléiades closure, 97 % inside the 95 % ellipse) and 0.70 / 0.70–1.10 (simulated triplets,
95–99 %). The along floor, 0.35 px, is set by the rougher simulated scene.

Failures are returned as a value (``status`` and ``reason``), never raised.
"""
from __future__ import annotations

from dataclasses import dataclass

from prismstation.core.lazy_cv2 import cv2  # imported at first use: start-up saving
import numpy as np
from scipy import ndimage

from prismstation.core.adjustment.stats import nmad

OK, LOW_SCORE, FLAT, DIVERGED, BORDER, OUTSIDE = (
    "ok", "low_score", "flat", "diverged", "border", "outside")

SIGMA_SCALE = 1.5
"""Factor on the formal LSM σ (correlated residuals; see the module doc)."""
SIGMA_FLOOR_ALONG = 0.35
"""σ (px) added in quadrature along the search (parallax) direction: relief within the template."""
SIGMA_FLOOR_ACROSS = 0.04
"""σ (px) added in quadrature across the search direction."""


def calibrated_sigma(sx: float, sy: float, direction=None) -> tuple[float, float]:
    """σ of x and y (px) claimed for a match of formal σ ``(sx, sy)`` found along ``direction``
    (``(dx, dy)`` or None): ``(K·σ_formal)² + floor²`` per the module doc's calibration."""
    if direction is None:
        fa = fc = SIGMA_FLOOR_ALONG
        d = np.array([1.0, 0.0])
    else:
        d = np.asarray(direction, float)
        d = d / np.hypot(*d)
        fa, fc = SIGMA_FLOOR_ALONG, SIGMA_FLOOR_ACROSS
    c2 = np.array([d[0] ** 2 * fa ** 2 + d[1] ** 2 * fc ** 2, d[1] ** 2 * fa ** 2 + d[0] ** 2 * fc ** 2])
    k2 = SIGMA_SCALE ** 2
    return float(np.sqrt(k2 * sx ** 2 + c2[0])), float(np.sqrt(k2 * sy ** 2 + c2[1]))


@dataclass(frozen=True)
class MatchResult:
    """Result of :func:`match_point`.

    Attributes
    ----------
    x, y : float
        Matched position in the search image (pixels, docs/model.md §1). On failure, the best
        estimate available (NCC peak or prediction); check :attr:`ok`.
    sigma_x, sigma_y : float
        Standard deviations of ``x``, ``y`` (pixels): the formal ones calibrated against
        empirical scatter (:func:`calibrated_sigma`); NaN when LSM did not run.
    score : float
        NCC at the integer peak, in [-1, 1] (NaN if not computed).
    iterations : int
        Gauss–Newton iterations of the LSM (0 if it did not run).
    status : str
        ``"ok"``, ``"low_score"``, ``"flat"``, ``"diverged"``, ``"border"`` or ``"outside"``.
    reason : str
        Human-readable explanation ("" when ok).
    ncc_x, ncc_y : float
        Position after NCC + parabolic subpixel refinement (pixels).
    formal_sigma_x, formal_sigma_y : float
        The formal σ from ``σ0²·N⁻¹`` alone (pixels; NaN when LSM did not run).
    """

    x: float
    y: float
    sigma_x: float
    sigma_y: float
    score: float
    iterations: int
    status: str
    reason: str = ""
    ncc_x: float = float("nan")
    ncc_y: float = float("nan")
    formal_sigma_x: float = float("nan")
    formal_sigma_y: float = float("nan")

    @property
    def ok(self) -> bool:
        return self.status == OK


def bilinear(img: np.ndarray, col: np.ndarray, row: np.ndarray) -> np.ndarray:
    """Exact bilinear interpolation of ``img`` at array-index coordinates (pixel centres at integers).

    Unlike ``cv2.remap`` (weights quantised to 1/32 px) the weights are exact. Positions
    outside ``[0, n-1]`` are clamped; callers check bounds themselves.
    """
    h, w = img.shape
    c = np.clip(col, 0.0, w - 1.000001)
    r = np.clip(row, 0.0, h - 1.000001)
    c0 = np.floor(c).astype(np.intp)
    r0 = np.floor(r).astype(np.intp)
    fc = c - c0
    fr = r - r0
    top = img[r0, c0] * (1 - fc) + img[r0, c0 + 1] * fc
    bot = img[r0 + 1, c0] * (1 - fc) + img[r0 + 1, c0 + 1] * fc
    return top * (1 - fr) + bot * fr


def _parabola(m1: float, m0: float, p1: float) -> float:
    """Vertex offset in (-0.5, 0.5) of the parabola through (-1, m1), (0, m0), (1, p1)."""
    den = m1 - 2.0 * m0 + p1
    if not np.isfinite(den) or den >= 0:
        return 0.0
    return float(np.clip(0.5 * (m1 - p1) / den, -0.5, 0.5))


def match_point(reference: np.ndarray, x: float, y: float, search: np.ndarray,
                x_pred: float, y_pred: float, *, direction=None, search_range: float = 10.0,
                across_range: float = 1.5, half_window: int = 15, min_score: float = 0.5,
                max_sigma: float = 0.3, min_margin: float = 0.02, lsm: bool = True,
                interpolation: str = "bicubic", max_iter: int = 30,
                max_lsm_move: float = 2.0) -> MatchResult:
    """Find the point ``(x, y)`` of ``reference`` in ``search``.

    Parameters
    ----------
    reference, search : ndarray, shape (rows, cols)
        Images, any numeric dtype (uint16 included).
    x, y : float
        Point in the reference image (pixels, docs/model.md §1).
    x_pred, y_pred : float
        Predicted position in the search image (pixels).
    direction : (dx, dy) or None
        Search direction in the search image (the parallax direction; normalised here). The
        search covers ``±search_range`` px along it and ``±across_range`` px across it. None
        searches a square of ``±search_range`` px.
    half_window : int
        Template half size ``h``: the template is ``(2h+1) × (2h+1)`` pixels.
    min_score : float
        NCC below this gives ``status="low_score"``.
    max_sigma : float
        Formal LSM σ (either axis, px) above this gives ``status="flat"`` (too little texture).
    min_margin : float
        A second NCC maximum (2 px or more from the best) within this of the best score gives
        ``status="flat"``: the match is ambiguous (texture flat or repeating along the search).
    lsm : bool
        Refine by least-squares matching (else return the NCC subpixel position).
    interpolation : {"bicubic", "bilinear"}
        Resampling of the search patch in LSM. Bilinear smooths by an amount that depends on
        the subpixel phase and biases the position (0.02 px RMS on noise-free Pléiades texture
        in ``benchmarks/bench_matching.py``); a cubic B-spline brings that to 0.003 px.
    max_iter, max_lsm_move : int, float
        Gauss–Newton iteration limit; largest move (px) allowed from the NCC position.

    Returns
    -------
    MatchResult
    """
    h = int(half_window)
    i0, j0 = int(np.floor(x)), int(np.floor(y))          # reference pixel holding the point
    ox, oy = x - (i0 + 0.5), y - (j0 + 0.5)               # point offset from template centre
    if not (h <= j0 < reference.shape[0] - h and h <= i0 < reference.shape[1] - h):
        return MatchResult(x_pred, y_pred, np.nan, np.nan, np.nan, 0, OUTSIDE,
                           "template leaves the reference image")
    tmpl = reference[j0 - h:j0 + h + 1, i0 - h:i0 + h + 1].astype(np.float32)
    if float(tmpl.std()) <= 1e-6 * (abs(float(tmpl.mean())) + 1.0):
        return MatchResult(x_pred, y_pred, np.nan, np.nan, np.nan, 0, FLAT,
                           "template has no contrast")

    # Predicted template centre in the search image, and the search window around it.
    cx, cy = x_pred - ox, y_pred - oy
    if direction is None:
        d = None
        ext_x = ext_y = search_range
    else:
        d = np.asarray(direction, float)
        d = d / np.hypot(*d)
        ext_x = abs(d[0]) * search_range + abs(d[1]) * across_range
        ext_y = abs(d[1]) * search_range + abs(d[0]) * across_range
    pad = h + 3                                           # template + parabola + LSM room
    c_lo = int(np.floor(cx - 0.5 - ext_x)) - pad
    c_hi = int(np.ceil(cx - 0.5 + ext_x)) + pad + 1
    r_lo = int(np.floor(cy - 0.5 - ext_y)) - pad
    r_hi = int(np.ceil(cy - 0.5 + ext_y)) + pad + 1
    c_lo, r_lo = max(c_lo, 0), max(r_lo, 0)
    c_hi, r_hi = min(c_hi, search.shape[1]), min(r_hi, search.shape[0])
    if c_hi - c_lo < 2 * h + 3 or r_hi - r_lo < 2 * h + 3:
        return MatchResult(x_pred, y_pred, np.nan, np.nan, np.nan, 0, OUTSIDE,
                           "search window leaves the search image")
    crop = search[r_lo:r_hi, c_lo:c_hi].astype(np.float32)

    ncc = cv2.matchTemplate(crop, tmpl, cv2.TM_CCOEFF_NORMED)
    ncc = np.where(np.isfinite(ncc), ncc, -np.inf)
    # Template centre (continuous coords) for each NCC cell, relative to the prediction.
    vv, uu = np.mgrid[0:ncc.shape[0], 0:ncc.shape[1]]
    dx = c_lo + uu + h + 0.5 - cx
    dy = r_lo + vv + h + 0.5 - cy
    if d is None:
        along = np.maximum(np.abs(dx), np.abs(dy))
        allowed = along <= search_range + 0.5
    else:
        along = np.abs(dx * d[0] + dy * d[1])
        allowed = (along <= search_range + 0.5) & (np.abs(dy * d[0] - dx * d[1]) <= across_range + 0.5)
    masked = np.where(allowed, ncc, -np.inf)
    v, u = np.unravel_index(int(np.argmax(masked)), masked.shape)
    score = float(masked[v, u])
    if not np.isfinite(score):
        return MatchResult(x_pred, y_pred, np.nan, np.nan, np.nan, 0, FLAT,
                           "no correlation in the search window (flat search image)")
    su = _parabola(ncc[v, u - 1], ncc[v, u], ncc[v, u + 1]) if 0 < u < ncc.shape[1] - 1 else 0.0
    sv = _parabola(ncc[v - 1, u], ncc[v, u], ncc[v + 1, u]) if 0 < v < ncc.shape[0] - 1 else 0.0
    tx, ty = c_lo + u + su + h + 0.5, r_lo + v + sv + h + 0.5   # template centre, NCC estimate
    nx, ny = tx + ox, ty + oy

    def fail(status, reason, px=nx, py=ny, sx=np.nan, sy=np.nan, it=0):
        return MatchResult(px, py, sx, sy, score, it, status, reason, nx, ny)

    if score < min_score:
        return fail(LOW_SCORE, f"correlation {score:.2f} below {min_score:.2f}")
    # a second local maximum nearly as high, 2 px or more away: flat or repetitive texture
    peaks = (masked == ndimage.maximum_filter(masked, size=3, mode="constant", cval=-np.inf))
    peaks &= np.hypot(uu - u, vv - v) >= 2.0
    second = float(masked[peaks].max()) if peaks.any() else -np.inf
    if second >= score - min_margin:
        return fail(FLAT, f"ambiguous correlation: a second peak scores {second:.3f} "
                          f"against {score:.3f} (flat or repetitive texture)")
    if along[v, u] > search_range - 0.5 or u in (0, ncc.shape[1] - 1) or v in (0, ncc.shape[0] - 1):
        return fail(BORDER, "correlation peak at the end of the search range")
    if not lsm:
        return MatchResult(nx, ny, np.nan, np.nan, score, 0, OK, "", nx, ny)
    return _lsm(tmpl, crop, c_lo, r_lo, tx, ty, ox, oy, score, nx, ny,
                max_iter, max_lsm_move, max_sigma, interpolation, d)


def _lsm(tmpl, crop, c_lo, r_lo, tx, ty, ox, oy, score, nx, ny, max_iter, max_move, max_sigma,
         interpolation, direction=None):
    """Affine + linear-radiometric least-squares matching started at template centre (tx, ty)."""
    h = tmpl.shape[0] // 2
    vv, uu = np.mgrid[-h:h + 1, -h:h + 1]
    u, v = uu.ravel().astype(float), vv.ravel().astype(float)
    t = tmpl.ravel().astype(float)
    img = crop.astype(float)
    deriv = np.array([-1.0, 8.0, 0.0, -8.0, 1.0]) / 12.0   # 4th-order central difference
    gx_img = ndimage.correlate1d(img, deriv[::-1], axis=1, mode="nearest")
    gy_img = ndimage.correlate1d(img, deriv[::-1], axis=0, mode="nearest")
    if interpolation == "bicubic":
        coeffs = ndimage.spline_filter(img, order=3, mode="mirror")

        def sample(col, row):
            return ndimage.map_coordinates(coeffs, [row, col], order=3, prefilter=False,
                                           mode="mirror")
    elif interpolation == "bilinear":
        def sample(col, row):
            return bilinear(img, col, row)
    else:
        raise ValueError(f"unknown interpolation {interpolation!r}")
    a = np.array([tx, 1.0, 0.0])          # x = a0 + a1 u + a2 v   (continuous coords)
    b = np.array([ty, 0.0, 1.0])          # y = b0 + b1 u + b2 v
    r0, r1 = 0.0, None
    n_obs = t.size
    status, reason = DIVERGED, "no convergence"
    for it in range(1, max_iter + 1):
        xs = a[0] + a[1] * u + a[2] * v
        ys = b[0] + b[1] * u + b[2] * v
        col, row = xs - c_lo - 0.5, ys - r_lo - 0.5
        if col.min() < 0 or row.min() < 0 or col.max() > img.shape[1] - 1 or row.max() > img.shape[0] - 1:
            status, reason = DIVERGED, "LSM patch left the search window"
            break
        g = sample(col, row)
        gx = bilinear(gx_img, col, row)
        gy = bilinear(gy_img, col, row)
        if r1 is None:
            r1 = t.std() / max(g.std(), 1e-12)
            r0 = t.mean() - r1 * g.mean()
        resid = t - (r0 + r1 * g)
        A = np.column_stack([r1 * gx, r1 * gx * u, r1 * gx * v,
                             r1 * gy, r1 * gy * u, r1 * gy * v, np.ones_like(g), g])
        N = A.T @ A
        try:
            dp = np.linalg.solve(N, A.T @ resid)
        except np.linalg.LinAlgError:
            status, reason = FLAT, "singular LSM normal matrix"
            break
        a += dp[0:3]
        b += dp[3:6]
        r0 += dp[6]
        r1 += dp[7]
        if np.hypot(a[0] - tx, b[0] - ty) > max_move or not (0.5 < abs(np.linalg.det(
                [[a[1], a[2]], [b[1], b[2]]])) < 2.0):
            status, reason = DIVERGED, "LSM moved too far from the correlation peak"
            break
        if abs(dp[0]) < 1e-3 and abs(dp[3]) < 1e-3 and np.abs(dp[[1, 2, 4, 5]]).max() < 1e-4:
            status, reason = OK, ""
            break
    px = a[0] + a[1] * ox + a[2] * oy
    py = b[0] + b[1] * ox + b[2] * oy
    if status != OK:
        return MatchResult(nx, ny, np.nan, np.nan, score, it, status, reason, nx, ny)
    sigma0_sq = float(resid @ resid) / max(n_obs - 8, 1)
    cov = sigma0_sq * np.linalg.inv(N)
    jx = np.array([1.0, ox, oy])
    sx = float(np.sqrt(jx @ cov[0:3, 0:3] @ jx))
    sy = float(np.sqrt(jx @ cov[3:6, 3:6] @ jx))
    cx, cy = calibrated_sigma(sx, sy, direction)
    if max(sx, sy) > max_sigma:
        return MatchResult(px, py, cx, cy, score, it, FLAT,
                           f"too little texture: formal σ = ({sx:.2f}, {sy:.2f}) px", nx, ny, sx, sy)
    return MatchResult(float(px), float(py), cx, cy, score, it, OK, "", nx, ny, sx, sy)


def transfer_points(reference: np.ndarray, search: np.ndarray, points, predicted, direction=None,
                    **options) -> list[MatchResult]:
    """:func:`match_point` for many points (e.g. a tie-point grid).

    Parameters
    ----------
    reference, search : ndarray (rows, cols)
    points, predicted : array_like (n, 2)
        ``(x, y)`` in the reference image and predicted ``(x, y)`` in the search image (pixels).
    direction : (dx, dy) or array_like (n, 2) or None
        One search direction for all points, or one per point.
    **options
        Passed to :func:`match_point`.
    """
    pts = np.asarray(points, float).reshape(-1, 2)
    pred = np.asarray(predicted, float).reshape(-1, 2)
    dirs = [None] * len(pts) if direction is None else \
        np.broadcast_to(np.asarray(direction, float), pts.shape)
    return [match_point(reference, p[0], p[1], search, q[0], q[1], direction=d, **options)
            for p, q, d in zip(pts, pred, dirs)]


def blunder_mask(results, predicted, direction, k: float = 3.0, min_abs: float = 0.5) -> np.ndarray:
    """Flag matches whose offset across the search direction disagrees with the others.

    Along the parallax direction the offset from the prediction carries the terrain height, so
    only the across component ``(match − prediction)·d⊥`` is expected to be common to all points
    (a relative-orientation offset). A match is kept when it is ``ok`` and that component lies
    within ``max(k·NMAD, min_abs)`` px of the median over the ok matches.

    Parameters
    ----------
    results : sequence of MatchResult
    predicted : array_like (n, 2)
        Predicted positions used for the search (pixels).
    direction : (dx, dy) or array_like (n, 2)
        Search (parallax) direction(s).

    Returns
    -------
    ndarray (n,), bool
        True for a blunder or a failed match.
    """
    pred = np.asarray(predicted, float).reshape(-1, 2)
    d = np.broadcast_to(np.asarray(direction, float), pred.shape)
    d = d / np.hypot(d[:, 0], d[:, 1])[:, None]
    xy = np.array([[r.x, r.y] for r in results], float).reshape(-1, 2)
    ok = np.array([r.ok for r in results], bool)
    across = (xy[:, 1] - pred[:, 1]) * d[:, 0] - (xy[:, 0] - pred[:, 0]) * d[:, 1]
    bad = ~ok
    if ok.sum() >= 3:
        med = np.median(across[ok])
        spread = nmad(across[ok])
        bad |= ~(np.abs(across - med) <= max(k * spread, min_abs))
    return bad
