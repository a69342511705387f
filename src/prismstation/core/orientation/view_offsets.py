"""Where F and B really are relative to N, before any fine matching.

Each view's ancillary geolocation is off by tens of metres, independently. This module finds a
view's offset relative to N over the whole range the a-priori uncertainty allows:

1. a window of N (``n_window = (col0, row0, cols, rows)``, N pixels) and the heights of its
   pixels from the reference DEM (:func:`n_heights`, through the ancillary N model);
2. the view's image resampled onto that N grid through the ancillary model at those heights
   (:func:`warp_into_n`): relief displacement removed, so what is left is a translation (the
   geolocation errors) plus small residual parallax from the reference DEM's errors;
3. :func:`prismstation.core.matching.coarse.image_offset` over the radius ``k·σ·√2 / GSD`` (two views,
   each with a-priori σ per component) — coarse NCC on a pyramid, then sub-pixel LSM with σ.

The result (:class:`ViewOffset`) is the N-space pixel vector from the ancillary prediction to
where the view really sees N's ground point — the ``offsets_px`` the DEM orientation workflow
uses to centre its searches (so its fine search may then be narrow). :func:`source_window`
gives the window of the view to read so that the warp covers the N window and the radius.

Wiring (ops): for a few N windows (e.g. :func:`lattice`), read N, compute heights, read each
view's :func:`source_window`, call :func:`view_offset`; combine the windows with
:func:`combine` (weighted mean, χ² consistency verdict from :mod:`prismstation.core.orientation.consistency`).
"""
from __future__ import annotations

from dataclasses import dataclass

from prismstation.core.lazy_cv2 import cv2  # imported at first use: start-up saving
import numpy as np
from scipy import ndimage, special   # special.fdtri is stats.f.ppf without importing scipy.stats (~0.3 s)

from prismstation.core.models import prism
from prismstation.core.matching.coarse import K_SIGMA, Offset, image_offset, search_radius_px
from prismstation.core.orientation.consistency import Verdict, shift_field_verdict
from prismstation.core.models.scene import Scene

#: a-priori σ (m) of the reference heights under an N window (SRTM ~6 m plus slope × N's
#: geolocation error of tens of metres)
SIGMA_HEIGHT_M = 10.0
#: a-priori σ (px) of a view's offset varying across the scene (drift, yaw: ~1 m)
SIGMA_FIELD_PX = 0.4
#: the ancillary mappings are computed every STRIDE N pixels (10 m) and interpolated
STRIDE = 4
#: warps after the first match (each with the offset found so far, see :func:`view_offset`)
REWARPS = 2


def lattice(shape, window_px: int, k: int = 3, margin_px: int = 0) -> list[tuple[int, int, int, int]]:
    """``k × k`` windows ``(col0, row0, window_px, window_px)`` spread over an image of
    ``shape`` (rows, cols), ``margin_px`` from its borders (clipped to fit)."""
    rows, cols = shape
    w = int(min(window_px, rows - 2 * margin_px, cols - 2 * margin_px))
    cs = np.linspace(margin_px, cols - margin_px - w, k).round().astype(int)
    rs = np.linspace(margin_px, rows - margin_px - w, k).round().astype(int)
    return [(int(c), int(r), w, w) for r in rs for c in cs]


def n_pixel_centres(n_window) -> np.ndarray:
    """N pixel centres ``(rows, cols, 2)`` (x, y) of a window (docs/model.md §1: centre at i + 0.5)."""
    c0, r0, w, h = n_window
    xs, ys = np.meshgrid(np.arange(c0, c0 + w) + 0.5, np.arange(r0, r0 + h) + 0.5)
    return np.stack([xs, ys], axis=-1)


def _strided(n_window, stride: int):
    """Pixel centres of the window every ``stride`` px (last row/column included), and the
    fractional indices of every pixel into that coarse grid, for interpolating back."""
    c0, r0, w, h = n_window
    cs = np.unique(np.r_[np.arange(0, w, stride), w - 1])
    rs = np.unique(np.r_[np.arange(0, h, stride), h - 1])
    xs, ys = np.meshgrid(c0 + cs + 0.5, r0 + rs + 0.5)
    fi = np.interp(np.arange(w), cs, np.arange(cs.size))
    fj = np.interp(np.arange(h), rs, np.arange(rs.size))
    jj, ii = np.meshgrid(fj, fi, indexing="ij")
    return np.stack([xs, ys], axis=-1), (jj, ii)


def _upsample(coarse: np.ndarray, idx) -> np.ndarray:
    return ndimage.map_coordinates(coarse, idx, order=1)


def n_heights(scene: Scene, n_window, sample, h0: float, iterations: int = 3,
              stride: int = STRIDE, n_shift=None) -> np.ndarray:
    """Heights ``(rows, cols)`` (ellipsoidal m) of the N window's pixels: ground through the
    ancillary N model at the height ``sample(E, N)`` gives, iterated from ``h0``; computed
    every ``stride`` px and interpolated bilinearly (the reference's posting is coarser).
    ``n_shift(xy) → (n, 2)`` (m, optional): N's own geolocation error where known (a first
    orientation), added to the ancillary ground before sampling — on slopes, heights sampled
    tens of metres off are tens of metres wrong, and each such metre is ~0.2 px of parallax."""
    grid, idx = _strided(n_window, stride)
    xy = grid.reshape(-1, 2)
    h = np.full(len(xy), float(h0))
    move = np.zeros_like(xy) if n_shift is None else np.asarray(n_shift(xy), float)
    for _ in range(iterations):
        en = prism.ancillary_to_ground(scene, scene.views["N"], xy, h, iterations=4) + move
        h = np.asarray(sample(en[:, 0], en[:, 1]), float)
    return _upsample(h.reshape(grid.shape[:2]), idx)


def source_window(scene: Scene, view: str, n_window, heights, margin_px: float):
    """Window ``(col0, row0, cols, rows)`` of ``view`` covering the N window's ground at its
    heights, grown by ``margin_px`` (the search radius plus a little)."""
    c0, r0, w, h = n_window
    sub = heights[::max(1, h // 16), ::max(1, w // 16)]
    xy = n_pixel_centres(n_window)[::max(1, h // 16), ::max(1, w // 16)].reshape(-1, 2)
    en = prism.ancillary_to_ground(scene, scene.views["N"], xy, sub.ravel(), iterations=4)
    p = prism.ground_to_ancillary(scene, scene.views[view], en, sub.ravel())
    lo = np.floor(p.min(0) - margin_px).astype(int)
    hi = np.ceil(p.max(0) + margin_px).astype(int)
    return int(lo[0]), int(lo[1]), int(hi[0] - lo[0]), int(hi[1] - lo[1])


def warp_into_n(scene: Scene, view: str, image: np.ndarray, origin, n_window, heights,
                shift_n_px=(0.0, 0.0), stride: int = STRIDE) -> np.ndarray:
    """``view``'s ``image`` (a window whose top-left pixel corner is ``origin`` = (col, row) in
    the full image) resampled onto the N window's grid through the ancillary model at
    ``heights``; N pixels are first moved by ``shift_n_px``. The mapping is computed every
    ``stride`` px and interpolated; the image is resampled bicubically; NaN outside ``image``."""
    grid, idx = _strided(n_window, stride)
    gh = heights[np.round(grid[..., 1] - n_window[1] - 0.5).astype(int),
                 np.round(grid[..., 0] - n_window[0] - 0.5).astype(int)]
    xy = grid.reshape(-1, 2) + np.asarray(shift_n_px, float)
    en = prism.ancillary_to_ground(scene, scene.views["N"], xy, gh.ravel(), iterations=4)
    p = prism.ground_to_ancillary(scene, scene.views[view], en, gh.ravel())
    mx = _upsample((p[:, 0] - origin[0] - 0.5).reshape(grid.shape[:2]), idx).astype(np.float32)
    my = _upsample((p[:, 1] - origin[1] - 0.5).reshape(grid.shape[:2]), idx).astype(np.float32)
    out = cv2.remap(np.asarray(image, np.float32), mx, my, cv2.INTER_CUBIC,
                    borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
    return out


@dataclass(frozen=True)
class ViewOffset:
    """A view's offset from the ancillary prediction, in N pixels (x, y), with σ and status."""

    view: str
    n_window: tuple
    dx: float
    dy: float
    sigma_dx: float
    sigma_dy: float
    radius_px: float
    status: str
    reason: str
    score: float
    #: the part of the σ from the reference heights (px, along ``along``, the N-space flight
    #: direction); common to all windows, so it does not average out when they are combined
    sigma_parallax_px: float = 0.0
    along: tuple = (0.0, 1.0)

    @property
    def ok(self) -> bool:
        return self.status == "ok"


def view_offset(scene: Scene, view: str, n_image: np.ndarray, n_window, v_image: np.ndarray,
                v_origin, heights, sigma_apriori_m: float, k: float = K_SIGMA,
                sigma_height_m: float = SIGMA_HEIGHT_M) -> ViewOffset:
    """Offset of ``view`` relative to N over ``k·σ·√2 / GSD`` pixels (module docstring).

    ``n_image`` is N's window ``n_window`` (rows, cols); ``v_image`` the view's window read at
    ``v_origin`` (e.g. from :func:`source_window`); ``heights`` from :func:`n_heights`;
    ``sigma_apriori_m`` each view's a-priori geolocation σ per component (m);
    ``sigma_height_m`` the a-priori σ of the window's mean reference height where N claims to
    be (the reference's own error plus slope × N's geolocation error): its parallax
    ``σ_h·|tanθ| / GSD`` along track is added to the matching σ, which knows only the images.
    """
    radius = search_radius_px(sigma_apriori_m * np.sqrt(2), scene.views["N"].pixel_size_m, k)
    warped = warp_into_n(scene, view, v_image, v_origin, n_window, heights)
    bad = ~np.isfinite(warped)
    if bad.mean() > 0.02:
        return ViewOffset(view, tuple(n_window), np.nan, np.nan, np.nan, np.nan, radius, "too_small",
                          f"the {view} window covers only {1 - bad.mean():.0%} of the N window "
                          "and its search range", np.nan)
    warped[bad] = np.nanmean(warped)
    # moving(x + d) = reference(x): N is the reference, the warped view the moving image
    n_image = np.asarray(n_image, np.float32)
    o: Offset = image_offset(n_image, warped, radius, subpixel=REWARPS == 0)
    dx, dy = o.dx, o.dy
    # The warp took the relief where the ancillary model puts the view's pixel, |d| px from
    # the ground the view really sees there: on a slope s that is s·|d|·GSD metres of height,
    # |d|·s·tanθ px along track (6 px scatter at 100 m per view on a 14,000 px scene). Warp
    # again with the offset found and match what is left, over that bound (slopes ≤ 45°);
    # whole pixels until the last match, which adds the sub-pixel value and its σ.
    for k in range(REWARPS):
        if not o.ok:
            break
        again = warp_into_n(scene, view, v_image, v_origin, n_window, heights, shift_n_px=(dx, dy))
        if np.isnan(again).mean() > 0.1:      # a band at the edge; the match uses the core
            return ViewOffset(view, tuple(n_window), dx, dy, np.nan, np.nan, radius, "too_small",
                              f"the {view} image covers only {1 - np.isnan(again).mean():.0%} of the "
                              "N window where the offset puts it", o.score)
        again[np.isnan(again)] = np.nanmean(again)
        bound = float(np.hypot(o.dx, o.dy)) * abs(scene.views[view].tan_theta) + 2.0
        o = image_offset(n_image, again, min(bound, radius), subpixel=k == REWARPS - 1)
        dx, dy = dx + o.dx, dy + o.dy
    cov = np.asarray(o.cov, float)
    par, d = 0.0, np.array([0.0, 1.0])
    if o.ok:
        c0, r0, w, h = n_window
        en = prism.ancillary_to_ground(scene, scene.views["N"], np.array([[c0 + w / 2, r0 + h / 2]]),
                                       np.array([float(np.mean(heights))]))
        d = prism.along_track_unit(scene, en)[0]
        par = sigma_height_m * abs(scene.views[view].tan_theta) / scene.views["N"].pixel_size_m
        cov = cov + par ** 2 * np.outer(d, d)
    return ViewOffset(view, tuple(n_window), dx, dy, float(np.sqrt(cov[0, 0])),
                      float(np.sqrt(cov[1, 1])), radius, o.status, o.reason, o.score,
                      float(par), (float(d[0]), float(d[1])))


def combine(offsets: list[ViewOffset], alpha: float = 0.05, sigma_field_px: float = SIGMA_FIELD_PX):
    """Weighted mean ``(dx, dy)`` of the ok offsets, its σ (rescaled by the data when they
    disagree), and the χ² verdict of a constant offset against the windows' σ, each widened
    by ``sigma_field_px``: how much a view's offset may vary across the scene (attitude drift
    and yaw) before a constant no longer describes it. The reference heights' parallax σ is
    taken as common to all windows (a conservative choice: the reference's smoothing and N's
    own geolocation error bias every window alike), so it is added to the mean's σ whole."""
    ok = [o for o in offsets if o.ok]
    if not ok:
        return np.array([np.nan, np.nan]), np.array([np.nan, np.nan]), None
    d = np.array([[o.dx, o.dy] for o in ok])
    s = np.hypot(np.array([[o.sigma_dx, o.sigma_dy] for o in ok]), sigma_field_px)
    w = 1 / s ** 2
    mean = (d * w).sum(0) / w.sum(0)
    sig = np.sqrt(1 / w.sum(0))
    verdict: Verdict | None = None
    if len(ok) >= 3:
        x = np.array([o.n_window[0] + o.n_window[2] / 2 for o in ok])
        y = np.array([o.n_window[1] + o.n_window[3] / 2 for o in ok])
        verdict = shift_field_verdict(x, y, d, s, alpha=alpha, min_patches=3, model="constant")
        sig = sig * verdict.scale
    par = np.mean([o.sigma_parallax_px for o in ok])
    along = np.mean([o.along for o in ok], axis=0)
    sig = np.hypot(sig, par * np.abs(along))
    return mean, sig, verdict


#: fewest ok windows for an offset gradient (an affine field has three parameters per axis)
MIN_WINDOWS_FOR_GRADIENT = 5
#: significance level of the F-test that keeps a gradient (per image axis)
GRADIENT_ALPHA = 0.01


def gradient(offsets: list[ViewOffset], centre) -> tuple[np.ndarray, np.ndarray]:
    """The view's offset as an affine field over N: ``o + G·(p − centre)`` (px, ``o`` (2,),
    ``G`` (2, 2) px per N pixel). Attitude drift makes it vary: on a simulated 14,000 px
    scene the mean of F's and B's offsets ran from +1.3 to −1.5 px along track, which a
    constant leaves in the relative DEMs' placement. The windows also scatter by the
    reference's height errors (px along track where N's error samples it on slopes), which a
    fitted gradient would carry over the whole scene; so per image axis the gradient is kept
    only when it explains the windows' scatter, by an F-test of the affine against a constant
    at :data:`GRADIENT_ALPHA` on the windows' own residuals. ``G`` is zero (and ``o`` the
    mean) otherwise, with fewer than :data:`MIN_WINDOWS_FOR_GRADIENT` ok windows or windows
    on one line."""
    ok = [o for o in offsets if o.ok]
    d = np.array([[o.dx, o.dy] for o in ok]).reshape(-1, 2)
    if not len(ok):
        return np.array([np.nan, np.nan]), np.zeros((2, 2))
    mean = d.mean(axis=0)
    p = np.array([[o.n_window[0] + o.n_window[2] / 2, o.n_window[1] + o.n_window[3] / 2] for o in ok])
    p = p - np.asarray(centre, float)
    A = np.column_stack([np.ones(len(ok)), p])
    n = len(ok)
    if n < MIN_WINDOWS_FOR_GRADIENT or np.linalg.matrix_rank(A / np.abs(A).max(0), tol=1e-3) < 3:
        return mean, np.zeros((2, 2))
    o, G = mean.copy(), np.zeros((2, 2))
    for k in range(2):
        coef = np.linalg.lstsq(A, d[:, k], rcond=None)[0]
        ssr_a = float(np.sum((d[:, k] - A @ coef) ** 2))
        ssr_c = float(np.sum((d[:, k] - mean[k]) ** 2))
        f = (ssr_c - ssr_a) / 2 / max(ssr_a / (n - 3), 1e-12)
        if f > special.fdtri(2, n - 3, 1 - GRADIENT_ALPHA):
            o[k], G[k] = coef[0], coef[1:]
    return o, G


def offset_at(offset, grad, centre, xy) -> np.ndarray:
    """A view's offset (px) at N positions ``xy`` (..., 2) from its value ``offset`` at
    ``centre`` and its gradient ``grad`` (2 × 2, px per N pixel; None: constant)."""
    xy = np.asarray(xy, float)
    out = np.broadcast_to(np.asarray(offset, float), xy.shape).copy()
    if grad is not None:
        out += (xy - np.asarray(centre, float)) @ np.asarray(grad, float).T
    return out


def n_along_sigma_px(windows: dict, par_px: dict, along, n_weight: float,
                     sigma_field_px: float = SIGMA_FIELD_PX, variance_factor: dict | None = None) -> float:
    """σ (N pixels, along track) of ``(1 − w)·δF + w·δB``, the error F's and B's combined
    offsets put on a cell's N position (``w = n_weight = tanθF / (tanθF + tanθB)``).

    ``windows``: ``{view: {n_window: (sigma_dx, sigma_dy)}}`` of the ok windows (px, the σ
    :func:`view_offset` states, its reference-height term included); ``par_px``: that term per
    view, ``σ_h·tanθ / GSD`` (px along ``along``, the unit N-space flight direction).

    A height error δh of the reference in a window moves F's offset there by ``+δh·tanθF/GSD``
    along track and B's by ``−δh·tanθB/GSD``; with this ``w`` the two cancel in N's position
    (``(1 − w)·tanθF = w·tanθB``). What is left of them comes from the windows F and B do not
    share, or weight differently: ``K²·σ_h²·Σ(wF_i − wB_i)²`` with ``K = (1 − w)·tanθF / GSD``,
    each window's height error taken as its own (the reference's error common to all windows
    cancels whole). The matching part of each window's σ (its stated σ without the height term,
    widened by ``sigma_field_px``) averages over the windows and is scaled by each view's χ²
    variance factor where the windows disagree more than their σ (``variance_factor``).
    Diagonal σ are projected on ``along`` (``sx²·a_x² + sy²·a_y²``)."""
    a = np.asarray(along, float) / np.linalg.norm(along)
    w_view = {"F": 1.0 - n_weight, "B": n_weight}
    weights, var = {}, 0.0
    for v in ("F", "B"):
        wins = windows.get(v) or {}
        if not wins:
            return float("nan")
        keys = list(wins)
        s = np.array([wins[k] for k in keys], float)
        total = s[:, 0] ** 2 * a[0] ** 2 + s[:, 1] ** 2 * a[1] ** 2           # stated, along
        match = np.clip(total - par_px[v] ** 2, 0.0, None) + sigma_field_px ** 2
        wt = 1.0 / (total + sigma_field_px ** 2)                              # as combine weighs them
        wt = wt / wt.sum()
        vf = (variance_factor or {}).get(v)
        scale = max(float(vf), 1.0) if vf is not None and np.isfinite(vf) else 1.0
        var += w_view[v] ** 2 * float(np.sum(wt ** 2 * match)) * scale
        weights[v] = dict(zip(keys, wt))
    k = w_view["F"] * par_px["F"]      # = w·par_B when par ∝ tanθ: the height term of N's position
    union = set(weights["F"]) | set(weights["B"])
    diff = np.array([weights["F"].get(u, 0.0) - weights["B"].get(u, 0.0) for u in union])
    var += k ** 2 * float(np.sum(diff ** 2))
    return float(np.sqrt(var))
