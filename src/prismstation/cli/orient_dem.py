"""``prismstation orient-dem PROJECT REFERENCE_DEM``: orientation with no GCP (Gonçalves, SRTM as ground control).

The orientation is the project's sensor model's (:func:`prismstation.ops.sensors.workflows_of`:
a PRISM triplet by patches of its relative DEM and one adjustment of the shift field, images
with RPCs by their relative DSM laid on the reference, each image's bias with its σ). Exit
status 0 when the verdict is ``ok``; 3, with one line on stderr (why, and what would help),
when it is not: a PRISM orientation whose σ does not reach the target (the terrain cannot fix
the shift field that well, too few patches matched, the adjustment failed) is stored and
reported but not trusted; an orientation with nothing to store (a co-registration of the
images' DSM that failed) is refused. ``--save`` stores it in the project (for images with
RPCs: the fit's a-priori biases, no view held fixed).
"""
from __future__ import annotations

import sys

from prismstation.cli._common import end_progress, existing, progress_printer
from prismstation.io.lock import refuse_if_held
from prismstation.io.project import load_project, save_project
from prismstation.io.report import write_report
from prismstation.io.text_report import format_report
from prismstation.ops.fit import orientation_record, project_report, stored_solution
from prismstation.ops.orientation import TARGET_M, OrientRequest, apply_orientation
from prismstation.ops.project import require_workflow
from prismstation.ops.sensors import workflows_of


def register(sub) -> None:
    p = sub.add_parser("orient-dem", help="orient the triplet from a reference DEM (SRTM), no GCP")
    p.add_argument("project")
    p.add_argument("reference", help="reference DEM: SRTM .hgt or GeoTIFF, orthometric heights through the "
                   "project's geoid (a file that states ellipsoidal heights: as they are)")
    p.add_argument("--geolocation-sigma-m", type=float, metavar="M",
                   help="a-priori σ of each view's ancillary geolocation, per component, metres; "
                        "every search covers 3 σ (default 50: the ~50 m shifts Gonçalves reports "
                        "for uncalibrated products; about 10 for calibrated ones; images with RPCs: "
                        "a 100 m search)")
    p.add_argument("--patch-km", type=float,
                   help="patch size, km (default: a quarter of the scene's shorter side, between 1 and 4 km: "
                        "4 km on a full PRISM scene, 2.5 km on a 10 km one)")
    p.add_argument("--posting", type=float,
                   help="grid posting of the matching, m (default 30; images with RPCs: 8 pixels)")
    p.add_argument("--target-m", type=float, default=TARGET_M, metavar="M",
                   help=f"the planimetric and height σ the orientation must reach to be trusted, "
                        f"metres (default {TARGET_M:g}; a PRISM triplet)")
    p.add_argument("--with-gcps", action="store_true",
                   help="adjust the project's GCPs (those measured in F and B) together with the "
                        "reference DEM's patches: the GCPs fix the frame, the patches the shape over "
                        "the whole scene (a PRISM triplet)")
    p.add_argument("--json", metavar="OUT", help="write the report (with the patch shifts) as JSON")
    p.add_argument("--save", action="store_true", help="store the DEM orientation in the project")
    p.set_defaults(func=run)


def run(args) -> int:
    if args.save:  # before the work: the window holding the project would drop what is saved
        refuse_if_held(args.project)
    project = load_project(existing(args.project, "project"))
    require_workflow(project, "orient-dem", args.project)
    existing(args.reference, "reference DEM")
    patch_m = None if args.patch_km is None else args.patch_km * 1000
    request = OrientRequest(args.geolocation_sigma_m, args.posting, patch_m, args.target_m, args.with_gcps)
    result = workflows_of(project).orient(project, args.reference, request, progress=progress_printer())
    end_progress()
    if result.record is None:
        print(f"prismstation orient-dem: REFUSED: {result.verdict.message}", file=sys.stderr)
        if args.json:
            write_report(result.json(None), args.json)
        return result.exit_status
    apply_orientation(project, result)
    sol, _ = stored_solution(project)
    report = project_report(project, sol, args.project)
    if args.save:
        project.set_orientation(orientation_record(project, sol))
        save_project(project, args.project)
    if args.json:
        write_report(result.json(report), args.json)
    for line in result.lines:
        print(line)
    if args.save:
        print(f"saved in {args.project}")
    print(format_report(report))
    if result.exit_status:
        print(f"prismstation orient-dem: NOT TRUSTED ({result.verdict.status}): {result.verdict.message}",
              file=sys.stderr)
    return result.exit_status
