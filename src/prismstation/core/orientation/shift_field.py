"""Affine field of shifts over an image (docs/model.md §3 step 4): ``shift_k(x, y) = p[k,0] +
p[k,1]·x + p[k,2]·y`` for ``k`` shift components (e.g. dE, dN, dh in metres) at positions
``(x, y)`` (e.g. N-image pixels, docs/model.md §1). An estimator of
:mod:`prismstation.core.adjustment.estimate` from positions ``(n, 2)`` to shifts ``(n, k)``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import block_diag

from prismstation.core.adjustment import lsq
from prismstation.core.adjustment.estimate import Normaliser, check_points, check_spread, failure_or
from prismstation.errors import ModelError


@dataclass(frozen=True, eq=False)
class ShiftField:
    """A fitted affine shift field.

    Attributes
    ----------
    params : (k, 3) coefficients per component, in the units of the inputs.
    component_cov : (k, 3, 3) covariance of each component's coefficients (a posteriori,
        scaled by σ0² when there is redundancy, else a priori from the given σ's).
    sigma0 : (k,) a-posteriori σ of unit weight per component (NaN without redundancy).
    fit_residuals : (n, k) observed − modelled shifts at the fitting positions.
    """

    params: np.ndarray
    component_cov: np.ndarray
    sigma0: np.ndarray
    fit_residuals: np.ndarray

    @classmethod
    def fit(cls, xy, shifts, sigma=None):
        """Fit from positions ``xy`` ``(n, 2)`` (n ≥ 3, spread in two directions) and
        ``shifts`` ``(n, k)`` with σ ``(n, k)`` (default 1); the :class:`ShiftField` or a
        falsy :class:`~prismstation.core.adjustment.estimate.FailedFit`."""
        xy = np.asarray(xy, float).reshape(-1, 2)
        return failure_or(fit_shift_field, xy[:, 0], xy[:, 1], shifts, sigma)

    @property
    def cov(self) -> np.ndarray:
        """(3k, 3k) covariance of ``params.ravel()`` (block-diagonal: components independent)."""
        return block_diag(*self.component_cov)

    @property
    def dof(self) -> int:
        """Redundancy ``k·(n − 3)`` of the whole fit (each component's σ0 has ``n − 3``)."""
        n, k = self.fit_residuals.shape
        return k * (n - 3)

    def predict(self, x, y) -> np.ndarray:
        """Modelled shifts at positions ``x, y`` (arrays of one shape) → shape (..., k)."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        return self.params[:, 0] + x[..., None] * self.params[:, 1] + y[..., None] * self.params[:, 2]

    def __call__(self, xy) -> np.ndarray:
        """Shifts ``(..., k)`` at positions ``xy`` ``(..., 2)``."""
        xy = np.asarray(xy, float)
        return self.predict(xy[..., 0], xy[..., 1])

    def inverse(self, shifts) -> np.ndarray:
        """Positions ``(..., 2)`` where the field takes the values ``shifts`` ``(..., 2)``;
        defined for two components with an invertible gradient only."""
        if self.params.shape[0] != 2:
            raise ModelError(f"a field of {self.params.shape[0]} components has no inverse")
        G = self.params[:, 1:]
        return (np.asarray(shifts, float) - self.params[:, 0]) @ np.linalg.inv(G).T

    def residuals(self, xy, shifts) -> np.ndarray:
        """``(n, k)`` observed − modelled ``shifts − self(xy)``."""
        return np.asarray(shifts, float).reshape(len(np.atleast_2d(xy)), -1) - self(xy)

    def predict_sigma(self, x, y) -> np.ndarray:
        """Standard deviation of the modelled shifts at ``x, y`` → shape (..., k)."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        j = np.stack([np.ones_like(x), x, y], -1)
        return np.sqrt(np.einsum("...i,kij,...j->...k", j, self.component_cov, j))


def fit_shift_field(x, y, shifts, sigmas=None) -> ShiftField:
    """Weighted least-squares affine fit of per-patch shifts vs patch position.

    ``x, y`` (n,) positions; ``shifts`` (n, k); ``sigmas`` (n, k) their σ (weights 1/σ²,
    default 1). Raises :class:`~prismstation.errors.DegenerateGeometry` (a ``ValueError``)
    for fewer than 3 positions or positions on or nearly on one line.
    """
    x, y = np.asarray(x, float).ravel(), np.asarray(y, float).ravel()
    s = np.asarray(shifts, float).reshape(x.size, -1)
    n, k = s.shape
    sig = np.ones_like(s) if sigmas is None else np.broadcast_to(np.asarray(sigmas, float), (n, k))
    check_points(n, 3, "an affine shift field", "patches")
    norm = Normaliser.of(np.column_stack([x, y]))
    u = norm.fwd(np.column_stack([x, y]))
    check_spread(u, "affine shift field", "patch positions")
    A = np.column_stack([np.ones(n), u])
    (cx, cy), sc = norm.centre, norm.scale
    back = np.array([[1, -cx / sc, -cy / sc], [0, 1 / sc, 0], [0, 0, 1 / sc]])
    params, covs = np.zeros((k, 3)), np.zeros((k, 3, 3))
    s0s, v = np.full(k, np.nan), np.zeros((n, k))
    for i in range(k):
        res = lsq.solve(A, s[:, i], sig[:, i], what="affine shift field")
        params[i], covs[i], v[:, i] = back @ res.params, back @ res.cov @ back.T, res.residuals
        if res.sigma0 is not None:
            s0s[i] = res.sigma0
    return ShiftField(params, covs, s0s, v)
