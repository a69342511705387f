"""A GeoTIFF written block by block (a rectified image, an orthoimage), atomically: the output
of a warp too large to hold whole.

The file is tiled (512 px), deflate-compressed, BigTIFF where it needs to be; it is written
beside its target and, when the ``with`` block ends, checked (its size, its bands, every block
in the file: :func:`prismstation.io.atomic.raster_check`) and renamed onto it; a block that
raised leaves no file and does not touch an existing one (:func:`prismstation.io.atomic.atomic_path`).
"""
from __future__ import annotations

from contextlib import contextmanager
from typing import Callable, Iterator

import numpy as np
import rasterio
from rasterio.transform import Affine
from rasterio.windows import Window

from prismstation.io.atomic import atomic_path, raster_check


@contextmanager
def block_writer(path, *, width: int, height: int, count: int, dtype, crs_wkt: str, transform,
                 nodata) -> Iterator[Callable[[np.ndarray, int, int], None]]:
    """Yield ``write(values, c0, r0)``: ``values`` ``(count, h, w)`` of ``dtype`` at the output
    pixel ``(c0, r0)`` of a ``width`` × ``height`` GeoTIFF of ``count`` bands in ``crs_wkt``,
    ``transform`` its north-up grid ``(a, 0, c, 0, e, f)`` (rasterio's order), ``nodata``
    its no-data value (module docstring: written to ``path`` atomically)."""
    profile = dict(driver="GTiff", width=width, height=height, count=count, dtype=dtype, crs=crs_wkt,
                   transform=Affine(*tuple(transform)[:6]), nodata=nodata, tiled=True, blockxsize=512,
                   blockysize=512, compress="deflate", BIGTIFF="IF_SAFER")
    with atomic_path(path, check=raster_check(width, height, count)) as part, \
            rasterio.open(str(part), "w", **profile) as dst:
        yield lambda values, c0, r0: dst.write(values, window=Window(c0, r0, values.shape[2], values.shape[1]))
