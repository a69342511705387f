"""``prismstation validate-ortho PROJECT ORTHO.tif [--kinds GCP ICP] [--json OUT] [--plot OUT.svg]``:
where an orthoimage of the project shows its GCPs and ICPs against their known ground positions
(:func:`prismstation.ops.ortho_validate.validate_ortho`: the view's own image resampled in the
ortho's geometry at the operator's measurement, matched in the ortho around the known position).

Prints each point's displacement (shown − known, metres east and north) beside what the fitted
model predicts for it, and the RMSE per kind against the ortho's expected accuracy.
"""
from __future__ import annotations

from prismstation.cli._common import add_model_options, apply_model_options, end_progress, existing, progress_printer
from prismstation.io.jsonfile import write_json
from prismstation.io.ortho_plot import write_ortho_svg
from prismstation.io.project import load_project
from prismstation.model.points import KINDS
from prismstation.ops.fit import stored_solution
from prismstation.ops.ortho_validate import validate_ortho


def register(sub) -> None:
    p = sub.add_parser("validate-ortho", help="an orthoimage's accuracy at the project's GCPs and ICPs")
    p.add_argument("project")
    p.add_argument("ortho", help="an orthoimage made by prismstation ortho from this project")
    p.add_argument("--kinds", nargs="+", choices=KINDS, default=["GCP", "ICP"], help="points to check (default GCP ICP)")
    p.add_argument("--json", metavar="OUT", help="every point's check and the statistics as JSON")
    p.add_argument("--plot", metavar="OUT.svg", help="the points' displacements over the ortho, as SVG")
    add_model_options(p, reference=False)
    p.set_defaults(func=run)


def run(args) -> int:
    project = load_project(existing(args.project, "project"))
    apply_model_options(project, args)
    existing(args.ortho, "orthoimage")
    sol, _ = stored_solution(project)  # the project's stored orientation
    val = validate_ortho(sol, project, args.ortho, kinds=tuple(args.kinds), progress=progress_printer())
    end_progress()
    for n in val.notes:
        print(f"note: {n}")
    print(f"{'id':<10} {'kind':<4} {'dE m':>7} {'dN m':>7} {'model dE':>9} {'model dN':>9} {'NCC':>5}")
    for p in val.points:
        if p.found:
            print(f"{p.id:<10} {p.kind:<4} {p.d[0]:7.2f} {p.d[1]:7.2f} {p.predicted[0]:9.2f} {p.predicted[1]:9.2f} "
                  f"{p.score:5.2f}")
        else:
            print(f"{p.id:<10} {p.kind:<4} not found: {p.reason or p.status}")
    exp = "unknown" if val.expected_sigma_m is None else f"{val.expected_sigma_m:.2f} m"
    print(f"view {val.view}, searched ±{val.search_px} cells of {val.posting_m:g} m; expected accuracy {exp} RMS")
    for kind, s in val.stats.items():
        if s["n"]:
            print(f"  {kind}: {s['n']} found, RMSE {s['rmse_m']:.2f} m (E {s['rmse_e_m']:.2f}, N {s['rmse_n_m']:.2f}), "
                  f"mean E {s['mean_e_m']:+.2f} N {s['mean_n_m']:+.2f}" +
                  (f"; {s['not_found']} not found" if s["not_found"] else ""))
        else:
            print(f"  {kind}: none found of {s['not_found']}")
    if args.json:
        write_json(args.json, val.as_dict())
    if args.plot:
        write_ortho_svg(args.plot, val, args.ortho)
        print(f"wrote {args.plot}")
    return 0
