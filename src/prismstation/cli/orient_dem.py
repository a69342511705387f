"""``prismstation orient-dem PROJECT REFERENCE_DEM``: orientation with no GCP (Gonçalves, SRTM as ground control).

Exit status 0 when the orientation's σ (from the adjustment of every matched cell) reaches the
target, 3 (with one line on stderr: why, and what would help) when the terrain cannot fix the
shift field that well, too few patches matched or the adjustment failed: the orientation is then
stored and reported, but not trusted.
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
from prismstation.ops.orient_dem import (TARGET_M, SigmaSummary, apply_orientation, control_points,
                                         orient_from_dem)
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
    p.add_argument("--target-m", type=float, default=TARGET_M, metavar="M",
                   help=f"the planimetric and height σ the orientation must reach to be trusted, "
                        f"metres (default {TARGET_M:g})")
    p.add_argument("--with-gcps", action="store_true",
                   help="adjust the project's GCPs (those measured in F and B) together with the "
                        "reference DEM's patches: the GCPs fix the frame, the patches the shape over "
                        "the whole scene")
    p.add_argument("--json", metavar="OUT", help="write the report (with the patch shifts) as JSON")
    p.add_argument("--save", action="store_true", help="store the DEM orientation in the project")
    p.set_defaults(func=run)


def run(args) -> int:
    project = load_project(existing(args.project, "project"))
    require_workflow(project, "orient-dem", args.project)
    existing(args.reference, "reference DEM")
    gcps = control_points(project) if args.with_gcps else None
    result = orient_from_dem(project, args.reference, sigma_apriori_m=args.geolocation_sigma_m, gcps=gcps,
                             patch_m=args.patch_km * 1000, posting_m=args.posting, target_m=args.target_m,
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
    if gcps is not None:
        print(f"{len(gcps)} GCPs in the adjustment with the reference DEM's patches; the reference's own "
              f"offset from them (E, N, h): "
              f"{', '.join(f'{v:+.2f}' for v in (result.field or {}).get('offset', []))} m")
    print(f"expected from the terrain before the run: "
          f"{SigmaSummary.from_dict(result.expected_sigma_m or {}).text()}")
    adj = result.adjustment or {}
    print(f"{len(used)} of {len(result.patches)} patches used, {adj.get('cells', 0)} cells in one adjustment; "
          f"each patch's own shift beyond its cells' noise σ_b (E, N, h) "
          f"{', '.join(f'{v:.2f}' for v in adj.get('sigma_b_m') or [])} m")
    for p in result.patches:
        state = "used" if p.used else f"not used: {p.reason}"
        if math.isfinite(p.dE):
            sig = ", ".join("—" if not math.isfinite(v) else f"{v:.2f}" for v in (p.sigma_E, p.sigma_N, p.sigma_h))
            shift = f"dE {p.dE:+7.2f} dN {p.dN:+7.2f} dh {p.dh:+7.2f} m  σ ({sig})"
        else:
            shift = "no shift"
        print(f"  patch at ({p.x:7.0f}, {p.y:7.0f}) px: {shift}  {state}")
    frame = "the GCPs'" if gcps is not None else "the reference DEM's"
    print(f"after the run: {SigmaSummary.from_dict(result.sigma_m).text()} (in {frame} frame)")
    print(f"verdict: {result.verdict.message}")
    if result.verdict.advice:
        print(f"  what would help: {result.verdict.advice}")
    print(format_report(report))
    if result.exit_status:
        print(f"prismstation orient-dem: NOT TRUSTED ({result.verdict.status}): {result.verdict.message}",
              file=sys.stderr)
    return result.exit_status
