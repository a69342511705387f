"""``prismstation transfer PROJECT [--points ID ...] [--dem DEM] [--csv OUT] [--json OUT]
[--save]``: the project's points measured in some views searched in the others.

Each point measured in some views and not in all is searched from its measurement in N (else
the first view it is in) in the views it lacks, as the window's Ctrl+T searches it
(:mod:`prismstation.ops.transfer_points`), through the project's stored fit (its settings, its
reference DEM or orientation from one; with no GCP, the products' own geometry and its
a-priori σ). ``--dem`` gives the searches a reference DEM's heights and slope (the project's
own reference DEM otherwise, when it names one). One line per point and view: where it was
found, its σ along the parallax (where a height moves it) and across, the correlation; or why
it was not. ``--csv`` writes the found measurements in the measurement CSV form, ``--json``
every search's result (docs/formats.md); ``--save`` adds the found ones to the project (saved
atomically) and refits. Progress on stderr; Ctrl+C stops it and nothing is written (exit
130). Exit status 3 when no point was found.
"""
from __future__ import annotations

import math
import sys

from prismstation.cli._common import end_progress, existing, progress_printer
from prismstation.cli.ties import fit_line
from prismstation.io.atomic import write_atomic
from prismstation.io.jsonfile import write_json
from prismstation.io.lock import refuse_if_held
from prismstation.io.points import measurements_csv
from prismstation.io.project import load_project, save_project
from prismstation.ops.fit import stored_solution
from prismstation.ops.reference_heights import load_for_scene
from prismstation.ops.transfer_points import (OUTSIDE_REASON, found_measurements, parallax_sigmas,
                                              to_transfer, transfer_points, transfer_record,
                                              transfer_summary)


def register(sub) -> None:
    p = sub.add_parser("transfer", help="search the project's points in the views they are not measured in")
    p.add_argument("project")
    p.add_argument("--points", nargs="+", metavar="ID", help="these points only (default: every point measured in "
                                                              "some views and not in all)")
    p.add_argument("--dem", metavar="DEM",
                   help="reference DEM (GeoTIFF or SRTM .hgt, orthometric through the project's geoid): the heights "
                        "searched around and the slope the matched shape is predicted from (default: the "
                        "project's reference DEM, when it names one)")
    p.add_argument("--csv", metavar="OUT", help="write the found measurements as a measurement CSV")
    p.add_argument("--json", metavar="OUT", help="write every search's result (position, σ, covariance, "
                                                "correlation, or why not) as JSON")
    p.add_argument("--save", action="store_true", help="add the found measurements to the project and refit")
    p.set_defaults(func=run)


def run(args) -> int:
    if args.save:  # before the work: the window holding the project would drop what is saved
        refuse_if_held(args.project)
    project = load_project(existing(args.project, "project"))
    todo = to_transfer(project, args.points)
    if not todo:
        print("transfer: every point is measured in every view or in none: nothing to search")
        return 0
    reference = load_for_scene(existing(args.dem, "reference DEM"), project) if args.dem else None
    sol, reference = stored_solution(project, reference=reference)
    print(f"transfer: {len(todo)} points, {_model_line(project, sol)}; "
          + (f"reference DEM {args.dem or project.reference_dem}" if reference is not None else
             "no reference DEM: heights searched about the mean height"))
    try:
        results = transfer_points(project, sol, todo, height_of=reference, progress=progress_printer("transfer "))
    except KeyboardInterrupt:
        end_progress()
        print("prismstation transfer: interrupted: nothing written", file=sys.stderr)
        return 130
    end_progress()
    wide = max(4, *(len(v) for v in project.scene.views))
    print(f"{'id':<10} {'view':<{wide}} {'status':<14} {'x':>10} {'y':>10} {'σ∥ px':>6} {'σ⊥ px':>6} "
          f"{'ρ':>5}  why not")
    for r in results:
        for v in r.targets:
            print(_row(r.pid, f"{v:<{wide}}", r.found.get(v)))
    print(transfer_summary(results, project.scene.views))
    ms = found_measurements(results)
    if args.json:
        write_json(args.json, {**transfer_record(results), "summary": transfer_summary(results, project.scene.views)},
                   indent=1)
    if args.csv and ms:
        write_atomic(args.csv, measurements_csv(ms), keep_backup=False)
        print(f"{len(ms)} measurements written to {args.csv}")
    if not ms:
        print(f"prismstation transfer: no point found in {args.project}", file=sys.stderr)
        return 3
    if args.save:
        project.load([], ms)
        save_project(project, args.project)
        print(f"{len(ms)} measurements added to {args.project}")
        print(fit_line(project, reference))
    return 0


def _model_line(project, sol) -> str:
    """What the searches go through: the orientation from a reference DEM, the fit, or the
    products' own geometry where a view is not fitted."""
    if project.settings.orientation == "dem":
        return "through the orientation from the reference DEM"
    loose = [v for v in project.scene.views if not sol.model.fitted(v)]
    if loose:
        return (f"through the products' own geometry for {', '.join(loose)} (no GCP fits it: the searches "
                f"cover its a-priori σ)")
    return f"through the fit ({project.settings.bias_model} bias)"


def _row(pid: str, view: str, t) -> str:
    """One line of the table: the match, or ``—`` in every column and why not."""
    if t is None or not t.ok:
        status, why = ("outside", OUTSIDE_REASON) if t is None else (t.match.status, t.match.reason)
        return f"{pid:<10} {view} {status:<14} {'—':>10} {'—':>10} {'—':>6} {'—':>6} {'—':>5}  {why}"
    along, across = parallax_sigmas(t)
    return (f"{pid:<10} {view} {'ok':<14} {t.x:10.3f} {t.y:10.3f} {_num(along, 6)} {_num(across, 6)} "
            f"{_num(t.match.rho, 5)}")


def _num(v: float, width: int) -> str:
    return f"{v:{width}.2f}" if math.isfinite(v) else f"{'—':>{width}}"
