"""Synthetic terrain of the simulator: a north-up height grid with ridges and valleys.

Heights are generated as orthometric metres from sea level (0) to ``relief`` (default 1400 m)
and stored ellipsoidal (``+ geoid``). Grid convention: cell ``(row, col)`` covers
``E ∈ [E0 + col·s, E0 + (col+1)·s)``, ``N ∈ (N0 − (row+1)·s, N0 − row·s]``; values are at
cell centres.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import fft, ndimage


@dataclass(frozen=True)
class Grid:
    """A north-up raster on the map: ``values`` ``(rows, cols)``, west edge ``e0``, north edge
    ``n0`` (m), cell size ``spacing`` (m)."""

    values: np.ndarray
    e0: float
    n0: float
    spacing: float

    def to_pixel(self, e, n):
        """Continuous array indices ``(col, row)`` with cell centres at integers."""
        return ((np.asarray(e) - self.e0) / self.spacing - 0.5,
                (self.n0 - np.asarray(n)) / self.spacing - 0.5)

    def sample(self, e, n) -> np.ndarray:
        """Exact bilinear interpolation (float64) at map points; edges extend the border."""
        col, row = self.to_pixel(e, n)
        return ndimage.map_coordinates(self.values, [np.ravel(row), np.ravel(col)], order=1,
                                       mode="nearest", prefilter=False).reshape(np.shape(e))

    @property
    def geotransform(self) -> tuple[float, float, float, float, float, float]:
        """GDAL order ``(e0, s, 0, n0, 0, −s)``."""
        return (self.e0, self.spacing, 0.0, self.n0, 0.0, -self.spacing)


def spectral_noise(shape, spacing, rng, beta, lambda_min, lambda_max) -> np.ndarray:
    """Zero-mean unit-variance Gaussian field with power spectrum ``∝ k^−beta`` between the
    wavelengths ``lambda_min`` and ``lambda_max`` (m)."""
    ny, nx = shape
    white = rng.standard_normal(shape).astype(np.float32)
    spec = fft.rfft2(white)
    ky = fft.fftfreq(ny, spacing).astype(np.float32)[:, None]
    kx = fft.rfftfreq(nx, spacing).astype(np.float32)[None, :]
    k = np.sqrt(kx * kx + ky * ky)
    k = np.maximum(k, 1.0 / lambda_max)
    amp = k ** (-beta / 2.0)
    amp *= np.exp(-(k * lambda_min) ** 2)
    amp[0, 0] = 0.0
    field = fft.irfft2(spec * amp, s=shape).astype(np.float32)
    field -= field.mean()
    field /= field.std() + 1e-12
    return field


def synthesize_relief(shape, spacing, rng, relief=1400.0, sea_fraction=0.03) -> np.ndarray:
    """Orthometric heights (m, float32) from 0 to ``relief``: a smooth fractal base, ridged
    crests, a regional tilt (stronger on small areas so that slopes stay believable), a flat
    plain at sea level over ``sea_fraction`` of the area and a few metres of fine detail."""
    extent = max(shape) * spacing
    base = spectral_noise(shape, spacing, rng, 4.5, 250.0, min(2.0 * extent, 12000.0))
    ridged = (1.0 - np.abs(spectral_noise(shape, spacing, rng, 4.0, 300.0,
                                                min(0.5 * extent, 5000.0)))) ** 2
    detail = spectral_noise(shape, spacing, rng, 3.0, 3.0 * spacing, 300.0)
    yy, xx = np.meshgrid(np.linspace(-1, 1, shape[0], dtype=np.float32),
                         np.linspace(-1, 1, shape[1], dtype=np.float32), indexing="ij")
    ang = rng.uniform(0, 2 * np.pi)
    tilt = np.cos(ang) * xx + np.sin(ang) * yy
    w_tilt = float(np.clip(3.2 - extent / 10000.0, 0.7, 2.6))
    z = base + 0.35 * ridged * (1 + np.tanh(base)) + w_tilt * tilt
    lo, hi = np.quantile(z, sea_fraction), np.quantile(z, 0.9995)
    h = np.clip((z - lo) / (hi - lo), 0, None)
    h = np.where(h > 1, 1 + 0.02 * np.tanh(h - 1), h) ** 1.2   # rounded summits
    h = relief * h / h.max()
    h = h + 4.0 * detail * np.clip(h / 50.0, 0, 1)
    return (relief * np.clip(h, 0, None) / h.max()).astype(np.float32)


def hillshade(heights: np.ndarray, spacing: float, sun_azimuth_deg=135.0,
              sun_elevation_deg=40.0) -> np.ndarray:
    """Lambertian shading (float32, 1 on flat ground, ≥ 0.25) of a north-up height grid."""
    dz_dn = -np.gradient(heights, spacing, axis=0)   # rows go south
    dz_de = np.gradient(heights, spacing, axis=1)
    az, el = np.radians(sun_azimuth_deg), np.radians(sun_elevation_deg)
    sun = np.array([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)])
    norm = np.sqrt(dz_de ** 2 + dz_dn ** 2 + 1.0)
    cosi = (-dz_de * sun[0] - dz_dn * sun[1] + sun[2]) / norm
    return np.clip(0.25 + 0.75 * np.clip(cosi, 0, None) / sun[2], 0.25, 1.6).astype(np.float32)
