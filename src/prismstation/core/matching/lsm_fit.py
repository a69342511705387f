"""The Gauss–Newton state of one least-squares patch (:mod:`prismstation.core.matching.lsm`):
position, affine shape, bend along the parallax, offset and gain on a fixed template and
search spline; its iterations and what they stop on; how far its shape may move
(:func:`shape_check`).

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
"""Largest bend (px) of the patch at the edge of a 25 px template (:data:`BEND_HALF`): a
curvature of the terrain, 5 m off the plane 30 m from the point at 0.2 px of parallax per
metre (a ridge of 90 m radius); a larger template's edge allows the same curvature
(:func:`max_bend`)."""
BEND_HALF = 12
"""Half size (px) of the template whose edge :data:`MAX_BEND` is measured at."""
RIVAL_ITER = 3
RIVAL_MARGIN = 0.1
"""A patch that must reach a correlation (``need_rho`` of :func:`~prismstation.core.matching.lsm.refine`: a rival peak) is given
up when, after :data:`RIVAL_ITER` iterations, its correlation lies more than this below it (on
the tuning scenes and the Pléiades triplet the correlation rose by at most 0.06 after the third
iteration)."""

MAX_ACROSS_CHANGE = 0.06
"""Largest change of the shape across the parallax (relief changes it along the parallax; the
model's views are right to 10⁻³ across)."""

_I2 = np.eye(2)
_NONE = np.empty(0)
_STATUS = (
    lambda it, v, mm: (OK, "", it),
    lambda it, v, mm: (OUTSIDE, "patch left the search image", it),
    lambda it, v, mm: (LOW_CORRELATION, f"correlation {v:.2f} after {it - 1} iterations: no rival", it),
    lambda it, v, mm: (TEXTURE, "singular normal matrix (no texture)", it),
    lambda it, v, mm: (MOVED, f"the patch moved more than {mm:g} px from its start", it),
    lambda it, v, mm: (SHAPE, "the patch's contrast inverted", it),
    lambda it, v, mm: (SHAPE, f"the shape degenerated (changed by {v:.0%})", it),
    lambda it, v, mm: (NOT_CONVERGED, f"no convergence in {it} iterations", it),
)
"""What :meth:`Fit.run` returns for each code of ``lsm_kernel.gauss_newton``: ``(status,
reason, iterations)`` from the iterations, the code's value and the largest move."""


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

    def run(self, bend: bool, max_iter: int, t0, max_move: float, A0inv, max_shape_change: float,
            need_rho: float | None = None, tol: float = STEP_TOL):
        """Iterate to convergence: ``(status, reason, iterations)``, status ``OK`` or a failure.

        Each iteration samples the search image at the patch, solves the normal equations of
        the residuals' design (the gradient the mean of both images', carried into the search
        image: Benhimane and Malis 2004, faster convergence) and steps. It stops: converged when
        the position moved less than ``tol`` (px) and the shape less than 2.5 times it at
        :data:`SHAPE_REACH` px (the last step then carries the sample to first order — the
        covariance and a bend started from here use it); ``moved`` beyond ``max_move`` px from
        ``t0``; ``shape`` when the shape changed by more than twice ``max_shape_change``, bent
        past twice :func:`max_bend` or inverted the contrast; still moving 0.1 px a step after
        :data:`WANDER_ITER`; with ``need_rho``, as :data:`RIVAL_ITER` and :data:`RIVAL_MARGIN`
        say. The loop is compiled (``lsm_kernel.gauss_newton``)."""
        wt = self.weights()
        n = self.T.size
        S, Sx, Sy = np.empty(n), np.empty(n), np.empty(n)
        have = self.smp is not None
        if have:
            S[:], Sx[:], Sy[:] = self.smp
        g = np.array([self.g0, np.nan if self.g1 is None else self.g1])
        sp = self.spline
        code, it, value = kernel.gauss_newton(
            sp.flat, sp.width, sp.c0, sp.r0, sp.lo, sp.hi, self.T, self.Tu, self.Tv, self.u, self.v, self.Q,
            self.d, _NONE if wt is None else np.sqrt(wt), self.t, self.A, self.c, g, bend, have, S, Sx, Sy,
            int(max_iter), np.asarray(t0, float), float(max_move), A0inv, float(max_shape_change),
            np.nan if need_rho is None else float(need_rho), RIVAL_ITER, RIVAL_MARGIN, float(tol),
            min(self.half, SHAPE_REACH), self.w is not None, WANDER_ITER, max_bend(self.half), self.half)
        if not math.isnan(g[1]):
            self.g0, self.g1 = float(g[0]), float(g[1])
        # the sample at the state reached: kept where it is that (converged: carried there)
        self.smp = (S, Sx, Sy) if code in (0, 2, 3) else None
        return _STATUS[code](it, value, max_move)

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
        """``(r, J, rho)`` at the current state: the residuals ``T − (g0 + g1·S)`` ``(n,)``, the
        design ``∂(g0 + g1·S(q))/∂(t, A, [c], g0, g1)`` ``(n, 8 or 11)`` on the search image's
        gradients alone (the covariance's), the correlation of template and patch."""
        smp = self.sample()
        if smp is None:
            return None, None, np.nan
        S, Sx, Sy = smp
        J, r = np.empty((11 if bend else 8, S.size)), np.empty(S.size)
        kernel.design_rows(S, Sx, Sy, self.T, self.Tu, self.Tv, self.u, self.v, self.Q, self.d, self.g0, self.g1,
                           _I2, False, bend, J, r, _NONE)
        return r, J.T, correlation(self.T, S)


def correlation(a, b) -> float:
    """Correlation coefficient of the arrays ``a`` and ``b`` (same size)."""
    a, b = a - a.mean(), np.ravel(b) - b.mean()
    return float(a @ b / np.sqrt((a @ a) * (b @ b)))


def max_bend(half: int) -> float:
    """Largest bend (px) at the edge of a template of half size ``half``: :data:`MAX_BEND`
    times ``(half / BEND_HALF)²`` (the bend grows as the square of the distance)."""
    return MAX_BEND * (half / BEND_HALF) ** 2


def shape_check(A0, A, parallax, max_change: float, max_across: float = MAX_ACROSS_CHANGE) -> str:
    """Why the shape ``A`` is too far from ``A0`` ("" when it is not): its change
    (largest singular value of ``A0⁻¹A − I``) beyond ``max_change``, or — given the parallax
    direction — its change across the parallax beyond ``max_across`` (relief moves points
    along the parallax only: a slope changes the row of ``A`` along it, nothing across)."""
    change = float(np.linalg.svd(np.linalg.solve(A0, A) - _I2, compute_uv=False)[0])
    if change > max_change:
        return f"the shape changed by {change:.0%} (more than {max_change:.0%})"
    if parallax is not None:
        d = np.asarray(parallax, float) / np.hypot(*parallax)
        across = float(np.hypot(*(np.array([-d[1], d[0]]) @ (A - A0))))
        if across > max_across:
            return f"the shape changed by {across:.0%} across the parallax (more than {max_across:.0%})"
    return ""
