"""Weighted linear least squares with the statistics a photogrammetrist reads.

Model ``l = A·x + v`` with weights ``w = 1 / σ²`` (a-priori standard deviations of the
observations). Residuals are reported as ``v = l − A·x̂`` (observed minus computed).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prismstation.core.adjustment.estimate import degenerate
from prismstation.errors import ModelError


@dataclass(frozen=True, eq=False)
class LsqResult:
    """Solution of a weighted least-squares problem with ``n`` observations and ``u`` unknowns.

    ``cov`` is the a-posteriori covariance ``σ0²·N⁻¹`` when there is redundancy, else the
    a-priori ``N⁻¹``. ``std_residuals`` are externally studentised residuals
    ``v_i / (s_(i)·σ_i·sqrt(r_i))`` with ``s_(i)`` the σ0 estimated without observation ``i``
    (NaN where undefined), so that a blunder does not hide itself by inflating σ0.
    """

    params: np.ndarray        # (u,)
    cov: np.ndarray           # (u, u)
    sigma0: float | None      # a-posteriori σ0 (unitless), None without redundancy
    dof: int
    residuals: np.ndarray     # (n,) observed − computed, units of l
    redundancy: np.ndarray    # (n,) redundancy numbers r_i in [0, 1]
    std_residuals: np.ndarray  # (n,)

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.diag(self.cov))


def solve(A, l, sigma=None, *, what: str = "parameters", rcond: float = 1e-10) -> LsqResult:
    """Solve ``A·x ≈ l`` (``A`` ``(n, u)``, ``l`` ``(n,)``) weighted by ``1/sigma²``.

    Raises :class:`~prismstation.errors.DegenerateGeometry` (a :class:`ModelError`) with
    ``what`` in the message when ``n < u`` or ``Aw`` is singular to ``rcond`` (e.g. collinear
    points), :class:`ModelError` for non-finite input. Columns should be normalised by the
    caller, who also judges conditioning short of singular
    (:func:`prismstation.core.adjustment.estimate.check_spread`).
    """
    A = np.asarray(A, dtype=float)
    l = np.asarray(l, dtype=float)
    n, u = A.shape
    if n < u:
        raise degenerate(f"{what}: {u} unknowns need at least {u} observations, have {n}")
    sig = np.ones(n) if sigma is None else np.broadcast_to(np.asarray(sigma, float), (n,))
    if not np.all(np.isfinite(A)) or not np.all(np.isfinite(l)) or np.any(~(sig > 0)):
        raise ModelError(f"{what}: observations contain non-finite values or σ ≤ 0")
    sw = 1.0 / sig
    Aw, lw = A * sw[:, None], l * sw
    # SVD-based solve: detect rank deficiency instead of failing deep in LAPACK
    U, s, Vt = np.linalg.svd(Aw, full_matrices=False)
    if s[-1] <= rcond * s[0]:
        k = s[0] / s[-1] if s[-1] > 0 else float("inf")
        raise degenerate(f"{what}: the points do not determine the unknowns (collinear or "
                         f"coincident points; condition number {k:.3g})", k)
    x = Vt.T @ ((U.T @ lw) / s)
    Ninv = (Vt.T / s**2) @ Vt
    vw = lw - Aw @ x                     # weighted residuals
    dof = n - u
    hat = np.einsum("ij,ij->i", U, U)    # leverage h_ii of the weighted problem
    red = np.clip(1.0 - hat, 0.0, 1.0)
    ssr = float(vw @ vw)
    sigma0 = float(np.sqrt(ssr / dof)) if dof > 0 else None
    cov = Ninv * (sigma0**2 if sigma0 is not None else 1.0)
    std_res = np.full(n, np.nan)
    if dof > 1:
        ok = red > 1e-9
        s_i2 = (ssr - vw[ok] ** 2 / red[ok]) / (dof - 1)
        with np.errstate(invalid="ignore", divide="ignore"):
            std_res[ok] = vw[ok] / np.sqrt(np.maximum(s_i2, 1e-300) * red[ok])
    return LsqResult(x, cov, sigma0, dof, l - A @ x, red, std_res)
