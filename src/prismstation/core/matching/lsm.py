"""Adaptive least-squares matching (Gruen 1985): a patch's position, shape and radiometry
estimated together, with the covariance of the position.

Coordinates (docs/model.md §1): image ``x`` = column, ``y`` = row, pixels, continuous, origin
at the top-left corner of the top-left pixel, so array element ``[j, i]`` has its centre at
``(i + 0.5, j + 0.5)``. Images are 2-D arrays of any numeric dtype.

The template is the ``(2h+1)²`` pixels of the reference around the point; a template pixel at
offset ``w = (u, v)`` from the point (pixel centre minus point) is modelled as

    T(w) = g0 + g1 · S(t + A·w [+ d·(c1·u² + c2·u·v + c3·v²)/h])

with ``S`` the search image (cubic B-spline interpolation, values and gradients exact:
:mod:`prismstation.core.matching.lsm_spline`), ``t`` the point's position in the search image, ``A``
(2×2) the local shape (search pixels per reference pixel: the Jacobian of the reference →
search mapping at the point), ``g0``, ``g1`` offset and gain, and optionally a bend along the
parallax direction ``d`` (the terrain's curvature within the template). Gauss–Newton from a
start ``(t0, A0)``; the result is ``t`` — the point itself, not a template corner — and its 2×2
covariance.

Covariance (:func:`refine`): ``(SIGMA_SCALE·σ_formal)² + (RELIEF_SCALE·σ_relief)²·ddᵀ +
σ_across²·d⊥d⊥ᵀ + C_sampling``. The formal ``σ0²·N⁻¹`` is inflated for the noise in the search
image's gradients; ``σ_relief`` and ``σ_across`` are the displacement the patch's shape does
not follow, along and across ``d``; ``C_sampling`` is where point-sampled edges (no optical
blur) lie between their samples in both views, and the pixels on such edges are weighted down
in the fit by that variance (all in :mod:`prismstation.core.matching.lsm_sigma`). Along ``d``
a second fit weighted to the point's surroundings (Gaussian of σ :data:`TAPER` px) gives the
position and σ when it states the smaller σ there, the two fits' disagreement counted in
both (relief finer than the template). Where the images are point-sampled (no optical blur),
the point is then moved by how far its fit moves on both images low-passed
(:mod:`prismstation.core.matching.lsm_sampled`): the pull of the two pixel grids, which the
stated covariance (built before) still holds. The factors were calibrated on simulated PRISM
triplets (the fractal relief, smooth hills, a real DEM's relief); ``tests/core/test_lsm.py`` and
``benchmarks/bench_transfer.py`` check the σ against the scatter on other scenes, on warped
real Pléiades texture and on the real Pléiades triplet (docs/matching.md).

Failures come back as a status with a reason, never raised and never a silent position:
``not_converged``, ``texture`` (too little texture: no contrast, noise outweighing the
gradients, or σ above the limit), ``shape`` (the shape degenerate or moved beyond its
allowance), ``moved`` (the patch ran away from its start), ``low_correlation``, ``outside``
(the patch leaves an image).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import lru_cache

import numpy as np
from scipy import special   # special.fdtri is stats.f.ppf without importing scipy.stats (~0.3 s)

from prismstation.core.matching.lsm_fit import (LOW_CORRELATION, MOVED, NOT_CONVERGED, OK,  # noqa: F401
                                                OUTSIDE, RIVAL_ITER, RIVAL_MARGIN, SHAPE, STEP_TOL, TEXTURE, Fit,
                                                max_bend, shape_check, template)
from prismstation.core.matching.lsm_sampled import POINT_SAMPLED, PULL_SHARE, smoothed_shift, template_stats
from prismstation.core.matching.lsm_sigma import (gradient_noise_inflation, largest_sigma, sampling_px,
                                                  sampling_scatter, unmodelled_sigma)
from prismstation.core.matching.lsm_spline import Spline, low_pass, search_spline

SIGMA_SCALE = 1.5
"""Factor on the formal σ: the views differ by more than noise (point spread, resampling),
calibrated on the simulated triplets (1.3 times too large on warped real texture)."""
RELIEF_SCALE = 2.0
"""Factor on the σ of the unmodelled relief along the parallax: the 4 px blocks smooth the
finest relief (calibrated on the simulator's fractal relief)."""
BEND_P = 0.99
"""Confidence of the F test that keeps a bend."""
TAPER = 3.0
"""σ (px) of the Gaussian weight about the point in the fit that gives the position along the
parallax: relief finer than the template moves the point by its own height, which an average
over the whole template misses (on the fractal relief 0.22 px along the parallax with the whole
template, 0.11 px with this weight; on smooth hills 0.04 and 0.07 px)."""
COARSE_HALF = 18
"""Templates of at least this half size (px) iterate on a quarter of their pixels first."""
COARSE_TOL = 0.1
"""The step (px) at which that first pass hands over to all the pixels: it only has to bring
the patch within their reach. Converging it to :data:`STEP_TOL` took 5 iterations a match on
the foreign scene (the every-other-pixel grid aliases the texture), where the full pass then
needed 3.3 all the same."""
TAPER_REACH = 4.0
"""The weighted fit iterates on the pixels within this many :data:`TAPER` of the point (beyond,
the weights are under 3·10⁻⁴; its σ counts every pixel)."""
NEAR_GAIN = 2.0
"""The weighted fit's formal σ is about this many times the whole template's (its Gaussian
holds a fifth of the template's weight): it is tried only where the unmodelled relief makes
the whole template's σ larger than that."""
NEAR_RELIEF = 0.7
"""The weighted fit's error along the parallax as a share of its disagreement with the whole
template's (measured on mounds 3–8 px wide on warped real texture: 0.4–0.7)."""
MID_HALF = 18
"""Half size (px) of the central part of a larger template fitted again from its end
(:func:`_mid_check`): relief within 65 px on steep slopes moves the whole template's position
by its mean over them."""
BEND_TRIGGER = 0.03
"""A bend is tried when the affine patch leaves this much unmodelled relief (px)."""
SAME = "same"
"""Status of a fit from another start that ended where a match already made ended (``found``
of :func:`refine`): that match again, given up before its further fits."""
SAME_PX = 0.1
"""How close (px) the whole template's affine fits must end to be one minimum: two minima of
point-sampled texture lie a few tenths of a pixel apart, so closer than that is one."""


@dataclass(frozen=True)
class LsmResult:
    """Outcome of :func:`refine`.

    ``x, y``: the point's position in the search image (pixels; on failure the best estimate,
    check :attr:`ok`); ``cov``: its 2×2 covariance (px², x then y; NaN when it could not be
    computed); ``formal_cov``: ``σ0²·N⁻¹`` with the gradient-noise inflation, before the
    factors and the unmodelled displacement; ``shape``: ``A`` (2×2); ``gain``, ``offset``:
    ``g1``, ``g0``; ``rho``: correlation of the template with the fitted patch;
    ``iterations``; ``status`` / ``reason``; ``score``: the correlation peak the search started
    from (:mod:`prismstation.core.matching.lsm_search`); ``extra``: ``bend`` (c1, c2, c3), ``sigma_relief``,
    ``sigma_across`` (px), the parallax direction ``d``, the template's ``half`` size, ``mid``
    (px: the central part's disagreement along the parallax where it entered, else 0),
    ``edges`` (px: the template's mean σ of where its edges lie between samples,
    :func:`~prismstation.core.matching.lsm_sampled.edge_sigma`), ``smoothed`` ((2,) px: how
    far the low-passed last fit moved the point, zeros where the images are not point-sampled)
    ``noise_along`` (px: the noise's share of the σ along the parallax, the rest relief),
    ``fit`` ((2,) px: where the whole template's affine fit ended, before the later fits) and
    ``along_half`` (the half size of the square of template pixels, fitted uniformly, whose
    fit gave the position along the parallax: the template's own, :data:`MID_HALF` for its
    central part; 0 for the fit weighted to the point's surroundings)."""

    x: float
    y: float
    cov: np.ndarray
    formal_cov: np.ndarray
    shape: np.ndarray
    gain: float
    offset: float
    rho: float
    iterations: int
    status: str
    reason: str = ""
    score: float = float("nan")        # the correlation shown to the operator (set by callers)
    extra: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == OK

    @property
    def sigma_x(self) -> float:
        return float(np.sqrt(self.cov[0, 0]))

    @property
    def sigma_y(self) -> float:
        return float(np.sqrt(self.cov[1, 1]))

    @property
    def formal_sigma_x(self) -> float:
        return float(np.sqrt(self.formal_cov[0, 0]))

    @property
    def formal_sigma_y(self) -> float:
        return float(np.sqrt(self.formal_cov[1, 1]))


_NAN2 = np.full((2, 2), np.nan)


def failed(x, y, status, reason, *, shape=None, rho=np.nan, iterations=0, score=np.nan) -> LsmResult:
    """A failed :class:`LsmResult` at the best estimate ``(x, y)``."""
    return LsmResult(float(x), float(y), _NAN2, _NAN2, np.eye(2) if shape is None else np.asarray(shape, float),
                     np.nan, np.nan, float(rho), iterations, status, reason, float(score))


def refine(reference, x: float, y: float, search, t0, A0, *, parallax=None, half: int = 12,
           max_iter: int = 20, max_move: float = 3.0, max_shape_change: float = 0.25,
           min_rho: float = 0.6, max_sigma: float = 0.5, smooth: float = 0.0,
           spline: Spline | None = None, taper: float = TAPER, need_rho: float | None = None,
           found=None) -> LsmResult:
    """Least-squares matching of the point ``(x, y)`` of ``reference`` in ``search``.

    Parameters
    ----------
    reference, search : ndarray (rows, cols)
    x, y : float
        The point in the reference image (pixels).
    t0 : (2,)
        Start position of the point in the search image (pixels).
    A0 : (2, 2)
        Start shape: search pixels per reference pixel, columns the images of the reference
        x and y axes (e.g. from the sensor model and the terrain slope).
    parallax : (dx, dy) or None
        The direction in the search image along which relief displaces points. Given, the
        affine patch, once converged, may also bend along it: ``+ d·(c1·u² + c2·u·v +
        c3·v²)/half`` (the terrain's curvature within the template, which an affine patch
        averages into its centre); the bend is kept when it is significant (F test at
        :data:`BEND_P`, on residuals scaled by :data:`SIGMA_SCALE`) and under
        :func:`~prismstation.core.matching.lsm_fit.max_bend` px at the template's edge.
    half : int
        Template half size: ``(2·half+1)²`` pixels.
    max_iter : int
        Gauss–Newton iterations before ``not_converged``.
    max_move : float
        Largest distance (px) of the result from ``t0`` (``moved`` beyond).
    max_shape_change : float
        Largest change of the shape from ``A0``, as the largest singular value of
        ``A0⁻¹A − I`` (``shape`` beyond; 0.25: ±25 % scale or shear).
    min_rho : float
        Correlation of template and fitted patch below this: ``low_correlation``.
    max_sigma : float
        Stated σ (px, larger semi-axis) above this: ``texture``.
    smooth : float
        σ (px) of a Gaussian low-pass applied to both images first (a coarse pass; 0: none).
    spline : Spline, optional
        A ready :class:`Spline` of ``search`` (for repeated calls); built here otherwise.
    need_rho : float, optional
        The correlation the match must reach to matter (a rival of a match found already):
        given up early (``low_correlation``) when it falls far short (:data:`RIVAL_MARGIN`).
    found : (k, 2), optional
        Where the whole template's affine fits of matches already made (from other starts) ended
        (``extra["fit"]``): a fit ending within :data:`SAME_PX` of one is that match again,
        returned at once as :data:`SAME`.
    """
    A0 = np.asarray(A0, float)
    t0 = np.asarray(t0, float)
    m = int(np.ceil(3 * smooth)) if smooth > 0 else 0
    tpl = template(reference, x, y, half + m)
    if tpl is None:
        return failed(t0[0], t0[1], OUTSIDE, "template leaves the reference image", shape=A0)
    T, u, v = tpl
    if m:
        T, u, v = low_pass(T, smooth)[m:-m, m:-m], u[m:-m, m:-m], v[m:-m, m:-m]
    if float(T.std()) <= 1e-6 * (abs(float(T.mean())) + 1.0):
        return failed(t0[0], t0[1], TEXTURE, "template has no contrast", shape=A0)
    if spline is None or smooth > 0:
        # room for the patch to move by max_move and its shape to change by max_shape_change
        spline = search_spline(search, t0, A0, half, max_move + 1.0 + 3 * smooth + 1.5 * max_shape_change * half,
                               smooth)
        if spline is None:
            return failed(t0[0], t0[1], OUTSIDE, "patch leaves the search image", shape=A0)
    d = np.zeros(2) if parallax is None else np.asarray(parallax, float) / np.hypot(*parallax)
    t_noise, aliasing, grads, edges, pw = template_stats(T)
    fit = Fit(T, u, v, spline, d, half, grads=grads)
    fit.t, fit.A, fit.pw = t0.copy(), A0.copy(), pw
    A0inv = np.linalg.inv(A0)
    it = 0
    if half >= COARSE_HALF:
        # a large template converges first on every other row and column (a quarter of the
        # cost per iteration), then on all its pixels from there (an iteration or two)
        keep = ((np.abs(np.rint(u - u.flat[0])) % 2 == 0) & (np.abs(np.rint(v - v.flat[0])) % 2 == 0)).ravel()
        sparse = fit.subset(keep)
        status, reason, it = sparse.run(False, max_iter, t0, max_move, A0inv, max_shape_change, need_rho,
                                       COARSE_TOL)
        if status == OK:
            fit.take(sparse)
        elif status in (MOVED, OUTSIDE, SHAPE, LOW_CORRELATION):
            fit.take(sparse)
            x_, y_ = (t0 if status == MOVED else fit.t)
            return failed(x_, y_, status, reason, shape=fit.A, iterations=it)
    status, reason, it2 = fit.run(False, max_iter, t0, max_move, A0inv, max_shape_change, need_rho)
    it += it2
    if status == OK and found is not None and len(found) and np.min(np.hypot(*(np.asarray(found) - fit.t).T)) < SAME_PX:
        return failed(fit.t[0], fit.t[1], SAME, "the match found already from another start", shape=fit.A,
                      iterations=it)
    fit_t = fit.t.copy()
    if status != OK:
        x_, y_ = (t0 if status == MOVED else fit.t)
        rho = fit.final(False)[2] if status == NOT_CONVERGED else np.nan
        return failed(x_, y_, status, reason, shape=fit.A, rho=rho, iterations=it)
    r, J, rho = fit.final(False)
    if r is None:
        return failed(fit.t[0], fit.t[1], OUTSIDE, "patch left the search image", shape=fit.A, iterations=it)
    n = 2 * half + 1
    bend = False
    if parallax is not None and unmodelled_sigma(_along(J, d, n), r.reshape(n, n), J.shape[1]) > BEND_TRIGGER:
        curved = fit.copy()
        status, _, it2 = curved.run(True, max_iter, t0, max_move, A0inv, max_shape_change)
        it += it2
        if status == OK and np.abs(curved.c).max() * half <= max_bend(half):
            r1, J1, rho1 = curved.final(True)
            if r1 is not None and _significant(r, r1):
                fit, bend, r, J, rho = curved, True, r1, J1, rho1
        elif status == NOT_CONVERGED:
            # the relief within the template asks for a bend that does not settle: the affine
            # patch's position there is not a match (on steep relief 0.54 px RMS, against 0.24
            # where a bend was kept)
            return failed(fit.t[0], fit.t[1], NOT_CONVERGED, f"the bend's fit did not converge in "
                          f"{it2} iterations", shape=fit.A, rho=rho, iterations=it)
    why = shape_check(A0, fit.A, d if parallax is not None else None, max_shape_change)
    if why:
        return failed(fit.t[0], fit.t[1], SHAPE, why + " from the start", shape=fit.A, rho=rho, iterations=it)
    e1 = d if parallax is not None else np.array([1.0, 0.0])
    e2 = np.array([-e1[1], e1[0]])
    # the image noise, the lower of the two images' (in the template's grey values): textured
    # ground makes the estimate high, never low
    noise = min(t_noise, fit.g1 * spline.noise_near(fit.t[0], fit.t[1], half))
    stated = _stated(fit, r, J, noise, e1, e2, n, aliasing)
    if stated is None:
        return failed(fit.t[0], fit.t[1], TEXTURE, "too little texture: the image noise outweighs its gradients",
                      shape=fit.A, rho=rho, iterations=it)
    cov, formal, s_relief, s_across, sampled, s_floor = stated
    t = fit.t.copy()
    local = 0.0
    along_fit = fit           # the fit whose position along the parallax is kept
    near_fit = None
    kept_sampled = sampled    # the sampling share of that fit
    if taper > 0 and parallax is not None and e1 @ cov @ e1 > NEAR_GAIN ** 2 * SIGMA_SCALE ** 2 * (e1 @ formal @ e1):
        # the relief the patch leaves moves the point along the parallax: a fit weighted to the
        # point's surroundings follows it closer. How far the two fits disagree along the
        # parallax measures that relief: the whole template's may be off by all of it, the
        # weighted one by :data:`NEAR_RELIEF` of it. The one stating the smaller σ gives the
        # position along the parallax (across, where relief moves nothing, the whole template)
        r2 = fit.u ** 2 + fit.v ** 2
        near, status, it3 = _refit(fit, np.exp(-r2 / (2 * taper ** 2)), r2 <= (TAPER_REACH * taper) ** 2, bend,
                                   (max_iter, t0, max_move, A0inv, max_shape_change))
        r3, J3, _ = near.final(bend) if status == OK else (None, None, None)
        st3 = _stated(near, r3, J3, noise, e1, e2, n, aliasing) if r3 is not None else None
        if st3 is not None:
            it += it3
            P1, P2 = np.outer(e1, e1), np.outer(e2, e2)
            delta = float(e1 @ (near.t - fit.t))
            var_near = e1 @ st3[0] @ e1 + (NEAR_RELIEF * delta) ** 2
            var_whole = max(e1 @ cov @ e1, delta ** 2)
            along = sampled
            if var_near < var_whole:
                t = t + P1 @ (near.t - fit.t)
                formal = (e1 @ st3[1] @ e1) * P1 + (e2 @ formal @ e2) * P2
                s_relief, local, along, along_fit = st3[2], taper, st3[4], near
                near_fit = near
                kept_sampled = along
            # the sampling of the fit that gives the position along the parallax, the whole
            # template's across
            cov = (min(var_near, var_whole) + e1 @ along @ e1) * P1 + (e2 @ (cov + sampled) @ e2) * P2
            sampled = None
    if sampled is not None:
        cov = cov + sampled
    # the noise's share of the σ along the parallax: the rest is relief the patch leaves
    noise_along = float(np.sqrt(SIGMA_SCALE ** 2 * (e1 @ formal @ e1) + e1 @ kept_sampled @ e1))
    mid = 0.0
    if parallax is not None and half > MID_HALF:
        t, cov, mid, it4, central = _mid_check(fit, t, cov, bend, (max_iter, t0, max_move, A0inv, max_shape_change),
                                               noise, e1, e2, n, aliasing)
        along_fit = central or along_fit
        it += it4
    if parallax is not None and along_fit is fit:
        # the relief the blocks read, no smaller than its own standard error under noise
        # alone: where few blocks hold the information a nil reading is not a nil relief
        # (as across: the floor is the reading's own noise, not relief the blocks smooth, so
        # it is not scaled by RELIEF_SCALE)
        cov = cov + max(s_floor ** 2 - (RELIEF_SCALE * s_relief) ** 2, 0.0) * np.outer(e1, e1)
    # the checks before the low-passed fit (its shift's own σ is checked after it)
    smax = largest_sigma(cov)
    why = ((LOW_CORRELATION, f"correlation {rho:.2f} below {min_rho:.2f}") if rho < min_rho else
           (TEXTURE, _too_vague(smax, max_sigma)) if not np.isfinite(smax) or smax > max_sigma else None)
    shift = np.zeros(2)
    if why is None and smooth == 0 and edges > POINT_SAMPLED:
        # the point-sampled images' sub-pixel pull: across the parallax the whole template's;
        # along it that of the fit that gave the position there, where the relief it leaves is
        # under its edges' σ (beyond, the low-pass moves the fit by the relief it weighs anew)
        run_args = (max_iter, t0, max_move, A0inv, max_shape_change)
        whole, it5 = smoothed_shift(reference, x, y, search, fit, bend, run_args)
        along = whole if along_fit is fit else np.zeros(2)
        if along_fit is not fit and s_relief < edges:
            along, it6 = smoothed_shift(reference, x, y, search, along_fit, bend, run_args)
            it5 += it6
        shift = e2 * float(e2 @ whole) + (e1 * float(e1 @ along) if s_relief < edges else 0.0)
        t, it = t + shift, it + it5
        # what the shift leaves, in its direction: the σ may now refuse the match
        cov = cov + PULL_SHARE ** 2 * np.outer(shift, shift)
        smax = largest_sigma(cov)
        if smax > max_sigma:
            why = (TEXTURE, _too_vague(smax, max_sigma) + f" (with the low-passed fit's shift, "
                            f"{np.hypot(*shift):.2f} px)")
    res = LsmResult(float(t[0]), float(t[1]), cov, formal, fit.A.copy(), float(fit.g1), float(fit.g0),
                    rho, it, OK, "", rho, {"bend": fit.c.copy() if bend else np.zeros(3),
                                           "sigma_relief": s_relief, "sigma_across": s_across, "d": d,
                                           "taper": local, "half": half, "mid": mid, "smoothed": shift,
                                           "edges": edges, "noise_along": noise_along, "fit": fit_t,
                                           "along_half": (half if along_fit is fit else MID_HALF
                                                          if along_fit is not near_fit else 0)})
    return res if why is None else replace(res, status=why[0], reason=why[1])


def _too_vague(smax: float, max_sigma: float) -> str:
    """The reason of a match refused for its σ (``texture``)."""
    return f"too little texture: σ {smax:.2f} px above {max_sigma:.2f}"


def _refit(fit: Fit, w, keep, bend: bool, run_args):
    """``(copy, status, iterations)``: ``fit`` fitted again from its end with the pixel weights
    ``w`` ``(n²,)``, iterating on the pixels ``keep`` only (beyond them the weight is nil or
    negligible); the copy holds the result on all the pixels."""
    other = fit.copy()
    other.w, other.keep = w, keep
    part = other.subset(keep)
    status, _, it = part.run(bend, *run_args)
    other.take(part)
    return other, status, it


def _mid_check(fit: Fit, t, cov, bend: bool, run_args, noise: float, e1, e2, n: int, aliasing):
    """The template's central :data:`MID_HALF` px fitted from the whole one's end: relief
    within a large template moves its position along the parallax by the relief's mean over
    it. Their disagreement ``Δ`` beyond what both state (``Δ² − σ² − σ_mid²``, along the
    parallax) is relief that neither σ holds: it is added to both, and the one stating less
    gives the position along the parallax (across, the whole template). Returns ``(t, cov,
    Δ or 0 when it was not used, iterations)``."""
    inside = (np.abs(fit.u) <= MID_HALF) & (np.abs(fit.v) <= MID_HALF)
    mid, status, it = _refit(fit, inside.astype(float), inside, bend, run_args)
    if status != OK:
        return t, cov, 0.0, it, None
    delta = float(e1 @ (mid.t - t))
    var_whole = float(e1 @ cov @ e1)
    if delta ** 2 <= var_whole:
        return t, cov, 0.0, it, None    # within the whole template's own σ: nothing to add
    r, J, _ = mid.final(bend)
    st = _stated(mid, r, J, noise, e1, e2, n, aliasing) if r is not None else None
    if st is None:
        return t, cov, 0.0, it, None
    var_mid = float(e1 @ (st[0] + st[4]) @ e1)
    excess = delta ** 2 - var_whole - var_mid
    if excess <= 0:
        return t, cov, 0.0, it, None
    P1 = np.outer(e1, e1)
    if var_mid < var_whole:
        t = t + P1 @ (mid.t - t)
    cov = (min(var_mid, var_whole) + excess) * P1 + float(e2 @ cov @ e2) * np.outer(e2, e2)
    return t, cov, delta, it, (mid if var_mid < var_whole else None)


def _stated(fit: Fit, r, J, noise: float, e1, e2, n: int, aliasing=None):
    """``(cov, formal, σ_relief, σ_across, sampled, σ_floor)`` of the fitted position (see
    :func:`refine`; ``σ_floor``: σ_relief no smaller than its own standard error; ``noise``:
    the images' noise σ in the template's grey values; ``aliasing``: :func:`sampling_px` of
    the template), None when the noise outweighs the gradients;
    ``sampled`` (2×2, px²), the point-sampled edges' share, is not in ``cov``."""
    k = J.shape[1]
    if fit.weights() is None:        # uniform weights: the sandwich is N⁻¹ itself
        s02 = float(r @ r) / max(r.size - k, 1)
        inflation = gradient_noise_inflation(J[:, 0], J[:, 1], noise ** 2, r.size)
        if not np.isfinite(inflation):
            return None
        Ni = np.linalg.inv(J.T @ J)
        formal = s02 * Ni[:2, :2] * inflation
        wn = None
        Jw = J
    else:
        w = fit.weights()
        s02 = float(w @ (r * r)) / float(w.sum()) * r.size / max(r.size - k, 1)
        # the noise's share of the information JᵀWJ: the taper's weights enter the gradients
        # (its sandwich), the aliasing's the information (the pixels' inverse variances)
        wt = np.ones(r.size) if fit.w is None else fit.w
        wp = np.ones(r.size) if fit.pw is None else fit.pw
        inflation = gradient_noise_inflation(J[:, 0] * wt * np.sqrt(wp), J[:, 1] * wt * np.sqrt(wp), noise ** 2,
                                             float(wt @ (wt * wp)))
        if not np.isfinite(inflation):
            return None
        Jw = J * w[:, None]
        Ni = np.linalg.inv(J.T @ Jw)
        formal = s02 * (Ni @ (J.T @ (Jw * w[:, None])) @ Ni)[:2, :2] * inflation
        wn = None if fit.w is None else fit.w.reshape(n, n)
    # the displacement the patch's shape does not follow, along the parallax and across it
    g_along = _along(J, e1, n)
    s_relief, s_floor = unmodelled_sigma(g_along, r.reshape(n, n), k, w=wn, both=True)
    s_across = unmodelled_sigma(_along(J, e2, n), r.reshape(n, n), k, w=wn, other=g_along, floor=True)
    cov = (SIGMA_SCALE ** 2 * formal + (RELIEF_SCALE * s_relief) ** 2 * np.outer(e1, e1)
           + s_across ** 2 * np.outer(e2, e2))
    # where point-sampled edges lie between their samples, in both views (:func:`sampling_px`)
    sampled = np.zeros((2, 2))
    if aliasing is not None and (aliasing[0].any() or aliasing[1].any()):
        K = sampling_scatter(Jw.reshape(n, n, k), J[:, 0].reshape(n, n), J[:, 1].reshape(n, n), *aliasing)
        sampled = 2.0 * (Ni @ K @ Ni)[:2, :2]
    return cov, formal, s_relief, s_across, sampled, s_floor


def _along(J, d, n: int):
    """The design's gradient along ``d`` on the template grid ``(n, n)``."""
    return (J[:, 0] * d[0] + J[:, 1] * d[1]).reshape(n, n)


def _significant(r0, r1) -> bool:
    """F test of the bend: do its residuals ``r1`` lower the affine patch's ``r0`` more than
    noise would (at :data:`BEND_P`, the residual variance scaled by :data:`SIGMA_SCALE`²)?"""
    dof = r1.size - 11
    f = (float(r0 @ r0) - float(r1 @ r1)) / 3 / (SIGMA_SCALE ** 2 * float(r1 @ r1) / dof)
    return bool(f > _f_quantile(dof))


@lru_cache(maxsize=64)
def _f_quantile(dof: int) -> float:
    return float(special.fdtri(3, dof, BEND_P))
