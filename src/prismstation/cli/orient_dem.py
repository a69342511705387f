"""``prismstation orient-dem PROJECT REFERENCE_DEM``: orientation with no GCP (Gonçalves, SRTM as ground control).

Exit status 0 when the patch shifts agree with their σ, 3 (with one line on stderr) when they do
not or too few patches matched: the orientation is then stored and reported, but not trusted.
"""
from __future__ import annotations

import math
import sys

from prismstation.cli._common import end_progress, existing, progress_printer
from prismstation.io.project import load_project, save_project
from prismstation.io.report import write_report
from prismstation.io.text_report import format_report
from prismstation.ops.coarse_offsets import SIGMA_APRIORI_M
from prismstation.ops.fit import fit_report
from prismstation.ops.orient_dem import apply_orientation, orient_from_dem
from prismstation.ops.project import require_workflow


def register(sub) -> None:
    p = sub.add_parser("orient-dem", help="orient the triplet from a reference DEM (SRTM), no GCP")
    p.add_argument("project")
    p.add_argument("reference", help="reference DEM: SRTM .hgt or GeoTIFF, orthometric heights")
    p.add_argument("--geolocation-sigma-m", type=float, default=SIGMA_APRIORI_M, metavar="M",
                   help="a-priori σ of each view's ancillary geolocation, per component, metres; "
                        "every search covers 3 σ (default 50: the ~50 m shifts Gonçalves reports "
                        "for uncalibrated products; about 10 for calibrated ones)")
    p.add_argument("--patch-km", type=float, default=4.0, help="patch size (default 4 km)")
    p.add_argument("--posting", type=float, default=30.0, help="grid posting of the matching, m (default 30)")
    p.add_argument("--json", metavar="OUT", help="write the report (with the patch shifts) as JSON")
    p.add_argument("--save", action="store_true", help="store the DEM orientation in the project")
    p.set_defaults(func=run)


def run(args) -> int:
    project = load_project(existing(args.project, "project"))
    require_workflow(project, "orient-dem", args.project)
    existing(args.reference, "reference DEM")
    result = orient_from_dem(project, args.reference, sigma_apriori_m=args.geolocation_sigma_m,
                             patch_m=args.patch_km * 1000, posting_m=args.posting,
                             progress=progress_printer())
    end_progress()
    apply_orientation(project, result)
    if args.save:
        save_project(project, args.project)
    _, report = fit_report(project, args.project)
    report["dem_control"] = project.dem_control
    if args.json:
        write_report(report, args.json)
    used = [p for p in result.patches if p.used]
    off = result.offsets_px
    print(f"a-priori geolocation σ {result.sigma_apriori_m:g} m per view; F−N ({off['F'][0]:+.2f}, "
          f"{off['F'][1]:+.2f}) px, B−N ({off['B'][0]:+.2f}, {off['B'][1]:+.2f}) px from the ancillary model"
          " at N's centre")
    rows, cols = project.scene.views["N"].shape
    for v, g in (result.gradients_px or {}).items():
        if any(c for row in g for c in row):
            span = [abs(g[k][0]) * cols + abs(g[k][1]) * rows for k in range(2)]
            print(f"  {v}−N varies over N (attitude drift): up to ±{span[0] / 2:.2f} px in x, "
                  f"±{span[1] / 2:.2f} px in y from its centre value")
    first = result.coarse.get("first_pass")
    if first:
        moved = [max(abs(a - b) for a, b in zip(off[v], first["offsets_px"][v])) for v in "FB"]
        print(f"  second pass with N placed by the patches: the offsets moved by up to "
              f"{max(moved):.2f} px")
    elif result.coarse.get("second_pass"):
        print(f"  second pass {result.coarse['second_pass']}")
    print(f"{len(used)} of {len(result.patches)} patches matched the reference")
    for p in result.patches:
        state = "used" if p.used else f"not used: {p.reason}"
        if math.isfinite(p.dE):
            shift = (f"dE {p.dE:+7.2f} dN {p.dN:+7.2f} dh {p.dh:+7.2f} m  "
                     f"σ ({p.sigma_E:.2f}, {p.sigma_N:.2f}, {p.sigma_h:.2f})")
        else:
            shift = "no shift"
        print(f"  patch at ({p.x:7.0f}, {p.y:7.0f}) px: {shift}  {state}")
    print(f"verdict: {result.verdict.message}")
    sg = result.sigma_m
    print(f"orientation σ in the reference DEM's frame: E {sg['E']:.1f} m, N {sg['N']:.1f} m "
          f"(planimetric {result.sigma_plan_m:.1f} m), h {sg['h']:.1f} m")
    print(format_report(report))
    if result.exit_status:
        print(f"prismstation orient-dem: NOT TRUSTED ({result.verdict.status}): {result.verdict.message}",
              file=sys.stderr)
    return result.exit_status
