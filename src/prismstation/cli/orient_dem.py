"""``prismstation orient-dem PROJECT REFERENCE_DEM``: orientation with no GCP (seed 003)."""
from __future__ import annotations

from prismstation.cli._common import end_progress, existing, progress_printer
from prismstation.io.project import load_project, save_project
from prismstation.io.report import write_report
from prismstation.io.text_report import format_report
from prismstation.ops.fit import fit_report
from prismstation.ops.orient_dem import apply_orientation, orient_from_dem


def register(sub) -> None:
    p = sub.add_parser("orient-dem", help="orient the triplet from a reference DEM (SRTM), no GCP")
    p.add_argument("project")
    p.add_argument("reference", help="reference DEM: SRTM .hgt or GeoTIFF, orthometric heights")
    p.add_argument("--patch-km", type=float, default=4.0, help="patch size (default 4 km)")
    p.add_argument("--posting", type=float, default=30.0, help="grid posting of the matching, m (default 30)")
    p.add_argument("--json", metavar="OUT", help="write the report (with the patch shifts) as JSON")
    p.add_argument("--save", action="store_true", help="store the DEM orientation in the project")
    p.set_defaults(func=run)


def run(args) -> int:
    project = load_project(existing(args.project, "project"))
    existing(args.reference, "reference DEM")
    result = orient_from_dem(project, args.reference, patch_m=args.patch_km * 1000,
                             posting_m=args.posting, progress=progress_printer())
    end_progress()
    apply_orientation(project, result)
    if args.save:
        save_project(project, args.project)
    _, report = fit_report(project, args.project)
    report["dem_control"] = project.dem_control
    if args.json:
        write_report(report, args.json)
    used = [p for p in result.patches if p.used]
    print(f"{len(used)} of {len(result.patches)} patches matched the reference; "
          f"{result.ties} tie points; F−N {result.across_px['F']:+.2f} px, B−N {result.across_px['B']:+.2f} px across track")
    for p in result.patches:
        state = "used" if p.used else f"rejected: {p.reason}"
        print(f"  patch at ({p.x:7.0f}, {p.y:7.0f}) px: dE {p.dE:+7.2f} dN {p.dN:+7.2f} dh {p.dh:+7.2f} m  "
              f"σ ({p.sigma_E:.2f}, {p.sigma_N:.2f}, {p.sigma_h:.2f})  {state}")
    print(format_report(report))
    return 0
