"""The Gauss–Newton state of one least-squares patch (:mod:`prismstation.core.matching.lsm`):
position, affine shape, bend along the parallax, offset and gain on a fixed template and
search spline; its iterations and what they stop on.

Coordinates as in :mod:`prismstation.core.matching.lsm` (docs/model.md §1).
"""
from __future__ import annotations

import math

import numpy as np

from prismstation.core.lazy_cv2 import lazy_module

kernel = lazy_module("prismstation.core.matching.lsm_kernel")  # numba at first use: start-up saving

OK = "ok"
NOT_CONVERGED, TEXTURE, SHAPE, MOVED, LOW_CORRELATION, OUTSIDE = (
    "not_converged", "texture", "shape", "moved", "low_correlation", "outside")

STEP_TOL = 1e-2
"""Converged when the position moves less than this (px) in an iteration, and the shape less
than 2.5 times this at :data:`SHAPE_REACH` px from the point."""
SHAPE_REACH = 12
"""Where the shape's step is measured (px from the point, at most the template's half size):
the 25 × 25 px every template holds. At a large template's edge a shape still creeping by
0.001 (0.03 px at 32 px) kept it iterating on aliased texture while the position had stopped."""
WANDER_ITER = 6
"""Iterations after which a patch still moving by 0.1 px per step is given up."""
MAX_BEND = 1.0
"""Largest bend (px) of the patch at the template's edge."""
RIVAL_ITER = 3
RIVAL_MARGIN = 0.1
"""A patch that must reach a correlation (``need_rho`` of :func:`~prismstation.core.matching.lsm.refine`: a rival peak) is given
up when, after :data:`RIVAL_ITER` iterations, its correlation lies more than this below it (on
the tuning scenes and the Pléiades triplet the correlation rose by at most 0.06 after the third
iteration)."""

_I2 = np.eye(2)
_NONE = np.empty(0)


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


class Fit:
    """The Gauss–Newton state of one patch: position ``t``, shape ``A``, bend ``c`` (3 or 0
    terms), offset ``g0`` and gain ``g1``, on a fixed template and search spline. ``grads``:
    the template's gradients ``(gu, gv)`` along x and y (``np.gradient``'s, grey values per px;
    shared, never written), computed here when None."""

    def __init__(self, T, u, v, spline, d, half, w=None, grads=None):
        self.T, self.u, self.v, self.spline, self.d, self.half = T.ravel(), u.ravel(), v.ravel(), spline, d, half
        self.uv = np.vstack([self.u, self.v])                  # (2, n) template offsets
        self.w = None if w is None else np.asarray(w, float).ravel()     # None: uniform
        self.pw = None                                     # the pixels' weights (aliasing), None: uniform
        self.keep = None                                   # the pixels iterated on (:meth:`subset`), None: all
        gu, gv = grads if grads is not None else np.gradient(T)[::-1]    # template gradients (grey values per px)
        self.Tu, self.Tv = gu.ravel(), gv.ravel()
        self.Q = np.vstack([self.u ** 2, self.u * self.v, self.v ** 2]) / half    # (3, n) bend terms
        self.c = np.zeros(3)
        self.g0, self.g1 = 0.0, None
        self.smp = None         # the search image sampled at the current t, A, c (None: not yet)

    def sample(self):
        """``(S, Sx, Sy)`` at the patch's pixels for the current ``t, A, c`` (None: outside)."""
        if self.smp is None:
            self.smp = self._sample()
        return self.smp

    def _sample(self):
        n = self.T.size
        S, Sx, Sy = np.empty(n), np.empty(n), np.empty(n)
        sp = self.spline
        if not kernel.sample_patch(sp.flat, sp.width, sp.c0, sp.r0, sp.lo, sp.hi, self.t, self.A, self.c, self.d,
                                   self.u, self.v, self.Q, bool(self.c.any()), S, Sx, Sy):
            return None
        return S, Sx, Sy

    def design(self, S, Sx, Sy, bend: bool, esm: bool, sw=None):
        """``(r, J)``: the residuals ``T − (g0 + g1·S)`` ``(n,)`` and the design
        ``∂(g0 + g1·S(q))/∂(t, A, [c], g0, g1)`` ``(8 or 11, n)``; with ``esm`` the gradient is
        the mean of the search image's and the template's carried into the search image
        (Benhimane and Malis 2004: faster convergence); without, the search image's alone (the
        covariance). ``sw`` ``(n,)``: each pixel's row and residual times it (None: 1)."""
        J, r = np.empty((11 if bend else 8, S.size)), np.empty(S.size)
        a, b, c, d = self.A.ravel()
        E = np.array([[d, -c], [-b, a]]) / (a * d - b * c) if esm else _I2      # A⁻ᵀ
        kernel.design_rows(S, Sx, Sy, self.T, self.Tu, self.Tv, self.u, self.v, self.Q, self.d, self.g0, self.g1,
                           E, esm, bend, J, r, _NONE if sw is None else sw)
        return r, J

    def run(self, bend: bool, max_iter: int, t0, max_move: float, A0inv, max_shape_change: float,
            need_rho: float | None = None, tol: float = STEP_TOL):
        """Iterate to convergence: ``(status, reason, iterations)``, status ``OK`` or a failure;
        ``need_rho``: give up as :data:`RIVAL_ITER` and :data:`RIVAL_MARGIN` say; ``tol``: the
        position's step (px) counted as converged, the shape's 2.5 times it at
        :data:`SHAPE_REACH` px."""
        nb = 3 if bend else 0
        wt = self.weights()
        sw = _NONE if wt is None else np.sqrt(wt)
        for it in range(1, max_iter + 1):
            smp = self.sample()
            if smp is None:
                return OUTSIDE, "patch left the search image", it
            S, Sx, Sy = smp
            if need_rho is not None and it >= RIVAL_ITER:
                rho = correlation(self.T, S)
                if rho < need_rho - RIVAL_MARGIN:
                    return LOW_CORRELATION, f"correlation {rho:.2f} after {it - 1} iterations: no rival", it
            if self.g1 is None:
                self.g1 = self.T.std() / max(S.std(), 1e-12)
                self.g0 = self.T.mean() - self.g1 * S.mean()
            r, J = self.design(S, Sx, Sy, bend, esm=True, sw=sw)       # rows and residuals × √weight
            k = J.shape[0]
            N, b, dp = np.empty((k, k)), np.empty(k), np.empty(k)
            kernel.normals(J, r, N, b)
            if not kernel.solve_small(N, b, dp):
                return TEXTURE, "singular normal matrix (no texture)", it
            self.smp = None
            self.t += dp[0:2]
            self.A += dp[2:6].reshape(2, 2)
            if bend:
                self.c += dp[6:9]
            self.g0 += dp[6 + nb]
            self.g1 += dp[7 + nb]
            if math.hypot(self.t[0] - t0[0], self.t[1] - t0[1]) > max_move:
                return MOVED, f"the patch moved more than {max_move:g} px from its start", it
            change = math.sqrt(float(np.square(A0inv @ self.A - _I2).sum()))   # ≥ the largest singular value
            bent = bend and np.abs(self.c).max() * self.half > 2 * MAX_BEND
            if change > 2 * max_shape_change or self.g1 <= 0 or bent:
                return SHAPE, ("the patch's contrast inverted" if self.g1 <= 0 else
                               f"the shape degenerated (changed by {change:.0%})"), it
            shape_still = (self.w is not None
                           or np.abs(dp[2:6 + nb]).max() * min(self.half, SHAPE_REACH) < 2.5 * tol)
            if max(abs(dp[0]), abs(dp[1])) < tol and shape_still:
                # converged: the last step (under the tolerance) carries the sample to first
                # order — S + ∇S·δq, the gradients kept — for the covariance and a bend started
                # from here, rather than sampling again
                dq = dp[2:6].reshape(2, 2) @ self.uv + dp[0:2, None]
                if bend:
                    dq += np.outer(self.d, dp[6:9] @ self.Q)
                self.smp = (S + Sx * dq[0] + Sy * dq[1], Sx, Sy)
                return OK, "", it
            step = math.hypot(dp[0], dp[1])
            if it >= WANDER_ITER and step > 0.1:
                break   # still wandering
        return NOT_CONVERGED, f"no convergence in {it} iterations", it

    def weights(self):
        """The pixels' weights in the fit: the taper's times the aliasing's (None: uniform)."""
        if self.w is None:
            return self.pw
        return self.w if self.pw is None else self.w * self.pw

    def copy(self):
        other = object.__new__(Fit)
        other.__dict__.update(self.__dict__)
        other.t, other.A, other.c = self.t.copy(), self.A.copy(), self.c.copy()
        return other

    def subset(self, keep):
        """A copy iterating on the pixels ``keep`` (boolean, ``(n²,)``) only: the pixels whose
        weight is negligible cost iterations and move nothing."""
        other = self.copy()
        other.smp = None
        idx = np.flatnonzero(keep)       # one pass over the mask: integer takes are cheaper
        for name in ("T", "u", "v", "Tu", "Tv", "w", "pw"):
            a = getattr(self, name)
            if a is not None:
                setattr(other, name, a.take(idx))
        other.uv, other.Q = self.uv.take(idx, axis=1), self.Q.take(idx, axis=1)
        return other

    def take(self, other):
        """Adopt ``other``'s parameters (a :meth:`subset`'s after its iterations)."""
        self.t, self.A, self.c, self.g0, self.g1 = other.t, other.A, other.c, other.g0, other.g1
        self.smp = None

    def final(self, bend: bool):
        """``(r, J, rho)`` at the current state: residuals, design (search-image gradients),
        correlation of template and patch."""
        smp = self.sample()
        if smp is None:
            return None, None, np.nan
        S, Sx, Sy = smp
        r, J = self.design(S, Sx, Sy, bend, esm=False)
        return r, J.T, correlation(self.T, S)


def correlation(a, b) -> float:
    """Correlation coefficient of the arrays ``a`` and ``b`` (same size)."""
    a, b = a - a.mean(), np.ravel(b) - b.mean()
    return float(a @ b / np.sqrt((a @ a) * (b @ b)))
