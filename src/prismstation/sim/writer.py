"""Writing the simulator's files: GeoTIFFs (rasterio), JSON and CSV, each atomically
(:mod:`prismstation.io.atomic`: a file is whole or absent; a failure is a ``WriteError``)."""
from __future__ import annotations

import csv
import io
import json
import warnings
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import rasterio
from rasterio.enums import Resampling
from rasterio.errors import NotGeoreferencedWarning
from rasterio.transform import Affine
from rasterio.windows import Window

from prismstation.io.atomic import atomic_path, raster_check, write_atomic
from prismstation.io.csvtable import text_cell
from prismstation.sim.terrain import Grid

TILE = 512


def _profile(width, height, dtype, geotransform, crs):
    profile = dict(driver="GTiff", width=width, height=height, count=1, dtype=dtype,
                   tiled=True, blockxsize=TILE, blockysize=TILE, compress="deflate",
                   BIGTIFF="IF_SAFER")
    if geotransform is not None:
        profile["transform"] = Affine.from_gdal(*geotransform)
        profile["crs"] = crs
    return profile


@contextmanager
def product_writer(path: Path, size: int, geotransform, crs, overviews: bool = False):
    """Open a ``size``² uint8 tiled (512) deflate GeoTIFF; yields ``write(rows, r0)``. The file
    is written beside ``path`` (with internal overviews when ``overviews``: :func:`add_overviews`)
    and renamed onto it when the block ends.

    ``geotransform`` is GDAL order (rotated terms allowed) or None for no georeferencing.
    """
    with warnings.catch_warnings(), rasterio.Env(GDAL_CACHEMAX=128), \
            atomic_path(path, check=raster_check(size, size, 1)) as tmp:  # MB: bounded memory
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        with rasterio.open(tmp, "w", **_profile(size, size, "uint8", geotransform, crs)) as dst:
            def write(rows: np.ndarray, r0: int):
                dst.write(rows, 1, window=Window(0, r0, rows.shape[1], rows.shape[0]))
            yield write
        if overviews:
            add_overviews(tmp, size)


def add_overviews(path: Path, size: int, minimum: int = 256) -> list[int]:
    """Internal overviews 2, 4, … down to ~``minimum`` px (average resampling)."""
    factors = []
    f = 2
    while size / f >= minimum:
        factors.append(f)
        f *= 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        with rasterio.Env(COMPRESS_OVERVIEW="DEFLATE"):
            with rasterio.open(path, "r+") as dst:
                dst.build_overviews(factors, Resampling.average)
    return factors


def write_grid(path: Path, grid: Grid, crs: str) -> None:
    """A north-up float32 grid as a tiled deflate GeoTIFF."""
    rows, cols = grid.values.shape
    profile = _profile(cols, rows, "float32", grid.geotransform, crs)
    profile["predictor"] = 3
    with atomic_path(path, check=raster_check(cols, rows, 1)) as tmp:
        with rasterio.open(tmp, "w", **profile) as dst:
            dst.write(grid.values.astype(np.float32), 1)


def write_json(path: Path, obj) -> None:
    write_atomic(path, json.dumps(obj, indent=2) + "\n", keep_backup=False)


def write_csv(path: Path, header: list[str], rows) -> None:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    w.writerows([text_cell(c) if isinstance(c, str) else c for c in row] for row in rows)
    write_atomic(path, buf.getvalue(), keep_backup=False)
