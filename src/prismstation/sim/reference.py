"""SRTM-like reference DEMs of a simulated scene, from its truth (``truth_dem.tif``, ellipsoidal
heights on the scene's map grid), written as int16 GeoTIFFs with SRTM's void value −32768:

* :func:`make_reference_dem` — on the scene's own projected grid: the truth averaged to 90 m
  cells, orthometric through a constant geoid, 2 m noise, voids.
* :func:`make_geographic_reference` — as SRTM is shipped: 3″ cells of EPSG:4326 centred on
  whole multiples of 3″, each the truth's mean over the cell, orthometric through a geoid model
  (EGM96), 4 m noise, rounded to whole metres, voids. Reading it back crosses from geographic
  to map coordinates, which a projected reference never asks of the reader.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import rasterio
from rasterio.enums import Resampling
from rasterio.transform import Affine
from scipy import ndimage

from prismstation.io.atomic import atomic_path, raster_check
from prismstation.io.reproject import grid_pixels, transformer

SRTM_VOID = -32768
#: the largest distance (m) between the truth samples averaged into one geographic cell
SAMPLE_M = 15.0


def make_reference_dem(truth_dem, out, *, posting_m: float = 90.0, noise_m: float = 2.0,
                       void_fraction: float = 0.02, geoid_m: float = 55.0, seed: int = 0) -> Path:
    """Write ``out`` from the simulator's ``truth_dem.tif`` (ellipsoidal heights) on its own
    grid, cells of about ``posting_m`` (a whole number of truth cells, averaged)."""
    rng = np.random.default_rng(seed)
    with rasterio.open(truth_dem) as ds:
        f = posting_m / abs(ds.transform.a)
        shape = (max(int(ds.height / f), 2), max(int(ds.width / f), 2))
        h = ds.read(1, out_shape=shape, resampling=Resampling.average).astype(float)
        t = ds.transform @ Affine.scale(ds.width / shape[1], ds.height / shape[0])
        crs = ds.crs
    return _write(out, _srtm_like(h - geoid_m, rng, noise_m, void_fraction), crs, t,
                  {"heights": f"orthometric, constant geoid {geoid_m:g} m"})


def make_geographic_reference(truth_dem, out, geoid, *, arcsec: float = 3.0,
                              noise_m: float = 4.0, void_fraction: float = 0.02,
                              seed: int = 0) -> Path:
    """Write ``out`` from ``truth_dem.tif`` on a geographic grid, as SRTM is shipped.

    Parameters
    ----------
    geoid : an object with ``undulation(E, N, crs)`` (:mod:`prismstation.io.geoid`, e.g. the
        EGM96 grid): the heights written are ``h − N`` with ``N`` at each cell's centre.
    arcsec : cell size, arc-seconds of latitude and of longitude; cell centres on whole
        multiples of it (SRTM's posts).
    noise_m : σ (m) of the white noise added per cell before the heights are rounded to
        whole metres.
    void_fraction : about this share of cells void (−32768), in small blobs.

    Every cell covering only ground the truth holds is written: its value is the mean of the
    truth (bilinear between its cells) over k × l samples at most :data:`SAMPLE_M` apart
    across the cell, each carried from longitude and latitude onto the truth's grid by pyproj.
    """
    rng = np.random.default_rng(seed)
    step = arcsec / 3600.0
    with rasterio.open(truth_dem) as ds:
        truth = ds.read(1).astype(np.float64)
        t, crs = ds.transform, ds.crs
    rows, cols = truth.shape
    # the truth's outline in degrees (its top, bottom, left and right edges); cells wholly inside
    k = np.linspace(0.0, 1.0, 65)
    edge_c = np.concatenate([k * cols, k * cols, 0 * k, 0 * k + cols])
    edge_r = np.concatenate([0 * k, 0 * k + rows, k * rows, k * rows])
    lon, lat = transformer(crs, "EPSG:4326").transform(*(t @ (edge_c, edge_r)))
    top, bottom, left, right = (slice(i * 65, (i + 1) * 65) for i in range(4))
    west, east = np.max(lon[left]), np.min(lon[right])
    north, south = np.min(lat[top]), np.max(lat[bottom])
    c0, c1 = math.ceil(west / step + 0.5), math.floor(east / step - 0.5)       # centres at c·step
    r0, r1 = math.ceil(-north / step + 0.5), math.floor(-south / step - 0.5)   # rows southwards
    if c1 - c0 < 2 or r1 - r0 < 2:
        raise ValueError(f"the truth DEM holds fewer than 2 × 2 cells of {arcsec:g}″")
    shape = (r1 - r0 + 1, c1 - c0 + 1)
    geo_t = Affine(step, 0.0, (c0 - 0.5) * step, 0.0, -step, -(r0 - 0.5) * step)
    lat0 = math.radians(-(r0 + r1) / 2 * step)
    cell_m = (math.radians(step) * 6_378_137 * math.cos(lat0), math.radians(step) * 6_367_000)  # about
    kl, kr = (max(2, math.ceil(m / SAMPLE_M)) for m in cell_m)
    h = np.empty(shape)
    sub_c = (np.arange(shape[1] * kl) + 0.5) / kl                 # sample columns, in cells
    for a in range(0, shape[0], 32):
        b = min(shape[0], a + 32)
        sub_r = a + (np.arange((b - a) * kr) + 0.5) / kr
        sc, sr = np.meshgrid(sub_c, sub_r)
        slon, slat = geo_t @ (sc, sr)
        col, row = grid_pixels(slon, slat, "EPSG:4326", crs, t)
        v = ndimage.map_coordinates(truth, [row - 0.5, col - 0.5], order=1, mode="nearest",
                                    prefilter=False)
        h[a:b] = v.reshape(b - a, kr, shape[1], kl).mean(axis=(1, 3))
    clon, clat = geo_t @ np.meshgrid(np.arange(shape[1]) + 0.5, np.arange(shape[0]) + 0.5)
    undulation = np.asarray(geoid.undulation(clon, clat, "EPSG:4326"), float)
    if not np.all(np.isfinite(undulation)):
        raise ValueError("the geoid has no undulation over part of the scene")
    describe = geoid.describe() if hasattr(geoid, "describe") else str(geoid)
    return _write(out, _srtm_like(h - undulation, rng, noise_m, void_fraction), "EPSG:4326",
                  geo_t, {"heights": f"orthometric, geoid {describe}",
                          "cell": f"{arcsec:g} arc-seconds, centres on its multiples",
                          "noise_m": f"{noise_m:g}"})


def _srtm_like(H, rng, noise_m: float, void_fraction: float) -> np.ndarray:
    """Orthometric heights ``H`` with white noise, rounded to whole metres, voids as blobs
    (like SRTM's radar shadows): int16 with :data:`SRTM_VOID`."""
    H = H + rng.normal(0.0, noise_m, H.shape)
    if void_fraction > 0:
        seeds = rng.random(H.shape) < void_fraction / 12
        H[ndimage.binary_dilation(seeds, iterations=1)] = np.nan
    return np.where(np.isfinite(H), np.round(H), SRTM_VOID).astype(np.int16)


def _write(out, data: np.ndarray, crs, transform, tags: dict) -> Path:
    out = Path(out)
    rows, cols = data.shape
    with atomic_path(out, check=raster_check(cols, rows, 1)) as tmp, \
            rasterio.open(tmp, "w", driver="GTiff", width=cols, height=rows, count=1,
                          dtype="int16", crs=crs, transform=transform, nodata=SRTM_VOID) as dst:
        dst.write(data, 1)
        dst.update_tags(**{f"SIMULATED_REFERENCE_{k.upper()}": v for k, v in tags.items()})
    return out
