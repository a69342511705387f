"""DSM validation against a reference DSM of another resolution or CRS (docs/model.md §5; Tadono et al. 2008).

The reference is resampled (``rasterio.warp``, bilinear by default) onto the grid of the DSM;
heights are made one kind (orthometric → ellipsoidal through a geoid object with
``undulation(E, N, crs)``, e.g. :mod:`prismstation.io.geoid`); statistics of DSM − reference are
taken over the cells where both are valid. Heights in metres; no data is NaN in memory.
"""
from __future__ import annotations

import numpy as np

from prismstation.core.surfaces.dsmstats import DsmValidation, validate_dsm
from prismstation.errors import InputError
from prismstation.io.dem import open_raster, read_dem, resample_to_grid, write_dem
from prismstation.io.geoid import undulation_on_grid
from prismstation.model.points import HEIGHT_KINDS
from prismstation.ops.progress import ProgressFn, checkpoint


def validate_dsm_files(dsm_path, reference_path, *, dsm_height: str = "ellipsoidal",
                       reference_height: str = "ellipsoidal", geoid=None, mask_path=None,
                       mask_nodata=None, resampling: str = "bilinear",
                       diff_out=None, progress: ProgressFn | None = None) -> tuple[DsmValidation, dict]:
    """Validate a DSM against a reference DSM on the DSM's grid.

    Parameters
    ----------
    dsm_height, reference_height : ``"ellipsoidal"`` or ``"orthometric"``; an orthometric
        surface is made ellipsoidal with ``geoid.undulation(E, N, crs)`` when the two differ.
    mask_path : optional class raster, resampled (nearest) onto the DSM grid; statistics per
        class value (``mask_nodata`` or the raster's nodata excluded).
    diff_out : optional path of a float32 GeoTIFF of DSM − reference (NaN = no data).
    progress : per :mod:`prismstation.ops.progress`; a cancel raises
        :class:`~prismstation.errors.Cancelled` and writes no difference raster.

    Returns
    -------
    (validation, info) with info describing grid, height handling and inputs.
    """
    for kind in (dsm_height, reference_height):
        if kind not in HEIGHT_KINDS:
            raise InputError(f"height kind {kind!r} is not one of {', '.join(HEIGHT_KINDS)}")
    checkpoint(progress, 0.0, "reading the DSM")
    grid = read_dem(dsm_path, what="DSM")
    checkpoint(progress, 0.3, "resampling the reference")
    ref = resample_to_grid(reference_path, grid, resampling=resampling)
    checkpoint(progress, 0.6, "comparing")
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
        with open_raster(mask_path, "mask") as ds:
            nod = ds.nodata if mask_nodata is None else mask_nodata
        fill = -2147483648 if nod is None else nod
        classes = resample_to_grid(mask_path, grid, resampling="nearest", what="mask",
                                   dtype=np.float64, fill=fill)
        mask_nodata = fill
        info["mask"] = str(mask_path)
    result = validate_dsm(dsm, ref, classes=classes, class_nodata=mask_nodata)
    checkpoint(progress, 0.9, "statistics done")
    if diff_out is not None:
        write_dem(diff_out, np.where(both, dsm - ref, np.nan), grid.crs, grid.transform)  # atomic
        info["difference_raster"] = str(diff_out)
    checkpoint(progress, 1.0, "done")
    return result, info
