"""An SRTM-like reference DEM of a simulated scene: the truth terrain averaged to 90 m,
orthometric (truth minus the geoid undulation), with noise and voids, written as an int16
GeoTIFF with SRTM's void value −32768."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import rasterio
from rasterio.enums import Resampling
from rasterio.transform import Affine
from scipy import ndimage

from prismstation.io.atomic import atomic_path, raster_check


def make_reference_dem(truth_dem, out, *, posting_m: float = 90.0, noise_m: float = 2.0,
                       void_fraction: float = 0.02, geoid_m: float = 55.0, seed: int = 0) -> Path:
    """Write ``out`` from the simulator's ``truth_dem.tif`` (ellipsoidal heights)."""
    rng = np.random.default_rng(seed)
    with rasterio.open(truth_dem) as ds:
        f = posting_m / abs(ds.transform.a)
        shape = (max(int(ds.height / f), 2), max(int(ds.width / f), 2))
        h = ds.read(1, out_shape=shape, resampling=Resampling.average).astype(float)
        t = ds.transform @ Affine.scale(ds.width / shape[1], ds.height / shape[0])
        crs = ds.crs
    H = h - geoid_m + rng.normal(0.0, noise_m, shape)
    if void_fraction > 0:  # blobs, like SRTM's radar shadow voids
        seeds = rng.random(shape) < void_fraction / 12
        voids = ndimage.binary_dilation(seeds, iterations=1)
        H[voids] = np.nan
    out = Path(out)
    data = np.where(np.isfinite(H), np.round(H), -32768).astype(np.int16)
    with atomic_path(out, check=raster_check(shape[1], shape[0], 1)) as tmp, \
            rasterio.open(tmp, "w", driver="GTiff", width=shape[1], height=shape[0], count=1,
                          dtype="int16", crs=crs, transform=t, nodata=-32768) as dst:
        dst.write(data, 1)
    return out
