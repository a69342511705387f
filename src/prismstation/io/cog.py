"""Cloud-Optimized GeoTIFFs written piece by piece: the one way prismstation writes a large
raster (the DSM, an orthoimage).

:func:`write_cog` hands its caller an uncompressed tiled GeoTIFF in the system's temporary
folder (``TMPDIR``) to fill window by window — nothing grid-sized need be held in memory — then
copies it into a COG (tiled 256 × 256, deflate with a predictor, internal overviews, an internal
mask when the caller wrote one) beside the target, reads it back and renames it over the target
(:mod:`prismstation.io.atomic`): a failure leaves no file and is a
:class:`~prismstation.errors.WriteError` naming the target, or the scratch copy when the
temporary folder is what failed. An error of prismstation's own raised while filling (a cancel,
an image that cannot be read) passes through as it is, and no file is left either.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Callable

import rasterio
from rasterio._err import CPLE_BaseError
from rasterio.errors import RasterioError
from rasterio.shutil import copy as rio_copy

from prismstation.errors import PrismError, WriteError
from prismstation.io.atomic import (FreeSpaceWatch, atomic_path, free_bytes, raster_check, scratch_file,
                                    write_error)

BLOCK = 256


def write_cog(path, profile: dict, fill: Callable, *, before_keep=None, what: str = "raster",
              overview_resampling: str = "AVERAGE") -> None:
    """Write a COG at ``path``: ``fill(ds)`` writes the scratch dataset ``ds`` (rasterio, opened
    for writing and reading back with ``profile`` — driver, size, bands, dtype, CRS, transform,
    nodata — made tiled 256 × 256 here); its tags, band names and mask go into the COG. ``before_keep()``, when
    given, is called once the COG is written and checked, before it replaces ``path``: whatever
    it raises (a cancel) leaves ``path`` as it was. ``what`` names the scratch file
    (``prismstation-WHAT-<owner>_…``: :func:`prismstation.io.atomic.scratch_file`, a killed run's
    removed by the next)."""
    path = Path(path)
    profile = dict(profile, driver="GTiff", tiled=True, blockxsize=BLOCK, blockysize=BLOCK)
    cols, rows, count = profile["width"], profile["height"], profile["count"]
    check = raster_check(cols, rows, count)
    plain = None
    try:
        with rasterio.Env(GDAL_PAM_ENABLED="NO", GDAL_TIFF_INTERNAL_MASK="YES"), \
                atomic_path(path, check=_check_then(check, before_keep)) as tmp:
            watch = None
            try:
                plain = str(scratch_file(what, ".tif"))  # (a killed run's: removed first)
                with FreeSpaceWatch(tempfile.gettempdir()) as watch, rasterio.open(plain, "w+", **profile) as ds:
                    fill(ds)
                check(Path(plain))
            except PrismError as exc:
                if not isinstance(exc, WriteError):
                    raise             # a cancel, a read that failed: as it is
                raise WriteError(f"cannot write the scratch copy of {path.name}: "
                                 f"{exc.problem.removeprefix('cannot write: ')}", plain) from None
            except (RasterioError, CPLE_BaseError, OSError) as exc:
                scratch = plain or tempfile.gettempdir()
                raise write_error(scratch, exc, f"cannot write the scratch copy of {path.name}",
                                  free=_least(watch, tempfile.gettempdir())) from None
            try:
                with FreeSpaceWatch(path.parent) as watch, rasterio.open(plain) as src:
                    rio_copy(src, tmp, driver="COG", COMPRESS="DEFLATE", PREDICTOR="YES", BLOCKSIZE=BLOCK,
                             OVERVIEWS="AUTO", OVERVIEW_RESAMPLING=overview_resampling, GEOTIFF_VERSION="1.1",
                             NUM_THREADS="ALL_CPUS")
            except (RasterioError, CPLE_BaseError) as exc:  # the free space when it failed, not after
                raise write_error(path, exc, free=_least(watch, path.parent)) from None
    finally:
        for f in (plain, f"{plain}.aux.xml", f"{plain}.msk") if plain else ():
            if os.path.exists(f):
                os.unlink(f)


def _least(watch, folder) -> int | None:
    """The least free space ``watch`` saw (GDAL frees its temporaries before it raises), else
    the free space now."""
    least = getattr(watch, "least", None)
    return least if least is not None else free_bytes(folder)


def _check_then(check, before_keep):
    """``check``, then ``before_keep()`` (if given): the last step before the rename."""
    if before_keep is None:
        return check

    def both(tmp: Path) -> None:
        check(tmp)
        before_keep()
    return both
