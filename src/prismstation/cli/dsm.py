"""``prismstation dsm PROJECT -o dsm.tif [--posting m] [--window c r w h] [--reference DEM]
[--orthometric] [--fill] [--min-fill %] [--heights auto|line|rays] [--scheduler ADDRESS]``: the project's DSM as a COG GeoTIFF.

The export is the sensor model's (:func:`prismstation.ops.sensors.workflows_of`: a PRISM
triplet's :func:`prismstation.ops.dsm_export.export_dsm`, images with RPCs
:func:`prismstation.ops.rpc_project.export_dsm`, which prints the pairs' agreement), the same
as the window's. Exit status 3 (after writing the file) when fewer than ``--min-fill``
percent of the seen cells (all images, or for images with RPCs any two) got a matched height, or when a bias the data cannot
determine decides the heights (:func:`prismstation.ops.fit.heights_not_fixed`: no GCP, no
reference DEM in the project's stored orientation), said in one line. ``--window``, ``--fill``,
``--scheduler`` and ``--workers`` mean the same for both models; the RPC DSM is written tile
by tile, whatever its size (:mod:`prismstation.ops.rpc_dsm_export`).
"""
from __future__ import annotations

import sys
from pathlib import Path

from prismstation.cli._common import end_progress, existing, progress_printer
from prismstation.io.formatting import fixed
from prismstation.io.project import load_project
from prismstation.ops.dsm_export import HEIGHT_MODELS, DsmRequest
from prismstation.ops.fit import heights_not_fixed, stale_orientation, stored_solution
from prismstation.ops.project import require_workflow
from prismstation.ops.reference_heights import load_for_scene
from prismstation.ops.sensors import workflows_of

LOW_FILL_STATUS = 3


def register(sub) -> None:
    p = sub.add_parser("dsm", help="semi-global matching of the three pairs → DSM GeoTIFF (COG)")
    p.add_argument("project")
    p.add_argument("-o", "--output", required=True, help="DSM GeoTIFF to write")
    p.add_argument("--window", nargs=4, type=int, metavar=("COL", "ROW", "W", "H"),
                   help="window in pixels of the N image (a triplet) or of the first image (images "
                        "with RPCs); default the whole image")
    p.add_argument("--posting", type=float, default=5.0, help="grid posting, m (default 5 = 2 × GSD)")
    p.add_argument("--orthometric", action="store_true", help="orthometric heights through the project's geoid")
    p.add_argument("--reference", metavar="DEM", help="reference DEM (orthometric through the project's geoid, unless the file states ellipsoidal heights) as the coarse prior")
    p.add_argument("--height-uncertainty", type=float, metavar="M",
                   help="a-priori ± height uncertainty of the prior, m (default: from the points, or 40 m with --reference)")
    p.add_argument("--fill", action="store_true", help="fill voids by interpolation (mask value 2)")
    p.add_argument("--min-fill", type=float, default=90.0, metavar="PERCENT",
                   help="exit with status 3 when fewer seen cells than this are matched (default 90)")
    p.add_argument("--heights", choices=HEIGHT_MODELS, default="auto",
                   help="heights from the model's parallax line, the rays through its biases, or "
                        "auto: the one the GCPs predict better, left out in turn (default)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="dask.distributed scheduler address (default: threads on this machine; 'processes' for processes)")
    p.add_argument("--workers", type=int, help="local threads or processes (default: the CPU count)")
    p.set_defaults(func=run)


def run(args) -> int:
    project = load_project(existing(args.project, "project"))
    require_workflow(project, "dsm", args.project)
    reference = None
    if args.reference:
        reference = load_for_scene(existing(args.reference, "reference DEM"), project)  # as the window does
    stale = stale_orientation(project)
    if stale:
        print(f"prismstation dsm: note: {stale}", file=sys.stderr)
    same = reference is not None and project.reference_dem and \
        Path(reference.path).resolve() == Path(project.reference_dem).resolve()
    sol, stored = stored_solution(project, reference=reference if same else None)  # the stored orientation
    reference = reference or stored

    request = DsmRequest(args.output, tuple(args.window) if args.window else None, args.posting,
                         args.orthometric, args.height_uncertainty, args.fill, args.min_fill,
                         args.heights, args.scheduler, args.workers)
    out = workflows_of(project).export_dsm(sol, project, request, reference=reference, progress=progress_printer())
    dsm = out.dsm
    end_progress()
    fill = out.fill_percent
    rows, cols = dsm.shape
    n = len(project.scene.views)
    seen_by = dsm.info.get("seen_by") or ('both' if n == 2 else 'all three' if n == 3 else f'all {n}')
    print(f"wrote {args.output}: {cols} × {rows} cells at {args.posting:g} m, {dsm.height_kind} heights, "
          f"{fill:.1f} % of the {out.seen_cells} cells {seen_by} "
          "images see matched" + (f", {out.filled_percent:.1f} % filled" if args.fill else ""))
    hm = dsm.info.get("heights")
    if hm:
        line = "the parallax line" if hm["model"] == "line" else "the rays through the biases"
        print(f"heights: {line} ({hm['reason']})")
    for pair, a in dsm.info.get("pair_agreement", {}).items():
        print(f"pairs {pair}: NMAD {fixed(a['nmad_m'])} m, median {fixed(a['median_m'])} m over {a['cells']} cells "
              f"({fixed(a['nmad_in_sigma'])} of their σ)")
    status = 0
    if out.low_fill:
        print(f"prismstation dsm: LOW FILL: only {fill:.1f} % of the seen cells matched "
              f"(threshold {args.min_fill:g} %); the voids are marked 0 in the mask band", file=sys.stderr)
        status = LOW_FILL_STATUS
    unfixed = heights_not_fixed(sol)
    if unfixed:
        print(f"prismstation dsm: HEIGHTS NOT FIXED: {unfixed}", file=sys.stderr)
        status = LOW_FILL_STATUS
    return status
