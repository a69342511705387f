"""Dense matching of F and B in N image space along the parallax direction → parallax map.

Coordinates follow docs/model.md §1 (``x`` column, ``y`` row, pixel centre at ``i + 0.5``). The
caller gives, for F and B, the 2×3 affine mapping that view's image coordinates (of the array
given) to N image coordinates, the parallax direction ``d`` in N space (unit vector of flight
direction) and a window of N image space. The parallax of a ground point is (docs/model.md §2)

    py = (pF − pB) · d          (N-image pixels)

with ``pF``, ``pB`` its positions carried into N space.

Method: F and B are resampled (bicubic) into a frame of N space rotated so that ``d`` runs
along its rows; for each candidate ``py`` around a prior (scalar or per-pixel map), the NCC of
``(2h+1)²`` windows is computed with box filters; the best candidate is refined by a parabola,
then rejected (NaN) when its score is low, at the end of the search range, the texture is flat,
or the B→F match disagrees (left–right check). Each value is placed at
``pF − w·py·d`` in N space (``w = n_weight``): with ``w = tanθF / (tanθF + tanθB)`` that is
where the N view sees the point (0.5 when θF ≈ θB). Work is done in strips across the
direction, with a ``progress(fraction) -> bool`` callback that cancels on False. Memory and
time grow with the window: call per patch for large areas.
"""
from __future__ import annotations

from dataclasses import dataclass

from prismstation.core.lazy_cv2 import cv2  # imported at first use: start-up saving
import numpy as np
from scipy import ndimage


@dataclass(frozen=True)
class ParallaxMap:
    """Result of :func:`parallax_map`.

    Attributes
    ----------
    parallax : ndarray (rows, cols), float32
        ``py`` in N-image pixels on the window's N pixel grid, NaN where unreliable.
    score : ndarray (rows, cols), float32
        NCC of the F→B match at each cell (NaN where none).
    window : (col0, row0, cols, rows)
        The N-image window: cell ``[j, i]`` is N pixel ``(col0 + i, row0 + j)``, its centre at
        ``(col0 + i + 0.5, row0 + j + 0.5)``.
    cancelled : bool
        True if ``progress`` returned False (the map is then incomplete, NaN elsewhere); the
        map is then falsy and ``reason`` says so (:mod:`prismstation.core.adjustment.estimate`).
    """

    parallax: np.ndarray
    score: np.ndarray
    window: tuple
    cancelled: bool

    def __bool__(self) -> bool:
        return not self.cancelled

    @property
    def reason(self) -> str:
        return "cancelled: the map is incomplete" if self.cancelled else ""

    @property
    def valid_fraction(self) -> float:
        return float(np.isfinite(self.parallax).mean())


def heights_from_parallax(py, c0: float, c1: float) -> np.ndarray:
    """Heights ``h = c0 + c1·py`` (docs/model.md §2, eq. 4); NaN stays NaN. Units of ``c0``, ``c1``."""
    return c0 + c1 * np.asarray(py, float)


def _affine3(m) -> np.ndarray:
    m = np.asarray(m, float).reshape(2, 3)
    return np.vstack([m, [0.0, 0.0, 1.0]])


def _resample(img, to_n, frame, shape):
    """Sample ``img`` (view image) on a frame grid: ``frame`` maps frame index → N coords."""
    m = np.linalg.inv(_affine3(to_n)) @ frame           # frame index → view coords
    m[:2, 2] -= 0.5                                     # view coords → view array index
    rows, cols = shape
    corners = m @ np.array([[0, cols - 1, 0, cols - 1], [0, 0, rows - 1, rows - 1], [1, 1, 1, 1]])
    c0 = max(int(np.floor(corners[0].min())) - 3, 0)
    r0 = max(int(np.floor(corners[1].min())) - 3, 0)
    c1 = min(int(np.ceil(corners[0].max())) + 4, img.shape[1])
    r1 = min(int(np.ceil(corners[1].max())) + 4, img.shape[0])
    if c1 <= c0 or r1 <= r0:
        return np.full(shape, np.nan, np.float32)
    crop = np.ascontiguousarray(img[r0:r1, c0:c1], dtype=np.float32)
    m[0, 2] -= c0
    m[1, 2] -= r0
    return cv2.warpAffine(crop, m[:2], (cols, rows), flags=cv2.INTER_CUBIC | cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)


def _match_rows(ref, other, prior, sign, rng, h, min_var):
    """Best ``py`` per cell: ``other(x − sign·py) ≈ ref(x)`` along rows; returns (py, score)."""
    rows, cols = ref.shape
    size = (2 * h + 1, 2 * h + 1)
    box = lambda a: cv2.boxFilter(a, cv2.CV_32F, size, borderType=cv2.BORDER_REFLECT)  # noqa: E731
    ref_bad = box(np.isnan(ref).astype(np.float32)) > 0
    ref = np.nan_to_num(ref, nan=0.0)
    m_r = box(ref)
    v_r = box(ref * ref) - m_r * m_r
    xx = np.arange(cols, dtype=np.float32)[None, :].repeat(rows, 0)
    yy = np.arange(rows, dtype=np.float32)[:, None].repeat(cols, 1)
    best = np.full((rows, cols), -np.inf, np.float32)
    best_k = np.full((rows, cols), -rng - 5, np.int32)
    left = np.full((rows, cols), np.nan, np.float32)
    right = np.full((rows, cols), np.nan, np.float32)
    prev = np.full((rows, cols), np.nan, np.float32)
    for k in range(-rng, rng + 1):
        o = cv2.remap(other, xx - sign * (prior + k), yy, cv2.INTER_LINEAR,
                      borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
        bad = np.isnan(o)
        any_bad = bool(bad.any())
        if any_bad:
            o[bad] = 0.0
        m_o = box(o)
        v_o = box(o * o) - m_o * m_o
        den = v_r * v_o
        np.maximum(den, 1e-30, out=den)
        np.sqrt(den, out=den)
        s = box(ref * o)
        s -= m_r * m_o
        s /= den
        s[v_o <= min_var] = np.nan
        if any_bad:
            s[box(bad.astype(np.float32)) > 0] = np.nan
        np.copyto(right, s, where=best_k == k - 1)
        better = s > best                                # NaN compares False
        np.copyto(best, s, where=better)
        np.copyto(best_k, k, where=better)
        np.copyto(left, prev, where=better)
        np.copyto(right, np.nan, where=better)
        prev = s
    with np.errstate(invalid="ignore", divide="ignore"):
        den = left - 2 * best + right
        frac = np.clip(np.where(den < 0, 0.5 * (left - right) / den, 0.0), -0.5, 0.5)
    py = prior + best_k + frac
    bad = ~np.isfinite(best) | (np.abs(best_k) >= rng) | ~np.isfinite(frac) | (v_r <= min_var) | ref_bad
    py[bad] = np.nan
    best[~np.isfinite(best)] = np.nan
    return py.astype(np.float32), best


def parallax_map(f_image, b_image, f_to_n, b_to_n, window, direction, *, prior=0.0,
                 search_range: int = 8, half_window: int = 4, min_score: float = 0.6,
                 lr_tolerance: float = 1.0, n_weight: float = 0.5, block_rows: int = 256,
                 progress=None) -> ParallaxMap:
    """Parallax map of an N-image window from F and B (see the module docstring).

    Parameters
    ----------
    f_image, b_image : ndarray (rows, cols)
        F and B images (any numeric dtype), or windows of them.
    f_to_n, b_to_n : array_like (2, 3)
        Affines from each array's image coordinates to N image coordinates (docs/model.md §1).
    window : (col0, row0, cols, rows)
        N-image window (integer pixels) of the output map.
    direction : (dx, dy)
        Parallax direction in N image space (normalised here); ``py`` is positive when F lies
        ahead of B along it.
    prior : float or ndarray (rows, cols)
        Expected ``py`` (pixels) on the window grid, e.g. from a reference DEM.
    search_range : int
        Candidates ``prior − search_range … prior + search_range`` (pixels).
    half_window : int
        NCC window half size ``h`` (window ``(2h+1)²``).
    min_score, lr_tolerance : float
        Minimum NCC; largest F→B / B→F disagreement (pixels) kept.
    n_weight : float
        Where a value is placed: ``pF − n_weight·py·d``.
    block_rows : int
        Strip height (frame rows) per block.
    progress : callable(fraction) -> bool, optional
        Called after each strip with the fraction done; returning False cancels.

    Returns
    -------
    ParallaxMap
    """
    col0, row0, ncols, nrows = (int(v) for v in window)
    d = np.asarray(direction, float)
    d = d / np.hypot(*d)
    e = np.array([-d[1], d[0]])
    h, rng = int(half_window), int(search_range)
    prior_n = np.broadcast_to(np.asarray(prior, np.float32), (nrows, ncols))
    reach = float(np.nanmax(np.abs(prior_n))) if prior_n.size else 0.0
    # frame: N = origin + (u + 0.5 + xmin)·d + (v + 0.5 + ymin)·e, u along d
    corners = np.array([[col0, row0], [col0 + ncols, row0], [col0, row0 + nrows],
                        [col0 + ncols, row0 + nrows]], float)
    mx = reach * max(n_weight, 1 - n_weight) + h + 2
    xmin = corners @ d
    ymin = corners @ e
    x_lo, x_hi = xmin.min() - mx, xmin.max() + mx
    y_lo, y_hi = ymin.min() - 1, ymin.max() + 1
    fcols, frows = int(np.ceil(x_hi - x_lo)), int(np.ceil(y_hi - y_lo))
    frame = np.array([[d[0], e[0], x_lo * d[0] + y_lo * e[0] + 0.5 * (d[0] + e[0])],
                      [d[1], e[1], x_lo * d[1] + y_lo * e[1] + 0.5 * (d[1] + e[1])],
                      [0, 0, 1]])                       # frame index (u, v) → N coords
    # N window index → frame index (for the prior and the final placement)
    n_to_frame = np.linalg.inv(frame) @ np.array([[1, 0, col0 + 0.5], [0, 1, row0 + 0.5], [0, 0, 1]])
    frame_to_nidx = np.linalg.inv(n_to_frame)
    prior_at_n = cv2.warpAffine(np.ascontiguousarray(prior_n, np.float32), frame_to_nidx[:2],
                                (fcols, frows), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                borderMode=cv2.BORDER_REPLICATE)
    # the prior where F sees each point: F's pixel at frame u shows the point N sees at
    # u − w·py, so prior_f(u) = prior(u − w·prior_f(u)) (fixed point; the prior taken at u
    # itself is the relief w·py — hundreds of metres — away along the flight direction)
    fx = np.arange(fcols, dtype=np.float32)[None, :].repeat(frows, 0)
    fy = np.arange(frows, dtype=np.float32)[:, None].repeat(fcols, 1)
    prior_f = prior_at_n
    for _ in range(4):
        prior_f = cv2.remap(prior_at_n, fx - np.float32(n_weight) * prior_f, fy, cv2.INTER_LINEAR,
                            borderMode=cv2.BORDER_REPLICATE)
    py_f = np.full((frows, fcols), np.nan, np.float32)
    sc_f = np.full((frows, fcols), np.nan, np.float32)
    cancelled = False
    f_img = np.asarray(f_image)
    scale = float(np.nanstd(f_img[::max(1, f_img.shape[0] // 64), ::max(1, f_img.shape[1] // 64)]))
    min_var = (1e-4 * max(scale, 1e-6)) ** 2
    starts = list(range(0, frows, block_rows))
    for i, v0 in enumerate(starts):
        v1 = min(v0 + block_rows, frows)
        a, b = max(v0 - h, 0), min(v1 + h, frows)
        shift = np.array([[1, 0, 0], [0, 1, a], [0, 0, 1]], float)
        f_r = _resample(f_image, f_to_n, frame @ shift, (b - a, fcols))
        b_r = _resample(b_image, b_to_n, frame @ shift, (b - a, fcols))
        pr = prior_f[a:b]
        py1, s1 = _match_rows(f_r, b_r, pr, +1, rng, h, min_var)
        # B → F with the prior carried to B positions
        xx = np.arange(fcols, dtype=np.float32)[None, :].repeat(b - a, 0)
        yy = np.arange(b - a, dtype=np.float32)[:, None].repeat(fcols, 1)
        pr_b = cv2.remap(pr, xx + pr, yy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        py2, _ = _match_rows(b_r, f_r, pr_b, -1, rng, h, min_var)
        back = cv2.remap(py2, xx - np.nan_to_num(py1), yy, cv2.INTER_NEAREST,
                         borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
        with np.errstate(invalid="ignore"):
            reject = ~(np.abs(py1 - back) <= lr_tolerance) | ~(s1 >= min_score)
        py1[reject] = np.nan
        py_f[v0:v1] = py1[v0 - a:v0 - a + (v1 - v0)]
        sc_f[v0:v1] = s1[v0 - a:v0 - a + (v1 - v0)]
        if progress is not None and progress((i + 1) / len(starts)) is False:
            cancelled = True
            break
    # place each value at pF − w·py·d: solve u_F = u_N + w·py(u_F) by fixed-point iteration
    jj, ii = np.mgrid[0:nrows, 0:ncols].astype(float)
    u_n = n_to_frame[0, 0] * ii + n_to_frame[0, 1] * jj + n_to_frame[0, 2]
    v_n = n_to_frame[1, 0] * ii + n_to_frame[1, 1] * jj + n_to_frame[1, 2]
    u_f = u_n + n_weight * np.asarray(prior_n, float)
    for _ in range(4):
        py = ndimage.map_coordinates(py_f, [v_n, u_f], order=1, mode="constant", cval=np.nan)
        u_f = u_n + n_weight * np.where(np.isfinite(py), py, prior_n)
    py = ndimage.map_coordinates(py_f, [v_n, u_f], order=1, mode="constant", cval=np.nan)
    sc = ndimage.map_coordinates(sc_f, [v_n, u_f], order=1, mode="constant", cval=np.nan)
    return ParallaxMap(py.astype(np.float32), sc.astype(np.float32),
                       (col0, row0, ncols, nrows), cancelled)
