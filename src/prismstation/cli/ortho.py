"""``prismstation ortho PROJECT -o OUT.tif [--view N|F|B|IMAGE|all] [--dem DSM.tif|REFERENCE
[--dem-heights auto|orthometric|ellipsoidal] [--dem-sigma M]] [--height H] [--posting M]
[--window COL ROW W H] [--resampling bilinear|cubic] [--scheduler ADDRESS] [--json OUT]``: each
view's orthoimage as a COG GeoTIFF, through the project's fitted model (the fit ``prismstation
fit`` makes, with the same ``--bias``, ``--parallax``, ``--fixed-view``), the same as the
window's Tools ▸ Orthoimage… (:func:`prismstation.ops.ortho.export_orthos`).

Prints each file, its grid, the share of cells with data and its expected planimetric accuracy
(the orientation's σ and the DEM's height σ times the view's off-nadir tangent; the check
points' RMSE in the view beside it). Warnings (a constant height, a DEM whose heights' kind is
assumed) go to stderr.
"""
from __future__ import annotations

import sys

from prismstation.cli._common import add_model_options, apply_model_options, end_progress, existing, progress_printer
from prismstation.io.jsonfile import write_json
from prismstation.io.project import load_project
from prismstation.ops.fit import stored_solution
from prismstation.ops.ortho import DEM_KINDS, RESAMPLINGS, OrthoRequest, export_orthos


def register(sub) -> None:
    p = sub.add_parser("ortho", help="orthoimages of the views through the fitted model onto a DEM (COG)")
    p.add_argument("project")
    p.add_argument("-o", "--output", required=True,
                   help="GeoTIFF to write (several views: OUT_VIEW.tif beside it)")
    p.add_argument("--view", nargs="+", metavar="VIEW",
                   help="N, F, B, an image's file name, or all (default: the reference view)")
    p.add_argument("--dem", metavar="DEM",
                   help="heights to project onto: the project's DSM or a reference DEM (any CRS; heights as "
                        "the file states, else orthometric, made ellipsoidal through the project's geoid; "
                        "default: the project's reference DEM)")
    p.add_argument("--dem-heights", choices=DEM_KINDS, default="auto",
                   help="the DEM's heights (default auto: as the file states, else orthometric)")
    p.add_argument("--dem-sigma", type=float, metavar="M",
                   help="σ of the DEM's heights, m (default: measured at the project's points, else 10 m)")
    p.add_argument("--height", type=float, metavar="H",
                   help="without --dem: one orthometric height for every cell (a warning says what relief does)")
    p.add_argument("--posting", type=float, metavar="M", help="cell size, m (default: the reference view's pixel, to 2 figures)")
    p.add_argument("--window", nargs=4, type=int, metavar=("COL", "ROW", "W", "H"),
                   help="the ground under this window of the reference view's image, pixels (default: each whole image)")
    p.add_argument("--resampling", choices=RESAMPLINGS, default="bilinear")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="dask.distributed scheduler address (default: threads on this machine; 'processes' for processes)")
    p.add_argument("--workers", type=int, help="local threads or processes (default: the CPU count)")
    p.add_argument("--json", metavar="OUT", help="write what was made (grids, accuracy, warnings) as JSON")
    add_model_options(p, reference=False)
    p.set_defaults(func=run)


def run(args) -> int:
    project = load_project(existing(args.project, "project"))
    apply_model_options(project, args)
    if args.dem:
        existing(args.dem, "DEM")
    sol, _ = stored_solution(project)  # the project's stored orientation
    views = None if not args.view else tuple(args.view)
    request = OrthoRequest(args.output, views, args.dem, args.dem_heights, args.dem_sigma, args.height,
                           args.posting, tuple(args.window) if args.window else None, args.resampling,
                           args.scheduler, args.workers)
    out = export_orthos(sol, project, request, project_path=args.project, progress=progress_printer())
    end_progress()
    for w in out.warnings:
        print(f"prismstation ortho: warning: {w}", file=sys.stderr)
    print(f"heights: {out.heights}")
    for o in out.orthos:
        print(f"wrote {o.path}: view {o.view}, {o.shape[1]} × {o.shape[0]} cells at {abs(o.transform[0]):g} m, "
              f"{o.valid_percent:.1f} % with data")
        print(f"  {accuracy_line(o.accuracy)}")
    if args.json:
        write_json(args.json, export_record(out))
    return 0


def _m(v) -> str:
    return "unknown" if v is None else f"{v:.2f} m"


def accuracy_line(acc) -> str:
    """The expected planimetric accuracy in one line."""
    text = (f"expected planimetric accuracy {_m(acc.expected_sigma_m)} RMS (orientation {_m(acc.orientation_sigma_m)}"
            f" ⊕ DEM {_m(acc.dem_sigma_m)} × off-nadir tan {acc.off_nadir_tan:.3f})")
    if acc.check_count:
        text += f"; the fit's {acc.check_count} check points in this view: {acc.check_rmse_m:.2f} m RMS"
    for n in acc.notes:
        text += f"; {n}"
    return text


def export_record(out) -> dict:
    """What ``--json`` writes."""
    return {"heights": out.heights, "warnings": list(out.warnings),
            "orthos": [{"path": o.path, "view": o.view, "transform": list(o.transform), "shape": list(o.shape),
                        "valid_percent": o.valid_percent, "interpolation_max_px": o.max_error_px,
                        "accuracy": o.accuracy.as_dict(), "tags": o.tags} for o in out.orthos]}
