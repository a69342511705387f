"""2-D affine transforms ``p' = L·p + t`` on arrays of points of shape ``(..., 2)``."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prismstation.core.adjustment import lsq
from prismstation.core.adjustment.estimate import Normaliser, check_points, check_spread, failure_or, published_cov
from prismstation.errors import ModelError


@dataclass(frozen=True, eq=False)
class Affine2D:
    """``x' = a·x + b·y + c``, ``y' = d·x + e·y + f``, held as a 2×3 matrix ``[[a, b, c], [d, e, f]]``.

    An estimator (:mod:`prismstation.core.adjustment.estimate`): :meth:`fit` from point pairs; a fitted
    one has ``cov`` (6, 6) of :attr:`params` ``[a, b, c, d, e, f]``, ``sigma0`` and ``dof``
    (None, None, 0 for an affine given rather than fitted).
    """

    matrix: np.ndarray
    cov: np.ndarray | None = None
    sigma0: float | None = None
    dof: int = 0

    def __post_init__(self):
        m = np.asarray(self.matrix, dtype=float).reshape(2, 3)
        m.setflags(write=False)
        object.__setattr__(self, "matrix", m)

    @classmethod
    def fit(cls, src, dst, sigma=None):
        """Least-squares affine from ``src`` ``(n, 2)`` to ``dst`` ``(n, 2)`` (n ≥ 3, spread in two
        directions); ``sigma`` (n,) a-priori σ of each ``dst`` point (its units; default 1, σ0
        then in those units). Returns the :class:`Affine2D` or a falsy
        :class:`~prismstation.core.adjustment.estimate.FailedFit`."""
        return failure_or(fit_affine, src, dst, sigma)

    @property
    def params(self) -> np.ndarray:
        """``[a, b, c, d, e, f]`` (the matrix row by row)."""
        return self.matrix.ravel()

    def residuals(self, src, dst) -> np.ndarray:
        """``(n, 2)`` observed − computed ``dst − self(src)``."""
        return np.asarray(dst, float) - self(src)

    @classmethod
    def from_coeffs(cls, a1, a2, a3, a4, a5, a6) -> "Affine2D":
        """docs/formats.md / paper eq. 1 order: ``x = A1·E + A2·N + A5``, ``y = A3·E + A4·N + A6``."""
        return cls([[a1, a2, a5], [a3, a4, a6]])

    @classmethod
    def from_gdal(cls, gt) -> "Affine2D":
        """GDAL geotransform ``(c, a, b, f, d, e)`` (pixel → map) as an :class:`Affine2D`."""
        c, a, b, f, d, e = (float(v) for v in gt)
        return cls([[a, b, c], [d, e, f]])

    @classmethod
    def identity(cls) -> "Affine2D":
        return cls([[1, 0, 0], [0, 1, 0]])

    @property
    def linear(self) -> np.ndarray:
        return self.matrix[:, :2]

    @property
    def offset(self) -> np.ndarray:
        return self.matrix[:, 2]

    def coeffs(self) -> list[float]:
        """The six values in docs/formats.md order ``[A1, A2, A3, A4, A5, A6]``."""
        (a, b, c), (d, e, f) = self.matrix
        return [a, b, d, e, c, f]

    def __call__(self, pts) -> np.ndarray:
        p = np.asarray(pts, dtype=float)
        return p @ self.linear.T + self.offset

    def apply_linear(self, vec) -> np.ndarray:
        """Apply only the linear part (to direction vectors)."""
        return np.asarray(vec, dtype=float) @ self.linear.T

    def inverse(self, pts=None):
        """Without ``pts`` the inverse :class:`Affine2D`; with points ``(..., 2)`` their image
        under it (the estimator protocol's ``inverse(xy)``)."""
        inv = np.linalg.inv(self.linear)
        back = Affine2D(np.column_stack([inv, -inv @ self.offset]))
        return back if pts is None else back(pts)

    def __matmul__(self, other: "Affine2D") -> "Affine2D":
        """Composition: ``(self @ other)(p) == self(other(p))``."""
        lin = self.linear @ other.linear
        return Affine2D(np.column_stack([lin, self.linear @ other.offset + self.offset]))

    def scale(self) -> float:
        """Mean linear scale ``sqrt(|det L|)``."""
        return float(np.sqrt(abs(np.linalg.det(self.linear))))


def fit_affine(src, dst, sigma=None) -> Affine2D:
    """:meth:`Affine2D.fit` raising :class:`~prismstation.errors.ModelError` (or
    :class:`~prismstation.errors.DegenerateGeometry`) instead of returning a failure."""
    src = np.asarray(src, float).reshape(-1, 2)
    dst = np.asarray(dst, float).reshape(-1, 2)
    n = len(src)
    if len(dst) != n:
        raise ModelError(f"affine: {n} source points but {len(dst)} destination points")
    check_points(n, 3, "an affine transform")
    ns, nd = Normaliser.of(src), Normaliser.of(dst)
    u = ns.fwd(src)
    check_spread(u, "affine transform")
    A = np.zeros((2 * n, 6))
    A[:n, :2], A[:n, 2] = u, 1
    A[n:, 3:5], A[n:, 5] = u, 1
    sig = np.ones(n) if sigma is None else np.broadcast_to(np.asarray(sigma, float), (n,))
    res = lsq.solve(A, nd.fwd(dst).T.ravel(), np.tile(sig / nd.scale, 2), what="affine transform")

    def publish(q):  # normalised [a', b', c', d', e', f'] → published (an affine map of q)
        L = nd.scale / ns.scale * q.reshape(2, 3)[:, :2]
        t = nd.scale * q.reshape(2, 3)[:, 2] - L @ ns.centre + nd.centre
        return np.column_stack([L, t]).ravel()

    p, cov = published_cov(publish, res.params, res.cov)
    return Affine2D(p.reshape(2, 3), cov, res.sigma0, res.dof)
