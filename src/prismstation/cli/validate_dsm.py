"""``prismstation validate-dsm DSM REFERENCE --json OUT`` (docs/formats.md, docs/model.md §5).

Statistics of DSM − reference (metres) over the cells where both are valid, on the DSM's grid:
bias, sd, rmse, min, max, count, nmad, median, percentiles, and per class of ``--mask``.
"""
from __future__ import annotations

from prismstation.cli._common import end_progress, progress_printer
from prismstation.errors import InputError
from prismstation.io.geoid import ConstantGeoid, GridGeoid
from prismstation.io.jsonfile import write_json
from prismstation.model.points import HEIGHT_KINDS
from prismstation.ops.validate import validate_dsm_files


def register(sub) -> None:
    p = sub.add_parser("validate-dsm", help="DSM accuracy against a reference DSM")
    p.add_argument("dsm")
    p.add_argument("reference")
    p.add_argument("--json", metavar="OUT", required=True, help="statistics as JSON")
    p.add_argument("--mask", metavar="M.tif", help="class raster: statistics per class value")
    p.add_argument("--mask-nodata", type=float, help="mask value to leave out (default: its nodata)")
    p.add_argument("--dsm-height", choices=HEIGHT_KINDS, default="ellipsoidal")
    p.add_argument("--reference-height", choices=HEIGHT_KINDS, default="ellipsoidal")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--geoid-constant", type=float, metavar="N", help="geoid undulation (m)")
    g.add_argument("--geoid-grid", metavar="GRID", help="geoid grid (e.g. egm96_15.gtx)")
    p.add_argument("--resampling", choices=("bilinear", "cubic", "nearest"), default="bilinear")
    p.add_argument("--diff-out", metavar="DIFF.tif", help="write DSM − reference as GeoTIFF")
    p.set_defaults(func=run)


def _geoid(args):
    if args.geoid_constant is not None:
        return ConstantGeoid(args.geoid_constant)
    if args.geoid_grid:
        return GridGeoid(args.geoid_grid)
    if args.dsm_height != args.reference_height:
        raise InputError(f"DSM heights are {args.dsm_height}, reference heights "
                         f"{args.reference_height}: give --geoid-constant or --geoid-grid")
    return None


def run(args) -> int:
    val, info = validate_dsm_files(args.dsm, args.reference, dsm_height=args.dsm_height,
                                   reference_height=args.reference_height, geoid=_geoid(args),
                                   mask_path=args.mask, mask_nodata=args.mask_nodata,
                                   resampling=args.resampling, diff_out=args.diff_out,
                                   progress=progress_printer())
    end_progress()
    out = val.as_dict()
    out.update(info)
    write_json(args.json, out)
    o = val.overall
    print(f"DSM − reference over {o.count} cells ({info['heights']['compared_as']} heights):")
    print(f"  bias {o.bias:.3f} m  sd {o.sd:.3f} m  rmse {o.rmse:.3f} m  "
          f"min {o.min:.3f} m  max {o.max:.3f} m  nmad {o.nmad:.3f} m")
    for k, s in sorted(val.per_class.items()):
        print(f"  class {k}: n {s.count}  bias {s.bias:.3f}  sd {s.sd:.3f}  rmse {s.rmse:.3f}  "
              f"nmad {s.nmad:.3f}")
    return 0
