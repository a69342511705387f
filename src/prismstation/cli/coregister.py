"""``prismstation coregister REFERENCE_DEM DEM --json OUT``: the 3-D shift laying DEM on REFERENCE_DEM.

DEM is resampled onto the reference grid (bilinear), then :func:`core.coreg.coregister`
estimates ``(dcol, drow, dz)``; FORMATS.md fixes the signs: ``shift_px`` is what to add to the
DEM's pixel positions, in reference-grid pixels, to lay it on the reference; ``dz`` is added to
its heights. Both DEMs must hold heights of the same kind (orthometric or ellipsoidal).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from prismstation.errors import InputError


def register(subparsers) -> None:
    p = subparsers.add_parser("coregister", help="3-D shift that aligns DEM to REFERENCE_DEM",
                              description=__doc__.splitlines()[0])
    p.add_argument("reference", metavar="REFERENCE_DEM", help="reference DEM (GeoTIFF, SRTM .hgt, ...)")
    p.add_argument("dem", metavar="DEM", help="DEM to align (any CRS; resampled onto the reference grid)")
    p.add_argument("--json", metavar="OUT", help="write the result as JSON")
    p.add_argument("--resampling", default="auto",
                   help="how DEM is resampled onto the reference grid: a rasterio name, or auto "
                        "(average when DEM is more than twice finer, else bilinear; the default)")
    p.add_argument("--method", choices=["lsm", "nuth-kaab"], default="lsm",
                   help="least-squares surface matching (default) or Nuth & Kääb (2011)")
    p.set_defaults(func=run)


METHODS = {"lsm": "least-squares surface matching (3-D translation)",
           "nuth-kaab": "Nuth & Kääb (2011) slope/aspect fit"}


def result_dict(res, reference: str, dem: str, method: str = "lsm") -> dict:
    """The JSON document of FORMATS.md (``shift_px``, ``shift_crs``, ``dz`` and their σ)."""
    f = float
    return {
        "reference": reference, "dem": dem,
        "shift_px": {"dcol": f(res.dcol), "drow": f(res.drow)},
        "sigma_px": {"dcol": f(res.sigma_dcol), "drow": f(res.sigma_drow)},
        "shift_crs": {"dx": f(res.dx), "dy": f(res.dy)},
        "sigma_crs": {"dx": f(res.sigma_dx), "dy": f(res.sigma_dy)},
        "dz": f(res.dz), "sigma_dz": f(res.sigma_dz),
        "iterations": int(res.iterations), "count": int(res.count), "converged": bool(res.converged),
        "nmad_before": f(res.nmad_before), "nmad_after": f(res.nmad_after),
        "mean_after": f(res.mean_after), "std_after": f(res.std_after),
        "method": METHODS[method],
    }


def run(args) -> int:
    from prismstation.core.coreg import coregister, nuth_kaab
    from prismstation.io.dem import read_dem

    ref = read_dem(args.reference)
    dem = read_dem(args.dem, ref.crs, ref.transform, ref.shape, resampling=args.resampling)
    both = np.isfinite(ref.heights) & np.isfinite(dem.heights)
    if both.sum() < 100:
        raise InputError(f"the DEMs overlap on {int(both.sum())} valid cells only; "
                         "need 100 or more", file=args.dem)
    estimate = nuth_kaab if args.method == "nuth-kaab" else coregister
    res = estimate(ref.heights, dem.heights, tuple(ref.transform)[:6])
    doc = result_dict(res, args.reference, args.dem, args.method)
    if not res.converged:
        doc["warning"] = "the adjustment did not converge"
    print(f"shift: dcol {res.dcol:+.3f} ± {res.sigma_dcol:.3f} px, drow {res.drow:+.3f} ± "
          f"{res.sigma_drow:.3f} px; dx {res.dx:+.2f} m, dy {res.dy:+.2f} m, dz {res.dz:+.2f} ± "
          f"{res.sigma_dz:.2f} m; NMAD {res.nmad_before:.2f} → {res.nmad_after:.2f} m "
          f"over {res.count} cells" + ("" if res.converged else " (NOT CONVERGED)"))
    if args.json:
        out = Path(args.json)
        try:
            out.write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
        except OSError as exc:
            raise InputError(f"cannot write: {exc}", file=out) from None
    return 0
