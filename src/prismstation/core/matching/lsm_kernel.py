"""The compiled inner loops of least-squares matching (:mod:`prismstation.core.matching.lsm`):
a window's cubic B-spline coefficients, the spline sampled with its derivatives at points or
over a patch's pixels, the rows of a Gauss–Newton design, its normal equations and the whole
loop of iterations, and the block sums and edge σ its covariance is made of
(:mod:`prismstation.core.matching.lsm_sigma`). Numba compiles them on first use and caches
them on disk (:func:`compile_kernels` loads them all): each is one pass over the pixels, where
the same work in array operations made a dozen passes and as many temporary arrays (a
transfer took 1.4–1.7 times as long so: docs/matching.md, speed).

Coordinates (docs/model.md §1): image ``x`` = column, ``y`` = row, pixels, continuous; the
spline's coefficient array ``flat`` is row-major with ``width`` columns, its element
``[j, i]`` centred at image point ``(c0 + i + 0.5, r0 + j + 0.5)``. Values are grey values,
gradients grey values per pixel, float64.
"""
from __future__ import annotations

import gc
import math

import numpy as np
from numba import njit

# no 'nnan' among the fast-math flags: the bounds checks must see a NaN position (it is outside)
_OPTS = dict(cache=True, nogil=True, fastmath={"contract", "reassoc", "nsz", "arcp", "afn"})


@njit(inline="always", **_OPTS)
def _at(flat, width, col, row):
    """``(S, ∂S/∂col, ∂S/∂row)`` of the spline at coefficient-array coordinates ``col, row``
    (the first coefficient's centre at 0, 0)."""
    fi, fj = math.floor(col), math.floor(row)
    return _taps(flat, (int(fj) - 1) * width + int(fi) - 1, width, col - fi, row - fj)


@njit(inline="always", **_OPTS)
def _taps(flat, o, width, x, y):
    """``(S, ∂S/∂col, ∂S/∂row)`` from the 4 × 4 coefficients whose first is ``flat[o]``, at
    the fractions ``x, y`` (0–1) past the second's centre."""
    x2, y2 = x * x, y * y
    x3, y3 = x2 * x, y2 * y
    wx0, wx1 = (1 - 3 * x + 3 * x2 - x3) / 6, (4 - 6 * x2 + 3 * x3) / 6
    wx2, wx3 = (1 + 3 * x + 3 * x2 - 3 * x3) / 6, x3 / 6
    dx0, dx1 = (-3 + 6 * x - 3 * x2) / 6, (-12 * x + 9 * x2) / 6
    dx2, dx3 = (3 + 6 * x - 9 * x2) / 6, x2 / 2
    wy0, wy1 = (1 - 3 * y + 3 * y2 - y3) / 6, (4 - 6 * y2 + 3 * y3) / 6
    wy2, wy3 = (1 + 3 * y + 3 * y2 - 3 * y3) / 6, y3 / 6
    dy0, dy1 = (-3 + 6 * y - 3 * y2) / 6, (-12 * y + 9 * y2) / 6
    dy2, dy3 = (3 + 6 * y - 9 * y2) / 6, y2 / 2
    s = sx = sy = 0.0
    for m in range(4):
        wy = wy0 if m == 0 else wy1 if m == 1 else wy2 if m == 2 else wy3
        dy = dy0 if m == 0 else dy1 if m == 1 else dy2 if m == 2 else dy3
        c0, c1, c2, c3 = flat[o], flat[o + 1], flat[o + 2], flat[o + 3]
        v = wx0 * c0 + wx1 * c1 + wx2 * c2 + wx3 * c3
        s += wy * v
        sx += wy * (dx0 * c0 + dx1 * c1 + dx2 * c2 + dx3 * c3)
        sy += dy * v
        o += width
    return s, sx, sy


@njit(**_OPTS)
def sample_points(flat, width, c0, r0, lo, hi, x, y, S, Sx, Sy):
    """The spline and its gradient at image points ``x, y`` ``(n,)`` into ``S, Sx, Sy``
    ``(n,)``; NaN at a point outside ``lo``–``hi`` (image px, x then y: where the spline's
    support stays inside)."""
    for p in range(x.size):
        if lo[0] <= x[p] <= hi[0] and lo[1] <= y[p] <= hi[1]:
            S[p], Sx[p], Sy[p] = _at(flat, width, x[p] - 0.5 - c0, y[p] - 0.5 - r0)
        else:
            S[p] = Sx[p] = Sy[p] = np.nan


@njit(**_OPTS)
def sample_patch(flat, width, c0, r0, lo, hi, t, A, c, d, u, v, Q, bend, S, Sx, Sy):
    """The spline and its gradient at a patch's pixels ``q = t + A·(u, v) [+ d·(c @ Q)]``
    (``u, v`` ``(n,)`` template offsets, ``Q`` ``(3, n)`` bend terms, used when ``bend``) into
    ``S, Sx, Sy``; False (what was written meaningless) when a pixel falls outside
    ``lo``–``hi`` (image px, x then y: where the spline's support stays inside)."""
    a00, a01, a10, a11 = A[0, 0], A[0, 1], A[1, 0], A[1, 1]
    n = u.size
    fx, fy, off = np.empty(n), np.empty(n), np.empty(n, np.int64)
    inside = True
    # two passes: the positions without a branch out of the loop (one the compiler
    # vectorises), then the taps: 1.7 times as fast as one pass
    for p in range(n):
        qx = t[0] + a00 * u[p] + a01 * v[p]
        qy = t[1] + a10 * u[p] + a11 * v[p]
        if bend:
            b = c[0] * Q[0, p] + c[1] * Q[1, p] + c[2] * Q[2, p]
            qx += d[0] * b
            qy += d[1] * b
        inside &= (lo[0] <= qx) & (qx <= hi[0]) & (lo[1] <= qy) & (qy <= hi[1])    # NaN is outside
        col, row = qx - 0.5 - c0, qy - 0.5 - r0
        fi, fj = math.floor(col), math.floor(row)
        fx[p], fy[p] = col - fi, row - fj
        off[p] = (np.int64(fj) - 1) * width + np.int64(fi) - 1
    if not inside:
        return False
    for p in range(n):
        S[p], Sx[p], Sy[p] = _taps(flat, off[p], width, fx[p], fy[p])
    return True


@njit(**_OPTS)
def design_rows(S, Sx, Sy, T, Tu, Tv, u, v, Q, d, g0, g1, E, esm, bend, J, r, sw):
    """The design ``∂(g0 + g1·S(q))/∂(t, A, [c], g0, g1)`` into ``J`` ``(8 or 11, n)`` and the
    residuals ``T − (g0 + g1·S)`` into ``r`` ``(n,)``, from the patch's values and gradients
    ``S, Sx, Sy``, each pixel's row and residual times ``sw`` ``(n,)`` (the square roots of
    its weight: ``JJᵀ`` and ``Jr`` are then the weighted normal equations; empty: 1). With
    ``esm`` the gradient is the mean of the search image's and the template's (``Tu, Tv``)
    carried into the search image by ``E`` = A⁻ᵀ."""
    k = J.shape[0]
    weighted = sw.size > 0
    for p in range(S.size):
        s = sw[p] if weighted else 1.0
        a, b = g1 * Sx[p], g1 * Sy[p]
        if esm:
            a = 0.5 * (a + E[0, 0] * Tu[p] + E[0, 1] * Tv[p])
            b = 0.5 * (b + E[1, 0] * Tu[p] + E[1, 1] * Tv[p])
        a, b = a * s, b * s
        J[0, p] = a
        J[1, p] = b
        J[2, p] = a * u[p]
        J[3, p] = a * v[p]
        J[4, p] = b * u[p]
        J[5, p] = b * v[p]
        if bend:
            g = a * d[0] + b * d[1]
            J[6, p] = g * Q[0, p]
            J[7, p] = g * Q[1, p]
            J[8, p] = g * Q[2, p]
        J[k - 2, p] = s
        J[k - 1, p] = S[p] * s
        r[p] = (T[p] - (g0 + g1 * S[p])) * s


@njit(**_OPTS)
def normals(J, r, N, b):
    """The normal equations of the design ``J`` ``(k, n)`` and residuals ``r`` ``(n,)``:
    ``J·Jᵀ`` into ``N`` ``(k, k)`` and ``J·r`` into ``b`` ``(k,)``. Three rows against each
    row at a time, in one pass over the pixels: 1.4–2.7 times as fast as BLAS's product for
    these 8 or 11 rows (its kernels are made for larger matrices)."""
    k, n = J.shape
    for i in range(0, k, 3):
        i1, i2 = min(i + 1, k - 1), min(i + 2, k - 1)
        for j in range(i, k + 1):
            y = r if j == k else J[j]
            s0 = s1 = s2 = 0.0
            for p in range(n):
                x = y[p]
                s0 += J[i, p] * x
                s1 += J[i1, p] * x
                s2 += J[i2, p] * x
            for q, s in ((i, s0), (i1, s1), (i2, s2)):
                if j == k:
                    b[q] = s
                elif q <= j:
                    N[q, j] = s
                    N[j, q] = s


@njit(**_OPTS)
def solve_small(N, b, x):
    """``N x = b`` for a small square ``N`` (copied, not written) by Gaussian elimination with
    partial pivoting (LAPACK's ``gesv``): False when a pivot is exactly 0 (singular)."""
    k = b.size
    M = N.copy()
    y = b.copy()
    for c in range(k):
        piv, big = c, abs(M[c, c])
        for i in range(c + 1, k):
            if abs(M[i, c]) > big:
                piv, big = i, abs(M[i, c])
        if big == 0.0:
            return False
        if piv != c:
            for j in range(k):
                M[c, j], M[piv, j] = M[piv, j], M[c, j]
            y[c], y[piv] = y[piv], y[c]
        for i in range(c + 1, k):
            f = M[i, c] / M[c, c]
            for j in range(c, k):
                M[i, j] -= f * M[c, j]
            y[i] -= f * y[c]
    for i in range(k - 1, -1, -1):
        acc = y[i]
        for j in range(i + 1, k):
            acc -= M[i, j] * x[j]
        x[i] = acc / M[i, i]
    return True


@njit(**_OPTS)
def _correlation(a, b):
    """Correlation coefficient of ``a`` and ``b`` ``(n,)``."""
    ma, mb = a.mean(), b.mean()
    sab = saa = sbb = 0.0
    for p in range(a.size):
        x, y = a[p] - ma, b[p] - mb
        sab += x * y
        saa += x * x
        sbb += y * y
    return sab / math.sqrt(saa * sbb)


@njit(**_OPTS)
def gauss_newton(flat, width, c0, r0, lo, hi, T, Tu, Tv, u, v, Q, d, sw, t, A, c, g, bend, have, S, Sx, Sy,
                 max_iter, t0, max_move, A0inv, max_shape_change, need_rho, rival_iter, rival_margin, tol,
                 reach, shape_free, wander_iter, max_bend, half):
    """The Gauss–Newton iterations of :meth:`~prismstation.core.matching.lsm_fit.Fit.run` (which
    documents them), the design's gradient the mean of both images' (ESM). ``t`` ``(2,)``, ``A``
    ``(2, 2)``, ``c`` ``(3,)`` and ``g`` = ``(g0, g1)`` (``g1`` NaN: not yet set) are updated in
    place; ``S, Sx, Sy`` ``(n,)`` hold the search image sampled at the start when ``have`` and
    the last sample at the end (converged: carried to first order by the last step).
    ``need_rho`` NaN: no rival. Returns ``(code, iterations, value)``: code 0 converged, 1
    outside, 2 low correlation (value: the correlation), 3 singular, 4 moved, 5 contrast inverted, 6 shape
    degenerated (value: the change), 7 not converged."""
    k = 11 if bend else 8
    nb = 3 if bend else 0
    J, r = np.empty((k, S.size)), np.empty(S.size)
    N, b, dp = np.empty((k, k)), np.empty(k), np.empty(k)
    E = np.empty((2, 2))
    it = 0
    for it in range(1, max_iter + 1):
        if not have:
            curved = c[0] != 0.0 or c[1] != 0.0 or c[2] != 0.0
            if not sample_patch(flat, width, c0, r0, lo, hi, t, A, c, d, u, v, Q, curved, S, Sx, Sy):
                return 1, it, 0.0
        have = False
        if not math.isnan(need_rho) and it >= rival_iter:
            rho = _correlation(T, S)
            if rho < need_rho - rival_margin:
                return 2, it, rho
        if math.isnan(g[1]):
            g[1] = T.std() / max(S.std(), 1e-12)
            g[0] = T.mean() - g[1] * S.mean()
        det = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
        E[0, 0], E[0, 1], E[1, 0], E[1, 1] = A[1, 1] / det, -A[1, 0] / det, -A[0, 1] / det, A[0, 0] / det
        design_rows(S, Sx, Sy, T, Tu, Tv, u, v, Q, d, g[0], g[1], E, True, bend, J, r, sw)
        normals(J, r, N, b)
        if not solve_small(N, b, dp):
            return 3, it, 0.0
        t[0] += dp[0]
        t[1] += dp[1]
        A[0, 0] += dp[2]
        A[0, 1] += dp[3]
        A[1, 0] += dp[4]
        A[1, 1] += dp[5]
        if bend:
            c[0] += dp[6]
            c[1] += dp[7]
            c[2] += dp[8]
        g[0] += dp[6 + nb]
        g[1] += dp[7 + nb]
        if math.hypot(t[0] - t0[0], t[1] - t0[1]) > max_move:
            return 4, it, 0.0
        change = 0.0
        for i in range(2):
            for j in range(2):
                e = A0inv[i, 0] * A[0, j] + A0inv[i, 1] * A[1, j] - (1.0 if i == j else 0.0)
                change += e * e
        change = math.sqrt(change)
        bent = bend and max(abs(c[0]), abs(c[1]), abs(c[2])) * half > 2 * max_bend
        if g[1] <= 0:
            return 5, it, change
        if change > 2 * max_shape_change or bent:
            return 6, it, change
        shape_step = 0.0
        for i in range(2, 6 + nb):
            shape_step = max(shape_step, abs(dp[i]))
        if max(abs(dp[0]), abs(dp[1])) < tol and (shape_free or shape_step * reach < 2.5 * tol):
            # converged: the last step (under the tolerance) carries the sample to first order
            # — S + ∇S·δq, the gradients kept — rather than sampling again
            for p in range(S.size):
                dqx = dp[2] * u[p] + dp[3] * v[p] + dp[0]
                dqy = dp[4] * u[p] + dp[5] * v[p] + dp[1]
                if bend:
                    q = dp[6] * Q[0, p] + dp[7] * Q[1, p] + dp[8] * Q[2, p]
                    dqx += d[0] * q
                    dqy += d[1] * q
                S[p] += Sx[p] * dqx + Sy[p] * dqy
            return 0, it, 0.0
        if it >= wander_iter and math.hypot(dp[0], dp[1]) > 0.1:
            break   # still wandering
    return 7, it, 0.0


@njit(**_OPTS)
def block_moments(G, r, O, lo, m, b, out):
    """Sums over the ``m × m`` blocks of ``b × b`` pixels of the ``(n, n)`` grids from row and
    column ``lo`` on, into ``out`` ``(3 or 6, m²)``: ``G², G·r, r²`` and, where ``O`` is not
    empty, ``O², G·O, O·r``."""
    other = O.size > 0
    for bi in range(m):
        for bj in range(m):
            s0 = s1 = s2 = s3 = s4 = s5 = 0.0
            for i in range(lo + bi * b, lo + bi * b + b):
                for j in range(lo + bj * b, lo + bj * b + b):
                    g, e = G[i, j], r[i, j]
                    s0 += g * g
                    s1 += g * e
                    s2 += e * e
                    if other:
                        o = O[i, j]
                        s3 += o * o
                        s4 += g * o
                        s5 += o * e
            k = bi * m + bj
            out[0, k], out[1, k], out[2, k] = s0, s1, s2
            if other:
                out[3, k], out[4, k], out[5, k] = s3, s4, s5


@njit(**_OPTS)
def edge_sums(J, ax, ay, b, cx, cy):
    """Sums over blocks of ``b × b`` pixels (the last ones partial, ``mb = ⌈n/b⌉`` a side) of
    the design rows ``J`` ``(n, n, k)`` times ``ax`` and times ``ay`` ``(n, n)``, into ``cx``,
    ``cy`` ``(mb², k)``."""
    n, k = J.shape[0], J.shape[2]
    mb = (n + b - 1) // b
    cx[:] = 0.0
    cy[:] = 0.0
    for i in range(n):
        for j in range(n):
            B = (i // b) * mb + j // b
            a, c = ax[i, j], ay[i, j]
            for q in range(k):
                cx[B, q] += J[i, j, q] * a
                cy[B, q] += J[i, j, q] * c


@njit(**_OPTS)
def _prefilter_rows(c, z, gain):
    """Each column of ``c`` ``(n, m)`` replaced in place by its cubic B-spline
    coefficients along the rows, the signal mirrored at both ends: scipy's
    ``spline_filter1d(..., axis=0, mode="mirror")`` (its gain, causal and anticausal passes and
    their mirrored starts, in its order), the inner loops running along a row."""
    n, m = c.shape
    if n < 2:
        return
    for i in range(n):
        for j in range(m):
            c[i, j] *= gain
    zn = z ** (n - 1)
    first = c[0] + zn * c[n - 1]
    zi = z
    for i in range(1, n - 1):
        for j in range(m):
            first[j] += zi * (c[i, j] + zn * c[n - 1 - i, j])
        zi *= z
    for j in range(m):
        c[0, j] = first[j] / (1 - zn * zn)
    for i in range(1, n):
        for j in range(m):
            c[i, j] += z * c[i - 1, j]
    for j in range(m):
        c[n - 1, j] = (z * c[n - 2, j] + c[n - 1, j]) * z / (z * z - 1)
    for i in range(n - 2, -1, -1):
        for j in range(m):
            c[i, j] = z * (c[i + 1, j] - c[i, j])


@njit(**_OPTS)
def spline_coefficients(img):
    """The cubic B-spline coefficients ``(rows, cols)`` (float64) of ``img``, the image mirrored at its edges: scipy's ``ndimage.spline_filter(img, 3,
    mode="mirror")`` to rounding, four times as fast (a side of 1 is left as it is, as there)."""
    z = math.sqrt(3.0) - 2.0
    gain = (1.0 - z) * (1.0 - 1.0 / z)
    c = img.astype(np.float64)
    _prefilter_rows(c, z, gain)
    t = np.ascontiguousarray(c.T)
    _prefilter_rows(t, z, gain)
    return np.ascontiguousarray(t.T)


@njit(**_OPTS)
def crossing_sigma(a, v, ratio_tab, px_tab, out):
    """:func:`~prismstation.core.matching.lsm_sigma.sampling_px` along the rows of ``a``
    ``(rows, cols)`` into ``out`` (same shape): for each crossing ``k`` (between columns ``k``
    and ``k + 1``, two from either end) whose squared difference exceeds ``4v``, the table's σ
    (``px_tab`` at ``ratio_tab``, linear between, 0 beyond) of the ratio of its four
    neighbours' squared differences less ``4v`` (at least 0) to its own less ``v``; each
    pixel the largest σ of the crossings ``k`` with it among ``k − 1 … k + 2``."""
    rows, cols = a.shape
    out[:] = 0.0
    last = ratio_tab.size - 1
    for i in range(rows):
        for k in range(2, cols - 3):
            d0 = (a[i, k + 1] - a[i, k]) ** 2
            if not d0 > 4 * v:
                continue
            side = ((a[i, k - 1] - a[i, k - 2]) ** 2 + (a[i, k] - a[i, k - 1]) ** 2
                    + (a[i, k + 2] - a[i, k + 1]) ** 2 + (a[i, k + 3] - a[i, k + 2]) ** 2 - 4 * v)
            ratio = max(side, 0.0) / max(d0 - v, 1e-12)
            if ratio > ratio_tab[last]:
                continue                                 # beyond the table: 0
            j = 0
            while j < last - 1 and ratio >= ratio_tab[j + 1]:
                j += 1
            if ratio == ratio_tab[last]:
                e = px_tab[last]
            else:
                slope = (px_tab[j + 1] - px_tab[j]) / (ratio_tab[j + 1] - ratio_tab[j])
                e = slope * (ratio - ratio_tab[j]) + px_tab[j]
            for c in range(k - 1, k + 3):
                if e > out[i, c]:
                    out[i, c] = e


def spline_points(flat, width: int, c0: int, r0: int, lo, hi, x, y):
    """``(S, Sx, Sy)`` (float64, ``(n,)``) of the spline at image points ``x, y`` (NaN outside
    ``lo``–``hi``)."""
    x, y = np.ascontiguousarray(x, np.float64).ravel(), np.ascontiguousarray(y, np.float64).ravel()
    S, Sx, Sy = np.empty(x.size), np.empty(x.size), np.empty(x.size)
    sample_points(flat, width, c0, r0, (float(lo[0]), float(lo[1])), (float(hi[0]), float(hi[1])), x, y, S, Sx, Sy)
    return S, Sx, Sy


_READY = False


def compile_kernels() -> None:
    """Compile the loops for the argument types matching passes them (or load them from the disk
    cache): a few tenths of a second once per process, which the first match pays otherwise.
    Then every object alive (numba's types and dispatchers, about 50,000 of the process's
    160,000) is left out of the cycle collector's passes (``gc.freeze``, as the window does
    after each of its full collections): a full pass over them took 57 ms of CPU, at random
    moments of a run of transfers (a millisecond a point of the foreign scene's 50). Once per
    process; later calls return at once."""
    global _READY
    if _READY:
        return
    flat, u = np.zeros(64), np.zeros(1)
    Q, J, out = np.zeros((3, 1)), np.empty((8, 1)), [np.empty(1) for _ in range(4)]
    spline_points(flat, 8, 0, 0, (1.5, 1.5), (5.5, 5.5), np.array([3.0]), np.array([3.0]))
    sample_patch(flat, 8, 0, 0, (1.5, 1.5), (5.5, 5.5), np.full(2, 3.0), np.eye(2), np.zeros(3), np.zeros(2),
                 u, u, Q, False, *out[:3])
    design_rows(*out[:3], u, u, u, u, u, Q, np.zeros(2), 0.0, 1.0, np.eye(2), True, False, J, out[3], u[:0])
    normals(J, out[3], np.empty((8, 8)), np.empty(8))
    gauss_newton(flat, 8, 0, 0, (1.5, 1.5), (5.5, 5.5), u, u, u, u, u, Q, np.zeros(2), u[:0],
                 np.full(2, 3.0), np.eye(2), np.zeros(3), np.array([0.0, np.nan]), False, False, *out[:3], 1,
                 np.full(2, 3.0), 3.0, np.eye(2), 0.25, np.nan, 3, 0.1, 0.01, 12, False, 6, 1.0, 12)
    solve_small(np.eye(2), np.ones(2), np.empty(2))
    g = np.zeros((8, 8))
    spline_coefficients(g)
    crossing_sigma(g, 1.0, np.arange(3.0), np.zeros(3), np.empty((8, 8)))
    block_moments(g, g, g, 0, 2, 4, np.empty((6, 4)))
    block_moments(g, g, np.empty((0, 0)), 0, 2, 4, np.empty((3, 4)))
    edge_sums(np.zeros((8, 8, 2)), g, g, 8, np.empty((1, 2)), np.empty((1, 2)))
    gc.freeze()
    _READY = True
