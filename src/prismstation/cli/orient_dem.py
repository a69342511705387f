"""``prismstation orient-dem PROJECT REFERENCE_DEM``: orientation with no GCP (Gonçalves, SRTM as ground control).

A PRISM triplet: exit status 0 when the orientation's σ (from the adjustment of every matched
cell) reaches the target, 3 (with one line on stderr: why, and what would help) when the
terrain cannot fix the shift field that well, too few patches matched or the adjustment
failed: the orientation is then stored and reported, but not trusted. Images with RPCs: the
relative DSM laid on the reference gives each image's bias with its σ
(:func:`prismstation.ops.rpc_project.orient_rpc_project`); ``--save`` stores them as the fit's
a-priori biases; a failed co-registration is refused with its reason, exit status 3, nothing
stored. The functions are the sensor model's (:mod:`prismstation.ops.workflows`).
"""
from __future__ import annotations

import math
import sys

from prismstation.cli._common import end_progress, existing, progress_printer
from prismstation.io.lock import refuse_if_held
from prismstation.io.project import load_project, save_project
from prismstation.io.report import write_report
from prismstation.io.text_report import format_report
from prismstation.ops.coarse_offsets import SIGMA_APRIORI_M
from prismstation.ops.coregister import result_dict
from prismstation.ops.fit import fit_report, solve_project
from prismstation.ops.orient_dem import (TARGET_M, SigmaSummary, apply_orientation, control_points,
                                         orient_from_dem)
from prismstation.ops.project import require_workflow
from prismstation.ops.rpc_project import json_safe, orientation_biases
from prismstation.ops.workflows import workflows


def register(sub) -> None:
    p = sub.add_parser("orient-dem", help="orient the triplet from a reference DEM (SRTM), no GCP")
    p.add_argument("project")
    p.add_argument("reference", help="reference DEM: SRTM .hgt or GeoTIFF, orthometric heights")
    p.add_argument("--geolocation-sigma-m", type=float, metavar="M",
                   help="a-priori σ of each view's ancillary geolocation, per component, metres; "
                        "every search covers 3 σ (default 50: the ~50 m shifts Gonçalves reports "
                        "for uncalibrated products; about 10 for calibrated ones; images with RPCs: "
                        "a 100 m search)")
    p.add_argument("--patch-km", type=float, default=4.0, help="patch size (default 4 km)")
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
    return RUN[project.scene.sensor.name](project, args)


def _run_rpc(project, args) -> int:
    """Images with RPCs: the relative DSM laid on the reference → each image's bias."""
    sol = solve_project(project)
    sigma = args.geolocation_sigma_m
    orientation, dsm = workflows(project).orient(sol, project, args.reference, posting_m=args.posting,
                                                 max_shift_m=None if sigma is None else 3.0 * sigma,
                                                 progress=progress_printer())
    end_progress()
    doc = {"coregistration": result_dict(orientation.coreg, str(args.reference), "relative DSM",
                                         crs_transform=tuple(dsm.transform)[:6]),
           "posting_m": dsm.posting_m, "fill": dsm.fill_fraction}
    if not orientation:
        print(f"prismstation orient-dem: REFUSED: the images' DSM could not be laid on the reference: "
              f"{orientation.coreg.reason}", file=sys.stderr)
        if args.json:
            write_report(json_safe(doc), args.json)
        return 3
    s, sg = orientation.shift_m, orientation.sigma_m
    print(f"relative DSM at {dsm.posting_m:.1f} m ({100 * dsm.fill_fraction:.0f} % matched) laid on "
          f"{args.reference}: the block moves dE {s[0]:+.2f} ± {sg[0]:.2f}, dN {s[1]:+.2f} ± {sg[1]:.2f}, "
          f"dh {s[2]:+.2f} ± {sg[2]:.2f} m")
    doc["biases"] = orientation_biases(project, orientation)
    for v, b in doc["biases"].items():
        print(f"  {v}: {b['model']} bias " + ", ".join(f"{n} {p:+.3f} ± {q:.3f}" for n, p, q in
                                                      zip(b["names"], b["params"], b["sigma"]))
              + " (change " + ", ".join(f"{x:+.3f}" for x in b["change"]) + ")")
    workflows(project).apply_orientation(project, orientation, args.reference)
    if args.save:
        save_project(project, args.project)
        print(f"saved in {args.project} as the fit's a-priori biases (no view held fixed)")
    _, report = fit_report(project, args.project)
    doc["report"] = report
    if args.json:
        write_report(json_safe(doc), args.json)
    print(format_report(report))
    return 0


def _run_prism(project, args) -> int:
    sigma = SIGMA_APRIORI_M if args.geolocation_sigma_m is None else args.geolocation_sigma_m
    gcps = control_points(project) if args.with_gcps else None
    result = orient_from_dem(project, args.reference, sigma_apriori_m=sigma, gcps=gcps,
                             patch_m=args.patch_km * 1000, posting_m=30.0 if args.posting is None else args.posting,
                             target_m=args.target_m,
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


#: the orientation of each sensor model (its name → the command's run)
RUN = {"prism": _run_prism, "rpc": _run_rpc}
