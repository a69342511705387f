"""Rendering of 1B2 product images through the rigorous geometry.

For each output pixel centre: image → map at h = 0 → nominal raw (line, col) → TRUE ray →
terrain intersection → ground texture; then a Gaussian sensor PSF (or none: point sampling) and
Gaussian noise, and optionally JPEG block noise (:func:`jpeg_blocks`).
"""
from __future__ import annotations

from prismstation.core.lazy_cv2 import cv2  # imported at first use: start-up saving
import numpy as np

from prismstation.sim import geometry as geo
from prismstation.sim.terrain import Grid
from prismstation.core.surfaces.sample import remap_points

HALO = 4


def dem_sampler(dem: Grid):
    """Fast bilinear sampler ``(E, N) → h`` of a float32 grid (cv2, 1/32-cell weights)."""
    values = np.ascontiguousarray(dem.values, dtype=np.float32)

    def sample(e, n):
        return remap_points(values, *dem.to_pixel(e, n)).astype(np.float64)

    return sample


def ground_of_pixels(orbit: geo.Orbit, view: geo.View, xy, sample, h_min, h_max,
                     tol=0.02) -> np.ndarray:
    """Terrain point ``(..., 3)`` (E, N, h) seen by product pixels ``xy`` ``(..., 2)``."""
    origin, direction = geo.pixel_rays(orbit, view, xy)
    return geo.intersect_terrain(origin, direction, sample, h_min, h_max, tol=tol)


def render_rows(orbit: geo.Orbit, view: geo.View, width: int, r0: int, r1: int, dem: Grid,
                texture: Grid, h_min: float, h_max: float, psf_sigma: float = 0.6,
                noise_sigma: float = 1.2, rng=None, sampler=None) -> np.ndarray:
    """Rows ``r0:r1`` (all ``width`` columns) of a product image, float32 DN before rounding.

    ``texture``: a :class:`~prismstation.sim.terrain.Grid` (sampled bicubically) or a function
    ``(E, N) → DN`` (sampled at each pixel's ground point). ``psf_sigma`` (px) Gaussian blur (0:
    none, each pixel one point of the ground), ``noise_sigma`` (DN) Gaussian noise from ``rng``
    (none when ``rng`` is None or ``noise_sigma`` is 0).
    """
    sample = sampler or dem_sampler(dem)
    halo = HALO if psf_sigma > 0 else 0
    ys = np.arange(r0 - halo, r1 + halo) + 0.5
    xs = np.arange(width) + 0.5
    xy = np.stack(np.meshgrid(xs, ys), axis=-1)
    ground = ground_of_pixels(orbit, view, xy, sample, h_min, h_max)
    if callable(texture):                  # a function of map position (no grid)
        img = texture(ground[..., 0], ground[..., 1])
    else:
        col, row = texture.to_pixel(ground[..., 0], ground[..., 1])
        img = remap_points(texture.values, col, row, cv2.INTER_CUBIC).astype(np.float32)
    if psf_sigma > 0:
        img = cv2.GaussianBlur(img, (0, 0), psf_sigma, borderType=cv2.BORDER_REFLECT)
        img = img[halo:halo + (r1 - r0)]
    if rng is not None and noise_sigma > 0:
        img = img + rng.normal(0.0, noise_sigma, img.shape).astype(np.float32)
    return img


def to_uint8(img: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def jpeg_blocks(img: np.ndarray, quality: int) -> np.ndarray:
    """``img`` (uint8, rows a multiple of 8 from an 8-aligned first row) through a baseline JPEG
    encoder at ``quality`` (1–100) and back: its 8 × 8 block noise, as compressed products carry."""
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise RuntimeError("JPEG encoding failed")
    return cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)
