"""The orthoimage GeoTIFF: one band of the view's values on a north-up grid of the scene's CRS,
a mask, metadata; Cloud-Optimized (tiled 256 × 256, deflate, internal overviews:
:func:`prismstation.io.cog.write_cog`), written tile by tile as the tiles are made.

Band 1 holds the image's values in the image's own data type (a PRISM image's bytes, a
Pléiades image's 12 bits in 16). No data — outside the image, where the DEM has a void, where
the resampling kernel leaves the image — is 0 for integer types (a valid sample that rounds to
0 is stored as 1, so that nodata never hides a pixel) and NaN for floating ones, and 0 in the
internal mask band (GDAL's per-dataset mask: 255 valid, 0 no data), which is what readers
should follow.

Tags (metadata, the ``prismstation`` domain's keys written as plain tags): ``ORTHO_VIEW``,
``ORTHO_IMAGE``, ``ORTHO_MODEL`` (the sensor model), ``ORTHO_ORIENTATION`` (how the model was
fitted, in words), ``ORTHO_PROJECT`` and ``ORTHO_REVISION``, ``ORTHO_DEM`` (the heights: file or
constant, and their kind), ``ORTHO_DEM_KIND``, ``ORTHO_DEM_PATH`` / ``ORTHO_DEM_CONSTANT_M``,
``ORTHO_POSTING_M``, ``ORTHO_RESAMPLING``, ``ORTHO_VALID_PERCENT``,
``ORTHO_INTERPOLATION_MAX_PX`` (the positions' largest interpolation error found),
``ORTHO_EXPECTED_SIGMA_M`` (the expected planimetric accuracy, RMS radial metres, with its parts
``ORTHO_ORIENTATION_SIGMA_M``, ``ORTHO_DEM_SIGMA_M``, ``ORTHO_OFF_NADIR_TAN``,
``ORTHO_CHECK_RMSE_M``) and ``ORTHO_ACCURACY`` (the same as JSON).
"""
from __future__ import annotations

import numpy as np
import pyproj
from rasterio.crs import CRS
from rasterio.transform import Affine
from rasterio.windows import Window

from prismstation.io.cog import write_cog
from prismstation.io.dem import open_raster

#: the image data types an ortho keeps (others are written as float32)
KEPT_DTYPES = ("uint8", "uint16", "int16", "uint32", "int32", "float32", "float64")


def ortho_dtype(image_dtype: str) -> str:
    """The data type of an ortho of an image of ``image_dtype``."""
    return image_dtype if image_dtype in KEPT_DTYPES else "float32"


def nodata_of(dtype: str) -> float:
    """No data of band 1: 0 for integer types, NaN for floating ones."""
    return float("nan") if np.dtype(dtype).kind == "f" else 0.0


def image_dtype(path) -> str:
    """Band 1's data type of the image ``path``."""
    with open_raster(path, "image") as ds:
        return ds.dtypes[0]


def to_band(values: np.ndarray, dtype: str) -> tuple[np.ndarray, np.ndarray]:
    """``(band, mask)`` of float32 ``values`` (NaN: no data): the values rounded and clipped
    into ``dtype`` (integer no data 0, a valid 0 stored as 1), the mask uint8 255 / 0."""
    valid = np.isfinite(values)
    dt = np.dtype(dtype)
    if dt.kind == "f":
        band = values.astype(dt)
    else:
        info = np.iinfo(dt)
        band = np.clip(np.rint(np.where(valid, values, 0.0)), max(info.min, 1) if info.min >= 0 else info.min,
                       info.max).astype(dt)
        band[valid & (band == 0)] = 1
        band[~valid] = 0
    return band, np.where(valid, 255, 0).astype(np.uint8)


class OrthoFile:
    """What :func:`write_ortho`'s ``fill`` writes to: ``write(window, values)`` puts a tile's
    float32 values (NaN: no data) at ``window`` = (row0, col0, rows, cols) of the grid."""

    def __init__(self, ds, dtype: str):
        self.ds, self.dtype = ds, dtype

    def write(self, window, values) -> None:
        r0, c0, rows, cols = window
        band, mask = to_band(values, self.dtype)
        w = Window(c0, r0, cols, rows)
        self.ds.write(band, 1, window=w)
        self.ds.write_mask(mask, window=w)


def write_ortho(path, shape, transform, crs, dtype: str, fill, *, tags: dict, before_keep=None) -> None:
    """Write the ortho at ``path`` (atomic: :func:`prismstation.io.cog.write_cog`): a grid of
    ``shape`` (rows, cols) on ``transform`` (rasterio order) in ``crs``; ``fill(OrthoFile)``
    writes its tiles (every cell of the grid, each once); ``tags`` its metadata (see
    the module docstring); ``before_keep`` as :func:`~prismstation.io.cog.write_cog`'s."""
    rows, cols = shape
    profile = dict(width=cols, height=rows, count=1, dtype=dtype, crs=CRS.from_user_input(crs),
                   transform=Affine(*tuple(transform)[:6]), nodata=nodata_of(dtype))

    def fill_scratch(ds):
        fill(OrthoFile(ds, dtype))
        ds.update_tags(**{k: str(v) for k, v in tags.items()})
        ds.set_band_description(1, f"view {tags.get('ORTHO_VIEW', '')}".strip())
    write_cog(path, profile, fill_scratch, before_keep=before_keep, what="ortho")


def read_ortho_info(path) -> dict:
    """Tags, CRS (pyproj), transform, shape, data type, no data, block shape, overview factors
    and mask flags of a written ortho."""
    with open_raster(path, "orthoimage") as ds:
        return {"tags": ds.tags(), "crs": pyproj.CRS.from_wkt(ds.crs.to_wkt()) if ds.crs else None,
                "transform": tuple(ds.transform)[:6], "shape": (ds.height, ds.width), "dtype": ds.dtypes[0],
                "nodata": ds.nodata, "blocks": ds.block_shapes[0], "overviews": ds.overviews(1),
                "mask_flags": [f.name for f in ds.mask_flag_enums[0]]}


def read_ortho_window(path, window) -> np.ndarray:
    """The ortho's values over ``window`` = (row0, col0, rows, cols) (clipped to the grid, the
    rest NaN) as float32, NaN where the mask says no data."""
    r0, c0, rows, cols = (int(v) for v in window)
    out = np.full((rows, cols), np.nan, np.float32)
    with open_raster(path, "orthoimage") as ds:
        a0, b0 = max(c0, 0), max(r0, 0)
        a1, b1 = min(c0 + cols, ds.width), min(r0 + rows, ds.height)
        if a1 <= a0 or b1 <= b0:
            return out
        w = Window(a0, b0, a1 - a0, b1 - b0)
        v = ds.read(1, window=w).astype(np.float32)
        m = ds.dataset.read_masks(1, window=w)
        out[b0 - r0:b1 - r0, a0 - c0:a1 - c0] = np.where(m > 0, v, np.nan)
    return out


def read_ortho_overview(path, max_px: int = 2048) -> tuple[np.ndarray, tuple]:
    """The whole ortho decimated to at most ``max_px`` on its longer side (float32, NaN no data;
    GDAL reads its overviews) and the transform of that array."""
    with open_raster(path, "orthoimage") as ds:
        f = max(1, int(np.ceil(max(ds.width, ds.height) / max_px)))
        shape = (max(1, ds.height // f), max(1, ds.width // f))
        v = ds.read(1, out_shape=shape).astype(np.float32)
        m = ds.dataset.read_masks(1, out_shape=shape)
        t = ds.transform @ Affine.scale(ds.width / shape[1], ds.height / shape[0])
    return np.where(m > 0, v, np.nan), tuple(t)[:6]

