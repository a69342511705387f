"""Rasters onto other grids and points onto rasters, exactly: the one place the project brings
a raster from its own grid and CRS onto another (reference DEMs, DEMs to co-register, DSMs and
references to validate, class masks) or finds where map points fall on a raster of another CRS
(geoid grids, a terrain DEM).

Two tools, one promise — positions exact to a small, stated fraction of a cell:

* :func:`warp_band`, :func:`warp_array`: a band onto a target grid through GDAL's warper
  (its kernels: bilinear, cubic, average…, voids left out of the weights), with the
  approximate transformer held to :data:`ERROR_PX`. GDAL's default threshold, 0.125 source
  pixel, interpolates each target row's source positions linearly between a few exact ones;
  on a curved mapping (a geographic grid onto UTM) the chords lie on one side of the arc, so
  the whole raster arrives shifted: a 3″ DEM read onto a 21 km UTM grid at 41° N came out
  5–6 m north (0.06 of its cell). At :data:`ERROR_PX` the position of every target cell in the
  source grid is off by at most that (checked by warping the source's own column and row
  numbers: ``tests/io/test_reproject.py``), at no measurable cost.
* :func:`grid_pixels`: the continuous pixel coordinates on a grid of map points of any CRS,
  pyproj at every point (exact).

Pixel coordinates follow docs/model.md §1: ``(col, row)`` with the origin at the top-left
corner of the top-left cell, a cell's centre at ``+0.5``.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
from pyproj import CRS as ProjCRS
from pyproj import Transformer
from rasterio.crs import CRS
from rasterio.enums import Resampling
from rasterio.io import MemoryFile
from rasterio.transform import Affine
from rasterio.vrt import WarpedVRT

#: the largest error, in source pixels, GDAL's approximate transformer may leave in the source
#: position of a target cell (GDAL's own default is 0.125). Measured (benchmarks/bench_reproject.py)
#: with 3″ grids onto 21 km UTM grids at 0–70° N, on the central meridian and 2.95° off it: at
#: most 0.00097 px, the surface within 0.05 m of its place (at 0.125: up to 0.081 px, 4.9 m
#: north at 41° N); a 3″ grid onto 6,000² cells of 2.5 m takes the same 2–3 s at either.
#: (GDAL's exact transformer, threshold 0, is not used: rasterio 1.4's WarpedVRT fails with it.)
ERROR_PX = 0.001


def warp_band(ds, dst_crs, dst_transform, dst_shape, *, resampling: str = "bilinear",
              src_nodata=None, fill=np.nan, dtype=np.float64, band: int = 1,
              error_px: float = ERROR_PX) -> np.ndarray:
    """Band ``band`` of the open dataset ``ds`` resampled onto a target grid.

    Parameters
    ----------
    ds : an open rasterio dataset (with a CRS and a transform).
    dst_crs, dst_transform, dst_shape : the target grid (``dst_shape`` = (rows, cols)).
    resampling : a GDAL kernel, by its ``rasterio.enums.Resampling`` name (``"bilinear"``,
        ``"cubic"``, ``"average"``, ``"nearest"``…).
    src_nodata : the source's void value (default the dataset's own nodata); voids are left
        out of every kernel's weights.
    fill : the value of target cells with no source (outside it, or voids only).
    dtype : of the result.
    error_px : the approximate transformer's threshold, source pixels (> 0; a benchmark
        compares GDAL's default with :data:`ERROR_PX`).

    Returns
    -------
    ndarray ``dst_shape`` of ``dtype``. Raises rasterio's errors (``RasterioError``,
    ``CPLE_BaseError``) and ``KeyError`` for an unknown kernel: callers name the file.
    """
    rows, cols = (int(v) for v in dst_shape)
    nodata = ds.nodata if src_nodata is None else src_nodata
    with WarpedVRT(ds, crs=CRS.from_user_input(dst_crs), transform=Affine(*tuple(dst_transform)[:6]),
                   width=cols, height=rows, resampling=Resampling[resampling],
                   tolerance=error_px, src_nodata=nodata, nodata=fill,
                   dtype=np.dtype(dtype).name) as vrt:
        return vrt.read(band)


def warp_array(array, src_crs, src_transform, dst_crs, dst_transform, dst_shape, *,
               resampling: str = "bilinear", src_nodata=np.nan, fill=np.nan,
               dtype=np.float64, error_px: float = ERROR_PX) -> np.ndarray:
    """A 2-D array on grid ``(src_crs, src_transform)`` resampled onto a target grid, as
    :func:`warp_band` (voids ``src_nodata``, NaN by default)."""
    a = np.asarray(array)
    with MemoryFile() as mem:
        with mem.open(driver="GTiff", width=a.shape[1], height=a.shape[0], count=1,
                      dtype=a.dtype, crs=CRS.from_user_input(src_crs),
                      transform=Affine(*tuple(src_transform)[:6]), nodata=src_nodata) as ds:
            ds.write(a, 1)
        with mem.open() as ds:
            return warp_band(ds, dst_crs, dst_transform, dst_shape, resampling=resampling,
                             fill=fill, dtype=dtype, error_px=error_px)


@lru_cache(maxsize=32)
def _transformer(src_wkt: str, dst_wkt: str) -> Transformer:
    return Transformer.from_crs(ProjCRS.from_wkt(src_wkt), ProjCRS.from_wkt(dst_wkt), always_xy=True)


def _wkt(crs) -> str:
    return crs.to_wkt() if hasattr(crs, "to_wkt") else ProjCRS.from_user_input(crs).to_wkt()


def transformer(src_crs, dst_crs) -> Transformer:
    """pyproj's transformer ``src_crs`` → ``dst_crs`` (x, y order: easting or longitude
    first), made once per pair of CRSs."""
    return _transformer(_wkt(src_crs), _wkt(dst_crs))


def grid_pixels(x, y, crs, grid_crs, grid_transform) -> tuple[np.ndarray, np.ndarray]:
    """Continuous pixel coordinates ``(col, row)`` on a grid of the points ``(x, y)`` of
    ``crs`` (any shape; pyproj at every point, so exact; a cell's centre at ``+0.5``).
    Points with no position in the grid's CRS come out non-finite."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    if _wkt(crs) != _wkt(grid_crs):
        x, y = (np.asarray(v, float) for v in transformer(crs, grid_crs).transform(x, y))
    t = ~Affine(*tuple(grid_transform)[:6])
    return t.a * x + t.b * y + t.c, t.d * x + t.e * y + t.f
