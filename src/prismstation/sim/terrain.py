"""Synthetic terrain of the simulator: a north-up height grid, and its statistics.

Two relief kinds are made here: ``fractal`` (:func:`synthesize_relief`, ridges and valleys from
sea level (0) to ``relief``, default 1400 m, with a few metres of fine detail) and ``smooth``
(:func:`smooth_relief`, rolling hills of a stated mean slope and no relief shorter than about a
kilometre); ``sim/dem_terrain.py`` takes it from a real DEM instead. Heights are generated as
orthometric metres and stored ellipsoidal (``+ geoid``). Grid convention: cell ``(row, col)`` covers
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


#: mean slope (rise over run) the smooth terrain is scaled to over the ground N sees
SMOOTH_MEAN_SLOPE = 0.06
#: shortest wavelength (m) of the smooth terrain: its spectrum is cut by exp(−(k·λ)²) below it
SMOOTH_LAMBDA_MIN_M = 1200.0
#: lowest height (m, orthometric) of the smooth terrain
SMOOTH_BASE_M = 150.0
#: cell (m) the terrain statistics are computed on: the posting of 1″ DEMs (GLO-30, SRTM 1″)
STATS_CELL_M = 30.0


def smooth_relief(shape, spacing, rng, inside, mean_slope=SMOOTH_MEAN_SLOPE,
                  base=SMOOTH_BASE_M, lambda_min=SMOOTH_LAMBDA_MIN_M) -> np.ndarray:
    """Rolling hills (orthometric m, float32, lowest ``base``): a Gaussian field with power
    ``∝ k^−4.5`` between ``lambda_min`` and ``max(min(2 × extent, 30 km), 2 × lambda_min)``,
    scaled so that its mean slope over the cells where ``inside`` ``(rows, cols)`` bool is True
    is ``mean_slope``."""
    extent = max(shape) * spacing
    z = spectral_noise(shape, spacing, rng, 4.5, lambda_min, max(min(2.0 * extent, 30000.0), 2.0 * lambda_min))
    gy, gx = np.gradient(z, spacing)
    z *= mean_slope / float(np.hypot(gx, gy)[inside].mean())
    return (base + z - z.min()).astype(np.float32)


def scale_relief(ortho: np.ndarray, inside, factor: float) -> tuple[np.ndarray, float]:
    """Heights scaled by ``factor`` about their mean over ``inside`` (bool, same shape):
    ``m + factor·(H − m)``; returns (heights float32, m)."""
    m = float(np.mean(ortho[inside], dtype=np.float64))
    return (m + factor * (ortho.astype(np.float64) - m)).astype(np.float32), m


def inside_polygon(poly, e, n) -> np.ndarray:
    """True where map points ``(e, n)`` lie inside the convex polygon ``poly`` ``(k, 2)``
    (E, N corners in order, either sense); ``e`` and ``n`` broadcast to the result's shape."""
    poly = np.asarray(poly, float)
    e, n = np.asarray(e, float), np.asarray(n, float)
    signs = []
    for (e1, n1), (e2, n2) in zip(poly, np.roll(poly, -1, axis=0)):
        signs.append((e2 - e1) * (n - n1) - (n2 - n1) * (e - e1) >= 0)
    pos = np.logical_and.reduce(signs)
    neg = np.logical_and.reduce([~s for s in signs])
    return pos | neg


def cell_centres(grid: Grid) -> tuple[np.ndarray, np.ndarray]:
    """Map coordinates (E, N) of every cell centre: E ``(1, cols)`` and N ``(rows, 1)``, which
    broadcast to ``(rows, cols)`` (a full mesh of a 6,000 px scene's grid costs seconds)."""
    rows, cols = grid.values.shape
    e = grid.e0 + (np.arange(cols) + 0.5) * grid.spacing
    n = grid.n0 - (np.arange(rows) + 0.5) * grid.spacing
    return np.meshgrid(e, n, sparse=True)


def terrain_statistics(ortho: Grid, footprint) -> dict:
    """Statistics of orthometric heights ``ortho`` over the convex polygon ``footprint`` (E, N
    corners): mean slope and the share of slopes above 30 %, both on the heights averaged to
    ``STATS_CELL_M`` cells (central differences), and the heights' range and mean at the grid's
    own cells. Percentages and metres, JSON-ready."""
    f = max(1, int(round(STATS_CELL_M / ortho.spacing)))
    rows, cols = (d // f * f for d in ortho.values.shape)
    block = ortho.values[:rows, :cols].astype(np.float64).reshape(rows // f, f, cols // f, f)
    coarse = Grid(block.mean(axis=(1, 3)), ortho.e0, ortho.n0, f * ortho.spacing)
    gy, gx = np.gradient(coarse.values, coarse.spacing)
    slope = np.hypot(gx, gy)[inside_polygon(footprint, *cell_centres(coarse))]
    h = ortho.values[inside_polygon(footprint, *cell_centres(ortho))]
    return {"mean_slope_pct": round(100.0 * float(slope.mean()), 2),
            "slope_over_30pct_share_pct": round(100.0 * float(np.mean(slope > 0.3)), 2),
            "height_min_m": round(float(h.min()), 1), "height_max_m": round(float(h.max()), 1),
            "height_mean_m": round(float(h.mean()), 1), "slope_cell_m": coarse.spacing,
            "area": "the ground N sees"}
