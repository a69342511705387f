"""The patch-level steps of the shift-field adjustment (:mod:`prismstation.core.orientation.field_adjust`).

Each patch ``p`` enters through its sums at the current parameters (``N_p``, ``b_p`` for the
``u`` unknowns, ``I_p``, ``h_p`` for its own shift, ``B_p`` the cross terms; arrays over
patches, as :class:`prismstation.core.orientation.field_adjust.PatchSums` holds them). A patch's own shift
``b_p ~ N(0, Σ_b)`` beyond its cells' noise is eliminated per patch (Woodbury, valid for a
patch whose ``I_p`` is singular — a flat patch fixes only its height):

    N' = Σ_p N_p − B_pᵀ K_p B_p,   b' = Σ_p b_p − B_pᵀ K_p h_p,   K_p = (Σ_b I_p + 1)⁻¹ Σ_b.

``Σ_b`` (diagonal, m²) comes from the data: restricted maximum likelihood by EM
(:func:`variance_components`). Each patch is tested against the field of the others
(:func:`leave_one_out`): its own shift information ``z_p = −(h_p + B_p Δ₋ₚ)`` has covariance
``I_p + I_p Σ_b I_p + B_p C₋ₚ B_pᵀ`` under the model, so ``T_p = z_pᵀ Cov⁺ z_p`` is χ² with as
many degrees of freedom as the patch fixes directions (three on relief, one on a plane): a
weakly conditioned patch is not a blunder for what it cannot see. The leave-one-out solutions
are also the jackknife of the field's parameters.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

#: EM iterations at most, and the change of any σ_b (m) that ends them
EM_ITER, EM_TOL_M = 300, 1e-3


def gains(I: np.ndarray, sigma_b) -> np.ndarray:
    """``K_p = (Σ_b I_p + 1)⁻¹ Σ_b`` (P, 3, 3) for diagonal ``Σ_b`` (3,) (m²)."""
    S = np.diag(np.asarray(sigma_b, float))
    return np.linalg.solve(S @ I + np.eye(3), np.broadcast_to(S, I.shape))


def reduced(S, keep, sigma_b, Nx, bx):
    """``(N', b')`` of the kept patches (bool (P,)) plus the extra equations ``Nx, bx``."""
    K = gains(S.I[keep], sigma_b)
    KB = K @ S.B[keep]
    Nr = Nx + (S.N[keep] - np.einsum("pji,pjk->pik", S.B[keep], KB)).sum(0)
    br = bx + (S.b[keep] - np.einsum("pji,pj->pi", S.B[keep], np.einsum("pjk,pk->pj", K, S.h[keep]))).sum(0)
    return Nr, br


def solve(S, keep, sigma_b, Nx, bx):
    """The step ``Δ`` (u,) and the covariance ``C = N'⁻¹`` at ``Σ_b``."""
    Nr, br = reduced(S, keep, sigma_b, Nx, bx)
    C = np.linalg.inv(Nr)
    return -C @ br, C


def patch_shifts(S, keep, sigma_b, delta, C):
    """Each kept patch's own shift (BLUP) ``b̂_p`` (P, 3) and its conditional covariance
    ``V_p`` (P, 3, 3) given the data (REML: with the parameters' uncertainty)."""
    K = gains(S.I[keep], sigma_b)
    KB = K @ S.B[keep]
    b = -np.einsum("pij,pj->pi", K, S.h[keep] + np.einsum("pij,j->pi", S.B[keep], delta))
    V = K + KB @ C @ np.swapaxes(KB, 1, 2)
    return b, V


def variance_components(S, keep, Nx, bx, start=None) -> np.ndarray:
    """REML estimate of ``Σ_b`` (3,) (m²) over the kept patches: the fixed point of EM,
    ``σ² = Σ_p (b̂_p² + V_p) / n``, reached by its faster form ``σ² = Σ_p b̂_p² / Σ_p (1 −
    V_p / σ²)`` (the same fixed point), EM's step where that denominator is not positive."""
    sb = np.full(3, 1.0) if start is None else np.maximum(np.asarray(start, float), 1e-4)
    n = int(keep.sum())
    for _ in range(EM_ITER):
        delta, C = solve(S, keep, sb, Nx, bx)
        b, V = patch_shifts(S, keep, sb, delta, C)
        v = np.einsum("pii->pi", V)
        em = (b ** 2 + v).sum(0) / max(n, 1)
        den = (1.0 - v / sb).sum(0)
        fast = np.where(den > 0.5, (b ** 2).sum(0) / np.maximum(den, 0.5), em)
        new = np.maximum(fast, 1e-6)
        done = np.all(np.abs(np.sqrt(new) - np.sqrt(sb)) <= EM_TOL_M)
        sb = new
        if done:
            break
    return sb


@dataclass(frozen=True)
class LeaveOneOut:
    """Per patch (P,; NaN for patches not kept): the field's step without it ``delta``
    (P, u), the test statistic ``T`` of its own shift against the others' field, its degrees
    of freedom ``dof`` (directions the patch fixes) and the critical value ``crit``."""

    delta: np.ndarray
    T: np.ndarray
    dof: np.ndarray
    crit: np.ndarray


def leave_one_out(S, keep, sigma_b, Nx, bx, alpha: float, reestimate: bool = True) -> LeaveOneOut:
    """Each kept patch left out in turn: the others' field (and, with ``reestimate``, their
    ``Σ_b``), and the χ² test of the patch against it at ``alpha`` shared over the patches
    (Bonferroni). Linear about the current parameters."""
    P, u = S.b.shape
    delta = np.full((P, u), np.nan)
    T, dof, crit = np.full(P, np.nan), np.zeros(P, int), np.full(P, np.nan)
    idx = np.flatnonzero(keep)
    for p in idx:
        k = keep.copy()
        k[p] = False
        sb = variance_components(S, k, Nx, bx, start=sigma_b) if reestimate else sigma_b
        d, C = solve(S, k, sb, Nx, bx)
        delta[p] = d
        I = S.I[p]
        z = -(S.h[p] + S.B[p] @ d)
        cov = I + I @ np.diag(sb) @ I + S.B[p] @ C @ S.B[p].T
        w, vec = np.linalg.eigh(I)
        r = int((w > 1e-9 * max(w.max(), 1e-300)).sum())
        if r == 0:
            continue
        T[p] = float(z @ np.linalg.pinv(cov, rcond=1e-9, hermitian=True) @ z)
        dof[p] = r
        crit[p] = float(stats.chi2.ppf(1 - alpha / max(len(idx), 1), r))
    return LeaveOneOut(delta, T, dof, crit)


def jackknife(deltas: np.ndarray) -> np.ndarray:
    """Delete-one jackknife covariance (u, u) of the parameters from the leave-one-out steps
    ``deltas`` (n, u) (all measured from the same point)."""
    d = deltas[np.isfinite(deltas).all(1)]
    n = len(d)
    if n < 3:
        return np.full((deltas.shape[1],) * 2, np.nan)
    c = d - d.mean(0)
    return (n - 1) / n * c.T @ c
