"""DSM validation against a reference DSM of another resolution or CRS (MODEL.md §5, seed 004).

The reference is resampled (``rasterio.warp``, bilinear by default) onto the grid of the DSM;
heights are made one kind (orthometric → ellipsoidal through a geoid object with
``undulation(E, N, crs)``, e.g. :mod:`prismstation.io.geoid`); statistics of DSM − reference are
taken over the cells where both are valid. Heights in metres; no data is NaN in memory.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from prismstation.core.dsmstats import DsmValidation, validate_dsm
from prismstation.errors import InputError, RasterReadError

HEIGHT_KINDS = ("ellipsoidal", "orthometric")


@dataclass(frozen=True, eq=False)
class DemGrid:
    """A DEM read into memory: ``heights`` (rows, cols) float64 with NaN for no data,
    ``transform`` (rasterio Affine, corner of the top-left cell) and ``crs``."""

    path: str
    heights: np.ndarray
    transform: object
    crs: object

    @property
    def shape(self) -> tuple[int, int]:
        return self.heights.shape


def _open(path, what: str):
    import rasterio

    p = Path(path)
    if not p.exists():
        raise InputError(f"{what} not found", file=p)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
            return rasterio.open(p)
    except rasterio.errors.RasterioIOError as exc:
        raise InputError(f"cannot open {what} as a raster ({exc})", file=p) from None


def read_dem(path, what: str = "DEM") -> DemGrid:
    """Read band 1 of a georeferenced DEM (nodata and non-finite values become NaN)."""
    with _open(path, what) as ds:
        if ds.crs is None:
            raise InputError(f"{what} has no coordinate reference system", file=path)
        try:
            a = ds.read(1, masked=True).astype(np.float64).filled(np.nan)
        except Exception as exc:
            raise RasterReadError(f"{path}: cannot read {what} ({exc})") from None
        a[~np.isfinite(a)] = np.nan
        return DemGrid(str(path), a, ds.transform, ds.crs)


def resample_to_grid(path, grid: DemGrid, *, resampling: str = "bilinear",
                     what: str = "reference", dtype=np.float64, fill=np.nan) -> np.ndarray:
    """Band 1 of raster ``path`` resampled onto ``grid`` (its transform, CRS and shape)."""
    from rasterio.enums import Resampling
    from rasterio.warp import reproject

    with _open(path, what) as ds:
        if ds.crs is None:
            raise InputError(f"{what} has no coordinate reference system", file=path)
        out = np.full(grid.shape, fill, dtype=dtype)
        try:
            reproject(source=ds.read(1), destination=out, src_transform=ds.transform,
                      src_crs=ds.crs, src_nodata=ds.nodata, dst_transform=grid.transform,
                      dst_crs=grid.crs, dst_nodata=fill, resampling=Resampling[resampling])
        except Exception as exc:
            raise RasterReadError(f"{path}: cannot resample {what} onto the DSM grid ({exc})") from None
    return out


def undulation_on_grid(geoid, grid: DemGrid, max_samples: int = 256) -> np.ndarray:
    """Geoid undulation (m) at every cell centre of ``grid``: exact on a coarse lattice of at
    most ``max_samples`` per axis, bilinear in between (geoids vary over kilometres)."""
    rows, cols = grid.shape
    exact = rows * cols <= max_samples ** 2 or rows < 2 or cols < 2
    r = np.arange(rows) if exact else np.unique(np.linspace(0, rows - 1, max_samples).round())
    c = np.arange(cols) if exact else np.unique(np.linspace(0, cols - 1, max_samples).round())
    cc, rr = np.meshgrid(c + 0.5, r + 0.5)
    t = grid.transform
    e = t.c + cc * t.a + rr * t.b
    n = t.f + cc * t.d + rr * t.e
    u = np.asarray(geoid.undulation(e, n, grid.crs), float).reshape(cc.shape)
    if exact:
        return u
    if np.all(u == u.flat[0]):                    # a constant geoid
        return np.full(grid.shape, u.flat[0])
    # separable bilinear interpolation in cell-index space: along columns, then along rows
    along = np.stack([np.interp(np.arange(cols), c, row) for row in u])      # (len(r), cols)
    i = np.clip(np.searchsorted(r, np.arange(rows), side="right") - 1, 0, len(r) - 2)
    t = ((np.arange(rows) - r[i]) / (r[i + 1] - r[i]))[:, None]
    return (1 - t) * along[i] + t * along[i + 1]


def validate_dsm_files(dsm_path, reference_path, *, dsm_height: str = "ellipsoidal",
                       reference_height: str = "ellipsoidal", geoid=None, mask_path=None,
                       mask_nodata=None, resampling: str = "bilinear",
                       diff_out=None) -> tuple[DsmValidation, dict]:
    """Validate a DSM against a reference DSM on the DSM's grid.

    Parameters
    ----------
    dsm_height, reference_height : ``"ellipsoidal"`` or ``"orthometric"``; an orthometric
        surface is made ellipsoidal with ``geoid.undulation(E, N, crs)`` when the two differ.
    mask_path : optional class raster, resampled (nearest) onto the DSM grid; statistics per
        class value (``mask_nodata`` or the raster's nodata excluded).
    diff_out : optional path of a float32 GeoTIFF of DSM − reference (NaN = no data).

    Returns
    -------
    (validation, info) with info describing grid, height handling and inputs.
    """
    for kind in (dsm_height, reference_height):
        if kind not in HEIGHT_KINDS:
            raise InputError(f"height kind {kind!r} is not one of {', '.join(HEIGHT_KINDS)}")
    grid = read_dem(dsm_path, "DSM")
    ref = resample_to_grid(reference_path, grid, resampling=resampling)
    dsm = grid.heights
    info = {"dsm": str(dsm_path), "reference": str(reference_path),
            "grid": {"crs": grid.crs.to_string(), "width": grid.shape[1], "height": grid.shape[0],
                     "transform": list(grid.transform.to_gdal())},
            "heights": {"dsm": dsm_height, "reference": reference_height, "compared_as":
                        dsm_height if dsm_height == reference_height else "ellipsoidal"},
            "resampling": resampling}
    if dsm_height != reference_height:
        if geoid is None:
            raise InputError("the DSM and the reference have different height kinds: "
                             "give a geoid (constant or grid)")
        und = undulation_on_grid(geoid, grid)
        if dsm_height == "orthometric":
            dsm = dsm + und
        else:
            ref = ref + und
        info["heights"]["geoid"] = geoid.describe() if hasattr(geoid, "describe") else str(geoid)
        info["heights"]["mean_undulation_m"] = float(np.nanmean(und))
    both = np.isfinite(dsm) & np.isfinite(ref)
    if not both.any():
        raise InputError("the DSM and the reference have no valid cell in common "
                         "(do they overlap? are their CRSs right?)", file=reference_path)
    classes = None
    if mask_path is not None:
        with _open(mask_path, "mask") as ds:
            nod = ds.nodata if mask_nodata is None else mask_nodata
        fill = -2147483648 if nod is None else nod
        classes = resample_to_grid(mask_path, grid, resampling="nearest", what="mask",
                                   dtype=np.float64, fill=fill)
        mask_nodata = fill
        info["mask"] = str(mask_path)
    result = validate_dsm(dsm, ref, classes=classes, class_nodata=mask_nodata)
    if diff_out is not None:
        import rasterio

        d = np.where(both, dsm - ref, np.nan).astype(np.float32)
        with rasterio.open(diff_out, "w", driver="GTiff", width=grid.shape[1], height=grid.shape[0],
                           count=1, dtype="float32", crs=grid.crs, transform=grid.transform,
                           nodata=np.nan, compress="deflate") as out:
            out.write(d, 1)
        info["difference_raster"] = str(diff_out)
    return result, info
