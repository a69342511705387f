"""``prismstation fit PROJECT [--json OUT] [--bias MODEL|VIEW=MODEL ...] [--parallax ...]
[--fixed-view VIEW|auto] [--gcps|--no-gcps] [--dem DEM|--no-dem] [--dem-sigma M]``.

The options become the project's stored settings (without options: the stored ones); the fit
(:func:`prismstation.ops.fit.stored_solution`, the one every command makes) and its result
(:func:`prismstation.ops.fit.orientation_record`) are stored in the project, which ``report``,
``dsm``, ``orient-dem``, ``ortho`` and the window then read. A project a window holds is fitted
and reported but not stored (with options: refused, as any write is)."""
from __future__ import annotations

from prismstation.cli._common import add_model_options, apply_model_options, existing
from prismstation.errors import ModelError
from prismstation.io.lock import ProjectLock, refuse_if_held
from prismstation.io.project import load_project, save_project
from prismstation.io.report import write_report
from prismstation.io.text_report import format_report
from prismstation.ops.fit import orientation_record, project_report, stored_solution


def register(sub) -> None:
    p = sub.add_parser("fit", help="fit the model, store it in the project, print (or write) the residual report")
    p.add_argument("project")
    p.add_argument("--json", metavar="OUT", help="write the report as JSON")
    add_model_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    project = load_project(existing(args.project, "project"))
    changed = apply_model_options(project, args)
    if changed:  # before the work: the window holding the project would drop what is stored
        refuse_if_held(args.project)
    sol, _ = stored_solution(project)
    if not sol.ok and project.settings.orientation != "dem":
        raise ModelError("; ".join(sol.messages) or "the model could not be fitted")
    report = project_report(project, sol, args.project)
    record = orientation_record(project, sol)
    stored = ""
    if changed or (record is not None and record != project.orientation):
        if ProjectLock(args.project).holder() is not None:
            stored = f"not stored: {args.project} is open in a window (the window stores its own fit)"
        else:
            project.set_orientation(record)
            save_project(project, args.project)
            stored = f"stored in {args.project}"
    if args.json:
        write_report(report, args.json)
    print(format_report(report))
    if stored:
        print(stored)
    return 0
