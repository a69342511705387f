"""Where image rays meet a height surface (a reference DEM): one iteration for every caller,
with a convergence test.

A ray is given by ``ground_at(h)``: the map point ``(E, N)`` where it passes height ``h`` (one
per ray, ``(n,)`` → ``(n, 2)`` metres; for a view at off-nadir angle θ the point moves by
``tan θ`` metres per metre of height). The surface is ``surface(en)``: ``(n, 2)`` → ``(n,)``
heights, NaN where it has none. Both heights of the same kind (ellipsoidal, as the model's).

The ray meets the surface where ``f(h) = surface(ground_at(h)) − h = 0``. The fixed point
``h ← surface(ground_at(h))`` contracts by the factor ``k = slope·tan θ`` per step: on gentle
ground (k ≈ 0.05) three steps are plenty, on a 45° slope seen by F or B (26° off nadir, k ≈ 0.5)
three steps leave an eighth of the starting error, and beyond k = 1 (slopes past ~64° at 26°)
it diverges. So each step is the fixed point while it contracts by at least half, else a
secant step on ``f``; a ray stops when ``|f(h)|`` is within ``tol_m``. A ray that has not
converged within ``max_iterations``, or leaves the surface (NaN), is reported, not returned
as a point: its ``en`` and ``h`` are NaN and ``converged`` is False (the failure convention
of :mod:`prismstation.core.adjustment.estimate`: the result is falsy when any ray failed, ``reason``
says why).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

#: a ray has met the surface when the surface lies within this many metres of its point
TOLERANCE_M = 0.01
#: steps allowed before a ray is reported as not converged
MAX_ITERATIONS = 30


@dataclass(frozen=True)
class RayHits:
    """Where ``n`` rays meet the surface: ``en`` (n, 2) map metres and ``h`` (n,) metres, NaN
    for a ray that did not converge; ``converged`` (n,) bool; ``iterations`` the steps taken
    by the slowest ray; ``reason`` why some did not converge ("" when all did)."""

    en: np.ndarray
    h: np.ndarray
    converged: np.ndarray
    iterations: int
    reason: str = ""

    def __bool__(self) -> bool:
        return bool(self.converged.all())


def ray_meets_surface(ground_at: Callable[[np.ndarray], np.ndarray],
                      surface: Callable[[np.ndarray], np.ndarray], h0, *,
                      tol_m: float = TOLERANCE_M, max_iterations: int = MAX_ITERATIONS) -> RayHits:
    """The points where the rays ``ground_at`` meet ``surface``, starting at heights ``h0``
    (scalar or (n,)); see the module docstring."""
    h = np.array(h0, float, ndmin=1)
    if h.size == 1:                    # one start for every ray
        h = np.full(len(np.asarray(ground_at(h), float).reshape(-1, 2)), h[0])
    n = h.size
    done = np.zeros(n, bool)
    lost = np.zeros(n, bool)
    h_prev = f_prev = None
    it = 0
    for it in range(1, max_iterations + 1):
        f = np.asarray(surface(ground_at(h)), float).reshape(n) - h
        lost |= ~np.isfinite(f) & ~done
        done |= np.abs(f) <= tol_m
        active = ~done & ~lost
        if not active.any():
            break
        step = np.where(active, f, 0.0)                      # the fixed point
        if f_prev is not None:
            slow = active & (np.abs(f) > 0.5 * np.abs(f_prev))
            denom = f - f_prev
            ok = slow & np.isfinite(f_prev) & (np.abs(denom) > 1e-12)
            step[ok] = -f[ok] * (h[ok] - h_prev[ok]) / denom[ok]   # the secant
        h_prev, f_prev = h.copy(), f
        h = h + step
    converged = done & ~lost
    en = np.asarray(ground_at(h), float).reshape(n, 2).copy()
    en[~converged] = np.nan
    h = np.where(converged, h, np.nan)
    reason = ""
    if lost.any():
        reason = f"{int(lost.sum())} of {n} rays left the surface (no height there)"
    if (~converged & ~lost).any():
        reason = "; ".join(filter(None, [reason, f"{int((~converged & ~lost).sum())} of {n} rays did not "
                                         f"meet the surface within {tol_m:g} m in {max_iterations} steps"]))
    return RayHits(en, h, converged, it, reason)
