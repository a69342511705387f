"""DEM-to-DEM co-registration: the 3-D shift laying a DEM on a reference DEM.

DEM is resampled onto the reference grid (bilinear or average: ``io.dem.read_dem``), then
either :func:`core.matching.coarse.dem_offset` searches the whole a-priori range at coarse resolution
and :func:`core.matching.coreg.coregister` refines ``(dcol, drow, dz)`` in reference-grid pixels
(least-squares surface matching, the default), or Nuth & Kääb (2011) fits the slope/aspect
relation. Geographic grids (EPSG:4326 SRTM .hgt, Copernicus GLO-30/90 GeoTIFF) work as they
are: the adjustment's metric quantities use a local metric frame at the grid's centre
(``io.dem.local_metric_transform``). Signs and the JSON document: docs/formats.md.

The result is a :class:`~prismstation.core.matching.coreg.CoregResult`, falsy with a ``reason`` when
the adjustment gave no shift (the failure convention of :mod:`prismstation.core.adjustment.estimate`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from prismstation.core.matching.coarse import dem_offset
from prismstation.core.matching.coreg import CoregResult, nuth_kaab
from prismstation.errors import InputError
from prismstation.io.dem import local_metric_transform, read_dem

#: the methods, by their command-line names
METHODS = {"lsm": "least-squares surface matching (3-D translation)",
           "nuth-kaab": "Nuth & Kääb (2011) slope/aspect fit"}
#: fewest cells both DEMs must hold
MIN_OVERLAP_CELLS = 100
#: the a-priori bound of the horizontal shift when none is given: this share of the
#: reference's shorter side
DEFAULT_RADIUS_SHARE = 0.25


@dataclass(frozen=True)
class Coregistration:
    """A co-registration's result and the reference grid it is expressed on: ``transform``
    the reference's (rasterio order, CRS units), ``method`` a key of :data:`METHODS`."""

    result: CoregResult
    transform: tuple
    method: str

    def __bool__(self) -> bool:
        return bool(self.result)

    @property
    def reason(self) -> str:
        return self.result.reason


def coregister_dems(reference, dem, *, method: str = "lsm", max_shift_m: float | None = None,
                    resampling: str = "auto") -> Coregistration:
    """The 3-D shift laying the DEM file ``dem`` on the DEM file ``reference``.

    ``max_shift_m``: a-priori bound of the horizontal shift, metres (default a quarter of the
    reference's extent; a shift beyond it is no result). ``resampling``: a rasterio name or
    ``auto``. Bad input (unreadable files, fewer than :data:`MIN_OVERLAP_CELLS` common
    cells, a bound that is not a positive number) raises :class:`InputError`.
    """
    if method not in METHODS:
        raise InputError(f"unknown co-registration method {method!r}; choose one of {', '.join(METHODS)}")
    if max_shift_m is not None and not (math.isfinite(max_shift_m) and max_shift_m > 0):
        raise InputError(f"--max-shift-m must be a positive number of metres, got {max_shift_m}")
    ref = read_dem(reference)
    moving = read_dem(dem, ref.crs, ref.transform, ref.shape, resampling=resampling)
    both = np.isfinite(ref.heights) & np.isfinite(moving.heights)
    if both.sum() < MIN_OVERLAP_CELLS:
        raise InputError(f"the DEMs overlap on {int(both.sum())} valid cells only; "
                         f"need {MIN_OVERLAP_CELLS} or more", file=dem)
    metric = local_metric_transform(ref.crs, ref.transform, ref.shape)
    if method == "nuth-kaab":
        res = nuth_kaab(ref.heights, moving.heights, metric)
    else:          # coarse exhaustive search over the a-priori range, then surface matching
        pixel = float(np.sqrt(abs(metric[0] * metric[4] - metric[1] * metric[3])))
        radius = max_shift_m if max_shift_m is not None else min(ref.shape) * DEFAULT_RADIUS_SHARE * pixel
        res = dem_offset(ref.heights, moving.heights, metric, radius)
    return Coregistration(res, tuple(ref.transform)[:6], method)


def _num(v, key: str, nulls: dict, why: str):
    v = float(v)
    if math.isfinite(v):
        return v
    nulls[key] = why
    return None


def result_dict(res, reference: str, dem: str, method: str = "lsm", crs_transform=None) -> dict:
    """The JSON document of docs/formats.md: ``shift_px``, ``shift_m``, ``shift_crs``, ``dz``, their σ,
    ``converged`` and ``reason``; non-finite numbers are null, explained in ``nulls``.
    ``crs_transform`` (a, b, c, d, e, f) converts the pixel shift into CRS units (default: the
    metric frame's, i.e. ``shift_crs`` = ``shift_m``)."""
    nulls: dict = {}
    why = res.reason or "undetermined (no redundancy)"

    def n(key, v):
        return _num(v, key, nulls, why)

    a, b, _, d, e, _ = (tuple(crs_transform)[:6] if crs_transform is not None
                        else (1.0, 0.0, 0.0, 0.0, 1.0, 0.0))
    if crs_transform is not None:
        dx_crs, dy_crs = a * res.dcol + b * res.drow, d * res.dcol + e * res.drow
        j = np.array([[a, b], [d, e]])
        # σ in CRS units from the pixel σ's (their correlation is not kept in CoregResult)
        cov = j @ np.diag([res.sigma_dcol ** 2, res.sigma_drow ** 2]) @ j.T
        sx_crs, sy_crs = np.sqrt(np.diag(cov))
    else:
        dx_crs, dy_crs, sx_crs, sy_crs = res.dx, res.dy, res.sigma_dx, res.sigma_dy
    doc = {
        "reference": reference, "dem": dem,
        "converged": bool(res.converged), "reason": res.reason,
        "shift_px": {"dcol": n("shift_px.dcol", res.dcol), "drow": n("shift_px.drow", res.drow)},
        "sigma_px": {"dcol": n("sigma_px.dcol", res.sigma_dcol), "drow": n("sigma_px.drow", res.sigma_drow)},
        "shift_m": {"dx": n("shift_m.dx", res.dx), "dy": n("shift_m.dy", res.dy)},
        "sigma_m": {"dx": n("sigma_m.dx", res.sigma_dx), "dy": n("sigma_m.dy", res.sigma_dy)},
        "shift_crs": {"dx": n("shift_crs.dx", dx_crs), "dy": n("shift_crs.dy", dy_crs)},
        "sigma_crs": {"dx": n("sigma_crs.dx", sx_crs), "dy": n("sigma_crs.dy", sy_crs)},
        "dz": n("dz", res.dz), "sigma_dz": n("sigma_dz", res.sigma_dz),
        "iterations": int(res.iterations), "count": int(res.count),
        "nmad_before": n("nmad_before", res.nmad_before), "nmad_after": n("nmad_after", res.nmad_after),
        "mean_after": n("mean_after", res.mean_after), "std_after": n("std_after", res.std_after),
        "method": METHODS[method],
    }
    if nulls:
        doc["nulls"] = nulls
    return doc
