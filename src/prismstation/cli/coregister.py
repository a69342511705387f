"""``prismstation coregister REFERENCE_DEM DEM --json OUT``: the 3-D shift laying DEM on REFERENCE_DEM.

DEM is resampled onto the reference grid (bilinear or average), then
:func:`core.coarse.dem_offset` searches the whole a-priori range (``--max-shift-m``) at coarse
resolution and :func:`core.coreg.coregister` refines ``(dcol, drow, dz)`` in reference-grid pixels. Geographic grids (EPSG:4326 SRTM .hgt,
Copernicus GLO-30/90 GeoTIFF) work as they are: the adjustment's metric quantities (slopes, the
shift in metres) use a local metric frame at the grid's centre (``io.dem.local_metric_transform``).

docs/formats.md fixes the signs: ``shift_px`` is what to add to the DEM's pixel positions, in
reference-grid pixels, to lay it on the reference; ``shift_m`` the same in metres (east, north)
at the grid's centre; ``shift_crs`` in CRS units (degrees for a geographic grid); ``dz`` is added
to its heights. Both DEMs must hold heights of the same kind (orthometric or ellipsoidal).

Exit status: 0 with a result; 2 on bad input; 3 when the adjustment did not give a result (did
not converge, left the a-priori bound ``--max-shift-m``, too little overlap): a one-line reason
on stderr, and the JSON (if asked) says ``"converged": false`` with the ``reason``. The JSON never
holds NaN: an undetermined number is ``null`` and ``nulls`` says why.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from prismstation.errors import InputError

NOT_CONVERGED = 3


def register(subparsers) -> None:
    p = subparsers.add_parser("coregister", help="3-D shift that aligns DEM to REFERENCE_DEM",
                              description=__doc__.splitlines()[0])
    p.add_argument("reference", metavar="REFERENCE_DEM",
                   help="reference DEM (GeoTIFF, SRTM .hgt, ...; geographic or projected)")
    p.add_argument("dem", metavar="DEM", help="DEM to align (any CRS; resampled onto the reference grid)")
    p.add_argument("--json", metavar="OUT", help="write the result as JSON")
    p.add_argument("--resampling", default="auto",
                   help="how DEM is resampled onto the reference grid: a rasterio name, or auto "
                        "(average when DEM is more than twice finer, else bilinear; the default)")
    p.add_argument("--method", choices=["lsm", "nuth-kaab"], default="lsm",
                   help="least-squares surface matching (default) or Nuth & Kääb (2011)")
    p.add_argument("--max-shift-m", type=float, default=None, metavar="M",
                   help="a-priori bound of the horizontal shift, metres (default: a quarter of the "
                        "reference's extent); a shift beyond it is reported as no result")
    p.set_defaults(func=run)


METHODS = {"lsm": "least-squares surface matching (3-D translation)",
           "nuth-kaab": "Nuth & Kääb (2011) slope/aspect fit"}


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


def run(args) -> int:
    from prismstation.core.coarse import dem_offset
    from prismstation.core.coreg import nuth_kaab
    from prismstation.io.dem import local_metric_transform, read_dem
    from prismstation.io.jsonfile import write_atomic

    if args.max_shift_m is not None and not (math.isfinite(args.max_shift_m) and args.max_shift_m > 0):
        raise InputError(f"--max-shift-m must be a positive number of metres, got {args.max_shift_m}")
    ref = read_dem(args.reference)
    dem = read_dem(args.dem, ref.crs, ref.transform, ref.shape, resampling=args.resampling)
    both = np.isfinite(ref.heights) & np.isfinite(dem.heights)
    if both.sum() < 100:
        raise InputError(f"the DEMs overlap on {int(both.sum())} valid cells only; "
                         "need 100 or more", file=args.dem)
    metric = local_metric_transform(ref.crs, ref.transform, ref.shape)
    if args.method == "nuth-kaab":
        res = nuth_kaab(ref.heights, dem.heights, metric)
    else:          # coarse exhaustive search over the a-priori range, then surface matching
        pixel = float(np.sqrt(abs(metric[0] * metric[4] - metric[1] * metric[3])))
        radius = args.max_shift_m if args.max_shift_m is not None else min(ref.shape) / 4 * pixel
        res = dem_offset(ref.heights, dem.heights, metric, radius)
    doc = result_dict(res, args.reference, args.dem, args.method, tuple(ref.transform)[:6])
    if args.json:
        import json
        out = Path(args.json)
        try:
            write_atomic(out, json.dumps(doc, indent=2, allow_nan=False) + "\n", keep_backup=False)
        except OSError as exc:
            raise InputError(f"cannot write: {exc}", file=out) from None
    if not res.converged:
        import sys
        print(f"prismstation coregister: no shift: {res.reason}", file=sys.stderr)
        return NOT_CONVERGED
    print(f"shift: dcol {res.dcol:+.3f} ± {res.sigma_dcol:.3f} px, drow {res.drow:+.3f} ± "
          f"{res.sigma_drow:.3f} px; dx {res.dx:+.2f} ± {res.sigma_dx:.2f} m, dy {res.dy:+.2f} ± "
          f"{res.sigma_dy:.2f} m (east, north); dz {res.dz:+.2f} ± {res.sigma_dz:.2f} m; "
          f"NMAD {res.nmad_before:.2f} → {res.nmad_after:.2f} m over {res.count} cells")
    return 0
