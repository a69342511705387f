"""``prismstation coregister REFERENCE_DEM DEM --json OUT``: the 3-D shift laying DEM on REFERENCE_DEM.

The use case is :func:`prismstation.ops.coregister.coregister_dems` (the method, the overlap
check and the default search radius); this module parses the arguments and prints or writes
its result.

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

import json
import sys
from pathlib import Path

from prismstation.io.atomic import write_atomic
from prismstation.ops.coregister import METHODS, coregister_dems, result_dict

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
    p.add_argument("--method", choices=list(METHODS), default="lsm",
                   help="least-squares surface matching (default) or Nuth & Kääb (2011)")
    p.add_argument("--max-shift-m", type=float, default=None, metavar="M",
                   help="a-priori bound of the horizontal shift, metres (default: a quarter of the "
                        "reference's extent); a shift beyond it is reported as no result")
    p.set_defaults(func=run)


def run(args) -> int:
    co = coregister_dems(args.reference, args.dem, method=args.method, max_shift_m=args.max_shift_m,
                         resampling=args.resampling)
    res = co.result
    doc = result_dict(res, args.reference, args.dem, args.method, co.transform)
    if args.json:
        write_atomic(Path(args.json), json.dumps(doc, indent=2, allow_nan=False) + "\n", keep_backup=False)
    if not co:
        print(f"prismstation coregister: no shift: {co.reason}", file=sys.stderr)
        return NOT_CONVERGED
    print(f"shift: dcol {res.dcol:+.3f} ± {res.sigma_dcol:.3f} px, drow {res.drow:+.3f} ± "
          f"{res.sigma_drow:.3f} px; dx {res.dx:+.2f} ± {res.sigma_dx:.2f} m, dy {res.dy:+.2f} ± "
          f"{res.sigma_dy:.2f} m (east, north); dz {res.dz:+.2f} ± {res.sigma_dz:.2f} m; "
          f"NMAD {res.nmad_before:.2f} → {res.nmad_after:.2f} m over {res.count} cells")
    return 0
