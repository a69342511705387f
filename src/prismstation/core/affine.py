"""2-D affine transforms ``p' = L·p + t`` on arrays of points of shape ``(..., 2)``."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Affine2D:
    """``x' = a·x + b·y + c``, ``y' = d·x + e·y + f``, held as a 2×3 matrix ``[[a, b, c], [d, e, f]]``."""

    matrix: np.ndarray

    def __post_init__(self):
        m = np.asarray(self.matrix, dtype=float).reshape(2, 3)
        m.setflags(write=False)
        object.__setattr__(self, "matrix", m)

    @classmethod
    def from_coeffs(cls, a1, a2, a3, a4, a5, a6) -> "Affine2D":
        """FORMATS.md / paper eq. 1 order: ``x = A1·E + A2·N + A5``, ``y = A3·E + A4·N + A6``."""
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
        """The six values in FORMATS.md order ``[A1, A2, A3, A4, A5, A6]``."""
        (a, b, c), (d, e, f) = self.matrix
        return [a, b, d, e, c, f]

    def __call__(self, pts) -> np.ndarray:
        p = np.asarray(pts, dtype=float)
        return p @ self.linear.T + self.offset

    def apply_linear(self, vec) -> np.ndarray:
        """Apply only the linear part (to direction vectors)."""
        return np.asarray(vec, dtype=float) @ self.linear.T

    def inverse(self) -> "Affine2D":
        inv = np.linalg.inv(self.linear)
        return Affine2D(np.column_stack([inv, -inv @ self.offset]))

    def __matmul__(self, other: "Affine2D") -> "Affine2D":
        """Composition: ``(self @ other)(p) == self(other(p))``."""
        lin = self.linear @ other.linear
        return Affine2D(np.column_stack([lin, self.linear @ other.offset + self.offset]))

    def scale(self) -> float:
        """Mean linear scale ``sqrt(|det L|)``."""
        return float(np.sqrt(abs(np.linalg.det(self.linear))))
