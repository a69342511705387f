"""The shift field's model pieces: the reference DEM as a surface (:class:`Surface`), the
field's affine basis over N's image (:class:`Basis`), and the along-track height pattern the
relative DEMs may hold beyond it (:class:`Distortion`). The adjustment that uses them is
:mod:`prismstation.core.orientation.field_adjust`."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Surface:
    """Reference heights ``heights`` (rows, cols; NaN where void) on a north-up grid whose
    top-left corner is ``(west, north)`` (m) with square cells of ``posting`` m."""

    heights: np.ndarray
    west: float
    north: float
    posting: float

    def __post_init__(self):
        gy, gx = np.gradient(np.asarray(self.heights, float), self.posting)
        object.__setattr__(self, "_gx", gx)
        object.__setattr__(self, "_gy", -gy)          # rows run south

    def sample(self, e, n):
        """Bilinear heights and gradients ``(h, dh/dE, dh/dN)`` at map points ``e, n`` (m),
        NaN where a void or the grid's edge is within reach."""
        col = (np.asarray(e, float) - self.west) / self.posting - 0.5
        row = (self.north - np.asarray(n, float)) / self.posting - 0.5
        rows, cols = self.heights.shape
        c0, r0 = np.floor(col).astype(int), np.floor(row).astype(int)
        inside = (c0 >= 1) & (r0 >= 1) & (c0 < cols - 2) & (r0 < rows - 2)
        c0, r0 = np.where(inside, c0, 1), np.where(inside, r0, 1)
        fc, fr = col - c0, row - r0
        out = []
        for g in (self.heights, self._gx, self._gy):
            v = ((1 - fr) * ((1 - fc) * g[r0, c0] + fc * g[r0, c0 + 1])
                 + fr * ((1 - fc) * g[r0 + 1, c0] + fc * g[r0 + 1, c0 + 1]))
            out.append(np.where(inside, v, np.nan))
        return tuple(out)


@dataclass(frozen=True)
class Basis:
    """The field's coordinates: ``u = (x − cx) / scale``, ``v = (y − cy) / scale`` (N pixels),
    and which terms each component keeps (``terms[k]``: 3 for ``1, u, v``; 1 for a constant)."""

    centre: tuple
    scale: float
    terms: tuple = (3, 3, 3)

    @classmethod
    def over(cls, shape, terms=(3, 3, 3)) -> "Basis":
        """The basis centred on an N image of ``shape`` (rows, cols), ±1 at its edges."""
        rows, cols = shape
        return cls((cols / 2.0, rows / 2.0), max(rows, cols) / 2.0, tuple(terms))

    def phi(self, x, y) -> np.ndarray:
        """``(..., 3)``: ``1, u, v`` at N positions ``x, y``."""
        u = (np.asarray(x, float) - self.centre[0]) / self.scale
        v = (np.asarray(y, float) - self.centre[1]) / self.scale
        return np.stack([np.ones_like(u), u, v], -1)

    @property
    def active(self) -> np.ndarray:
        """``(9,)`` bool: which of ``θ`` (per component: 1, u, v) are estimated."""
        return np.array([j < t for t in self.terms for j in range(3)])

    def predict(self, theta, x, y) -> np.ndarray:
        """The field ``(..., 3)`` (dE, dN, dh, m) of parameters ``theta`` (9,) at ``x, y``."""
        return self.phi(x, y) @ np.asarray(theta, float).reshape(3, 3).T

    def predict_sigma(self, cov, x, y) -> np.ndarray:
        """σ ``(..., 3)`` of the field at ``x, y`` from the ``(9, 9)`` covariance of ``θ``."""
        p = self.phi(x, y)
        return np.sqrt(np.stack([np.einsum("...i,ij,...j->...", p, cov[3 * k:3 * k + 3, 3 * k:3 * k + 3], p)
                                 for k in range(3)], -1))


@dataclass(frozen=True)
class Distortion:
    """What the relative DEMs' heights may hold beyond the affine field: a polynomial of the
    along-track coordinate ``t = ((x, y) − centre)·d / scale`` (N px; ``d`` the flight direction
    in N image space, unit; ``t = ±1`` at the image's ends for a path-oriented product), in
    Legendre polynomials of degrees ``degrees`` (2: ``(3t² − 1)/2``, 3: ``(5t³ − 3t)/2``).

    Attitude that is not linear in time makes F's and B's offsets from N vary non-linearly
    along the track; their difference is a parallax, i.e. heights that the field's affine
    ``dh`` cannot hold. Where the terrain is nearly a plane at the patches' scale such a
    height pattern reads as a planimetric shift: on a scene made by another simulator, 0.045 px
    of quadratic parallax over 10 km (3 cm of height) moved the field by 6 m. With these terms
    the adjustment fixes the pattern where the terrain tells it from a shift, and its σ grows
    where it does not."""

    centre: tuple
    scale: float
    direction: tuple
    degrees: tuple = (2, 3)

    def psi(self, x, y) -> np.ndarray:
        """``(..., D)``: the polynomials at N positions ``x, y``."""
        d = np.asarray(self.direction, float)
        t = ((np.asarray(x, float) - self.centre[0]) * d[0] + (np.asarray(y, float) - self.centre[1]) * d[1]) / self.scale
        leg = {1: lambda t: t, 2: lambda t: 1.5 * t * t - 0.5, 3: lambda t: 2.5 * t ** 3 - 1.5 * t,
               4: lambda t: (35 * t ** 4 - 30 * t * t + 3) / 8}
        return np.stack([leg[k](t) for k in self.degrees], -1) if self.degrees else np.zeros(np.shape(t) + (0,))

    def __len__(self) -> int:
        return len(self.degrees)
