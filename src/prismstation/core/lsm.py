"""Adaptive least-squares matching (Gruen 1985): a patch's position, affine shape and
radiometry estimated together, with the covariance of the position.

Coordinates (docs/model.md §1): image ``x`` = column, ``y`` = row, pixels, continuous, origin
at the top-left corner of the top-left pixel, so array element ``[j, i]`` has its centre at
``(i + 0.5, j + 0.5)``. Images are 2-D arrays of any numeric dtype.

The template is the ``(2h+1)²`` pixels of the reference around the point ``p``; a template
pixel at offset ``w = (u, v)`` from ``p`` (pixel centre minus ``p``) is modelled as

    T(w) = g0 + g1 · S(t + A·w)

with ``S`` the search image (cubic B-spline interpolation, its derivatives analytic), ``t``
the point's position in the search image, ``A`` (2×2) the local shape (search pixels per
reference pixel: the Jacobian of the reference → search mapping at the point) and ``g0``,
``g1`` offset and gain. Gauss–Newton on the 8 parameters from a start ``(t0, A0)``; the result
is ``t`` — the point itself, not a template corner — and its 2×2 covariance.

Covariance. The formal ``σ0²·N⁻¹`` assumes independent grey-value residuals; real residuals
are correlated over a few pixels (resampling, the sensor's point spread, relief the affine
does not follow), which makes it several times too small. :func:`refine` states
``N⁻¹ M N⁻¹`` instead, ``M = Σ_Δ k(Δ)·c(Δ)·Σ_w a(w)·a(w+Δ)ᵀ`` over lags ``|Δ| ≤``
:data:`HAC_LAG` px, ``c(Δ)`` the residuals' autocovariance, ``a`` the design rows and ``k`` the
Bartlett taper (a heteroscedasticity-and-autocorrelation-consistent estimate; at lag 0 alone
it is the formal covariance), times :data:`SIGMA_SCALE`. Tests and
``benchmarks/bench_transfer.py`` check it against empirical scatter.

Failures come back as a status with a reason, never raised and never a silent position:
``not_converged``, ``texture`` (too little texture: σ above the limit or no contrast),
``shape`` (the estimated shape degenerate or far from the start), ``moved`` (the patch ran
away from the start), ``low_correlation``, ``outside`` (the patch leaves an image).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

OK = "ok"
NOT_CONVERGED, TEXTURE, SHAPE, MOVED, LOW_CORRELATION, OUTSIDE = (
    "not_converged", "texture", "shape", "moved", "low_correlation", "outside")

WANDER_ITER = 6
"""Iterations after which a patch still moving by 0.1 px per step is given up."""
"""Largest residual lag (px, each axis) in the covariance's autocorrelation term."""
SIGMA_SCALE = 1.6
"""Factor on the formal σ (calibrated: see the module doc)."""
RELIEF_SCALE = 1.5
"""Factor on the σ of the unmodelled relief displacement (calibrated: see the module doc)."""


@dataclass(frozen=True)
class LsmResult:
    """Outcome of :func:`refine`.

    ``x, y``: the point's position in the search image (pixels; on failure the best estimate,
    check :attr:`ok`); ``cov``: its 2×2 covariance (px², x then y; NaN when it could not be
    computed); ``formal_cov``: ``σ0²·N⁻¹`` alone; ``shape``: ``A`` (2×2); ``gain``, ``offset``:
    ``g1``, ``g0``; ``rho``: correlation of the template with the fitted patch;
    ``iterations``; ``status`` / ``reason``."""

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


class Spline:
    """Cubic B-spline interpolation of a window of an image, with analytic derivatives.

    ``img`` is a window whose top-left corner is image pixel ``(c0, r0)``; :meth:`sample`
    takes image coordinates (continuous, docs/model.md §1)."""

    def __init__(self, img, c0: int = 0, r0: int = 0):
        self.coef = ndimage.spline_filter(np.asarray(img, np.float64), order=3, mode="mirror")
        self.c0, self.r0 = c0, r0
        rows, cols = self.coef.shape
        self._flat, self._w = self.coef.ravel(), cols
        k = np.arange(-1, 3)
        self._taps = (k[:, None] * cols + k[None, :]).ravel()
        self.lo = (c0 + 1.5, r0 + 1.5)                  # where the 4×4 support stays inside
        self.hi = (c0 + cols - 2.5, r0 + rows - 2.5)

    def inside(self, x, y) -> bool:
        return bool(x.min() >= self.lo[0] and y.min() >= self.lo[1]
                    and x.max() <= self.hi[0] and y.max() <= self.hi[1])

    def sample(self, x, y):
        """``(S, ∂S/∂x, ∂S/∂y)`` at image points ``x, y`` (same shape, inside)."""
        col = np.ravel(x) - 0.5 - self.c0
        row = np.ravel(y) - 0.5 - self.r0
        i, j = np.floor(col).astype(np.intp), np.floor(row).astype(np.intp)
        wx, dx = _weights(col - i)
        wy, dy = _weights(row - j)
        g = np.take(self._flat, (j * self._w + i)[:, None] + self._taps)          # (n, 16)
        g = g.reshape(-1, 4, 4)                                                   # [n, row, col]
        gx = np.einsum("nmk,nk->nm", g, wx)
        s = np.einsum("nm,nm->n", gx, wy)
        sy = np.einsum("nm,nm->n", gx, dy)
        sx = np.einsum("nm,nmk,nk->n", wy, g, dx, optimize=False)
        return s.reshape(np.shape(x)), sx.reshape(np.shape(x)), sy.reshape(np.shape(x))


def _weights(t):
    """Cubic B-spline weights for taps −1..2 and their derivatives, ``(n, 4)`` each."""
    w = np.empty((t.size, 4))
    d = np.empty((t.size, 4))
    s = 1.0 - t
    t2 = t * t
    w[:, 0] = s * s * s / 6.0
    w[:, 3] = t2 * t / 6.0
    w[:, 1] = 2.0 / 3.0 - t2 + 0.5 * t2 * t
    w[:, 2] = 1.0 - w[:, 0] - w[:, 1] - w[:, 3]
    d[:, 0] = -0.5 * s * s
    d[:, 3] = 0.5 * t2
    d[:, 1] = 1.5 * t2 - 2.0 * t
    d[:, 2] = -d[:, 0] - d[:, 1] - d[:, 3]
    return w, d


def template(reference, x: float, y: float, half: int):
    """``(T, u, v)``: the ``(2·half+1)²`` reference pixels around ``(x, y)`` (float64) and
    their centres' offsets from the point (pixels), or None when the window leaves the image."""
    i0, j0 = int(np.floor(x)), int(np.floor(y))
    if not (half <= j0 < reference.shape[0] - half and half <= i0 < reference.shape[1] - half):
        return None
    t = np.asarray(reference[j0 - half:j0 + half + 1, i0 - half:i0 + half + 1], np.float64)
    k = np.arange(-half, half + 1, dtype=float)
    v, u = np.meshgrid(k + j0 + 0.5 - y, k + i0 + 0.5 - x, indexing="ij")
    return t, u, v


def search_spline(search, t0, A0, half: int, margin: float, smooth: float = 0.0) -> Spline | None:
    """The :class:`Spline` of the part of ``search`` that a patch of ``A0``-shape at ``t0``
    can reach within ``margin`` px (low-passed by a Gaussian of σ ``smooth`` px when > 0);
    None when less than the patch remains."""
    reach = half * np.abs(np.asarray(A0, float)).sum(axis=1) + margin + 4
    c0 = max(int(np.floor(t0[0] - reach[0])), 0)
    r0 = max(int(np.floor(t0[1] - reach[1])), 0)
    c1 = min(int(np.ceil(t0[0] + reach[0])) + 1, search.shape[1])
    r1 = min(int(np.ceil(t0[1] + reach[1])) + 1, search.shape[0])
    if c1 - c0 < 8 or r1 - r0 < 8:
        return None
    crop = np.asarray(search[r0:r1, c0:c1], np.float64)
    if smooth > 0:
        crop = ndimage.gaussian_filter(crop, smooth, mode="nearest")
    return Spline(crop, c0, r0)


def refine(reference, x: float, y: float, search, t0, A0, *, parallax=None, half: int = 12,
           max_iter: int = 20, max_move: float = 3.0, max_shape_change: float = 0.25,
           min_rho: float = 0.6, max_sigma: float = 0.5, smooth: float = 0.0,
           spline: Spline | None = None) -> LsmResult:
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
        patch may also bend along it: ``+ d·(c1·u² + c2·u·v + c3·v²)/half`` (the terrain's
        curvature within the template, which an affine patch averages into its centre).
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
    """
    tpl = template(reference, x, y, half)
    A0 = np.asarray(A0, float)
    t = np.asarray(t0, float).copy()
    if tpl is None:
        return failed(t[0], t[1], OUTSIDE, "template leaves the reference image", shape=A0)
    T, u, v = tpl
    if smooth > 0:
        m = int(np.ceil(3 * smooth))
        big = template(reference, x, y, half + m)
        if big is None:
            return failed(t[0], t[1], OUTSIDE, "template leaves the reference image", shape=A0)
        T = ndimage.gaussian_filter(big[0], smooth, mode="nearest")[m:-m, m:-m]
    if float(T.std()) <= 1e-6 * (abs(float(T.mean())) + 1.0):
        return failed(t[0], t[1], TEXTURE, "template has no contrast", shape=A0)
    Tv_, Tu_ = np.gradient(T)          # template gradients (grey values per reference px)
    Tu_, Tv_ = Tu_.ravel(), Tv_.ravel()
    if spline is None or smooth > 0:
        spline = search_spline(search, t, A0, half, max_move + 1.0 + 3 * smooth, smooth)
        if spline is None:
            return failed(t[0], t[1], OUTSIDE, "patch leaves the search image", shape=A0)
    u, v, Tf = u.ravel(), v.ravel(), T.ravel()
    if parallax is None:
        d, Q = np.zeros(2), np.zeros((u.size, 0))
    else:
        d = np.asarray(parallax, float) / np.hypot(*parallax)
        Q = np.column_stack([u * u, u * v, v * v]) / half
    nq = Q.shape[1]
    c = np.zeros(nq)
    A = A0.copy()
    A0inv = np.linalg.inv(A0)
    g0, g1 = 0.0, None
    converged = False
    it = 0

    def state():
        bend = Q @ c
        qx = t[0] + A[0, 0] * u + A[0, 1] * v + d[0] * bend
        qy = t[1] + A[1, 0] * u + A[1, 1] * v + d[1] * bend
        if not spline.inside(qx, qy):
            return None
        return spline.sample(qx, qy)

    def design(S, Sx, Sy, esm=False):
        gx, gy = g1 * Sx, g1 * Sy
        if esm:   # Benhimane & Malis 2004: the mean of the search and template gradients
            Ai = np.linalg.inv(A)
            gx = 0.5 * (gx + Ai[0, 0] * Tu_ + Ai[1, 0] * Tv_)
            gy = 0.5 * (gy + Ai[0, 1] * Tu_ + Ai[1, 1] * Tv_)
        gd = (gx * d[0] + gy * d[1])[:, None] * Q
        return np.column_stack([gx, gy, gx * u, gx * v, gy * u, gy * v, gd, np.ones_like(S), S])

    for it in range(1, max_iter + 1):
        smp = state()
        if smp is None:
            return failed(t[0], t[1], OUTSIDE, "patch left the search image", shape=A, iterations=it)
        S, Sx, Sy = smp
        if g1 is None:
            g1 = Tf.std() / max(S.std(), 1e-12)
            g0 = Tf.mean() - g1 * S.mean()
        r = Tf - (g0 + g1 * S)
        J = design(S, Sx, Sy, esm=True)
        try:
            dp = np.linalg.solve(J.T @ J, J.T @ r)
        except np.linalg.LinAlgError:
            return failed(t[0], t[1], TEXTURE, "singular normal matrix (no texture)", shape=A, iterations=it)
        t += dp[0:2]
        A += dp[2:6].reshape(2, 2)
        c += dp[6:6 + nq]
        g0 += dp[6 + nq]
        g1 += dp[7 + nq]
        if np.hypot(*(t - t0)) > max_move:
            return failed(t0[0], t0[1], MOVED, f"the patch moved more than {max_move:g} px from its start",
                          shape=A, iterations=it)
        change = np.linalg.norm(A0inv @ A - np.eye(2))      # ≥ the largest singular value
        if change > 2 * max_shape_change or g1 <= 0 or np.abs(c).max(initial=0) * half > 2 * max_move:
            return failed(t[0], t[1], SHAPE, "the patch's contrast inverted" if g1 <= 0 else
                          f"the shape degenerated (changed by {change:.0%})", shape=A, iterations=it)
        if np.abs(dp[0:2]).max() < 2e-3 and np.abs(dp[2:6 + nq]).max() * half < 5e-3:
            converged = True
            break
        if it >= WANDER_ITER and np.hypot(*dp[0:2]) > 0.1:
            break   # still wandering: no convergence
    smp = state()
    if smp is None:
        return failed(t[0], t[1], OUTSIDE, "patch left the search image", shape=A, iterations=it)
    S, Sx, Sy = smp
    r = Tf - (g0 + g1 * S)
    rho = float(np.corrcoef(Tf, S)[0, 1])
    if not converged:
        return failed(t[0], t[1], NOT_CONVERGED, f"no convergence in {max_iter} iterations",
                      shape=A, rho=rho, iterations=it)
    change = np.linalg.svd(A0inv @ A - np.eye(2), compute_uv=False)[0]
    if change > max_shape_change:
        return failed(t[0], t[1], SHAPE, f"the shape changed by {change:.0%} from the start "
                      f"(more than {max_shape_change:.0%})", shape=A, rho=rho, iterations=it)
    J = design(S, Sx, Sy)
    Ninv = np.linalg.inv(J.T @ J)
    n, k = 2 * half + 1, J.shape[1]
    formal = float(r @ r) / max(r.size - k, 1) * Ninv[:2, :2]
    cov = SIGMA_SCALE ** 2 * formal
    s_relief = 0.0
    if parallax is not None:
        G = (J[:, 0] * d[0] + J[:, 1] * d[1]).reshape(n, n)
        s_relief = unmodelled_sigma(G, r.reshape(n, n), k)
        cov = cov + (RELIEF_SCALE * s_relief) ** 2 * np.outer(d, d)
    res = LsmResult(float(t[0]), float(t[1]), cov, formal, A, float(g1), float(g0), rho, it, OK, "",
                    rho, {"bend": c.copy(), "sigma_relief": s_relief, "d": d})
    if rho < min_rho:
        return _as_failure(res, LOW_CORRELATION, f"correlation {rho:.2f} below {min_rho:.2f}")
    smax = float(np.sqrt(np.linalg.eigvalsh(cov)[-1]))
    if not np.isfinite(smax) or smax > max_sigma:
        return _as_failure(res, TEXTURE, f"too little texture: σ {smax:.2f} px above {max_sigma:.2f}")
    return res


def unmodelled_sigma(G, r, n_params: int, block: int = 4) -> float:
    """σ (px) of the displacement along the parallax that the patch's shape does not follow.

    ``G``: the fitted patch's gradient along the parallax direction on the template grid
    ``(n, n)`` (grey values per px), ``r``: the residuals ``(n, n)``, ``n_params``: the
    adjustment's parameter count. Each ``block × block`` part of the template gets its own
    displacement ``δ = ΣGr / ΣG²`` (the residual a displacement leaves is ``G·δ``); what the
    residuals hold beyond it is noise of variance ``σn²``; the σ is the ``ΣG²``-weighted RMS of
    the ``δ`` less their noise ``σn²/ΣG²``: the relief within the template that no affine or
    quadratic patch follows — the error it leaves at the point is of that size."""
    n = r.shape[0]
    m = n // block
    if m < 2:
        return 0.0
    lo = (n - m * block) // 2
    Gb = G[lo:lo + m * block, lo:lo + m * block].reshape(m, block, m, block).transpose(0, 2, 1, 3).reshape(m * m, -1)
    rb = r[lo:lo + m * block, lo:lo + m * block].reshape(m, block, m, block).transpose(0, 2, 1, 3).reshape(m * m, -1)
    g2 = np.sum(Gb * Gb, axis=1)
    if np.any(g2 <= 0):
        return 0.0
    delta = np.sum(Gb * rb, axis=1) / g2
    noise = float(np.sum((rb - Gb * delta[:, None]) ** 2)) / max(rb.size - m * m - n_params, 1)
    excess = np.sum(g2 * delta ** 2 - noise) / np.sum(g2)
    return float(np.sqrt(max(excess, 0.0)))


def _as_failure(res: LsmResult, status: str, reason: str) -> LsmResult:
    from dataclasses import replace
    return replace(res, status=status, reason=reason)
