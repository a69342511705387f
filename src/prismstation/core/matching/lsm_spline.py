"""Cubic B-spline interpolation of an image window with analytic derivatives: the search
image of least-squares matching (:mod:`prismstation.core.matching.lsm`).

Coordinates as there (docs/model.md §1): image ``x`` = column, ``y`` = row, pixels,
continuous, array element ``[j, i]`` centred at ``(i + 0.5, j + 0.5)``. Values and gradients
in float64 (grey values, grey values per pixel), sampled by
:mod:`prismstation.core.matching.lsm_kernel`.
"""
from __future__ import annotations

import numpy as np

from prismstation.core.lazy_cv2 import cv2, lazy_module  # imported at first use: start-up saving
from prismstation.core.matching.lsm_sigma import noise_sigma

kernel = lazy_module("prismstation.core.matching.lsm_kernel")


class Spline:
    """Cubic B-spline interpolation of a window of an image, with analytic derivatives.

    ``img`` is a window whose top-left corner is image pixel ``(c0, r0)``; :meth:`sample`
    takes image coordinates (continuous, docs/model.md §1)."""

    def __init__(self, img, c0: int = 0, r0: int = 0):
        self.raw = np.ascontiguousarray(img, np.float64)
        self.coef = kernel.spline_coefficients(self.raw)
        self.c0, self.r0 = c0, r0
        rows, cols = self.coef.shape
        self.flat, self.width = self.coef.ravel(), cols
        self.lo = (c0 + 1.5, r0 + 1.5)                  # where the 4×4 support stays inside (image px)
        self.hi = (c0 + cols - 2.5, r0 + rows - 2.5)

    def noise_near(self, x: float, y: float, half: int) -> float:
        """:func:`noise_sigma` of the window's pixels within ``half`` px of ``(x, y)``."""
        i, j = int(x - self.c0), int(y - self.r0)
        return noise_sigma(self.raw[max(j - half, 0):j + half + 1, max(i - half, 0):i + half + 1])

    def sample(self, x, y):
        """``(S, ∂S/∂x, ∂S/∂y)`` at image points ``x, y`` (same shape; NaN outside
        :attr:`lo`–:attr:`hi`)."""
        out = kernel.spline_points(self.flat, self.width, self.c0, self.r0, self.lo, self.hi, x, y)
        return tuple(a.reshape(np.shape(x)) for a in out)


def low_pass(a, sigma: float):
    """``a`` (2-D) convolved with a Gaussian of σ ``sigma`` px, edges extended: scipy's
    ``gaussian_filter(a, sigma, mode="nearest")`` (its kernel, to 10⁻¹³ of the values) by
    OpenCV, four times as fast."""
    r = int(4.0 * sigma + 0.5)
    return cv2.GaussianBlur(np.ascontiguousarray(a, np.float64), (2 * r + 1, 2 * r + 1), sigma,
                            borderType=cv2.BORDER_REPLICATE)


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
        crop = low_pass(crop, smooth)
    return Spline(crop, c0, r0)
