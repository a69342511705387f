"""``prismstation fit PROJECT [--json OUT] [--bias ...] [--parallax ...]``."""
from __future__ import annotations

from prismstation.cli._common import add_model_options, apply_model_options, existing
from prismstation.errors import ModelError
from prismstation.io.project import load_project, project_geoid, solve_project
from prismstation.io.report import report_dict, write_report
from prismstation.io.text_report import format_report


def register(sub) -> None:
    p = sub.add_parser("fit", help="fit the model and print (or write) the residual report")
    p.add_argument("project")
    p.add_argument("--json", metavar="OUT", help="write the report as JSON")
    add_model_options(p)
    p.set_defaults(func=run)


def fitted_report(args):
    project = load_project(existing(args.project, "project"))
    apply_model_options(project, args)
    sol = solve_project(project)
    if not sol.ok:
        raise ModelError("; ".join(sol.messages) or "the model could not be fitted")
    geoid = project_geoid(project).describe() if project.geoid else None
    return sol, report_dict(sol, project_path=args.project, geoid=geoid)


def run(args) -> int:
    sol, report = fitted_report(args)
    if args.json:
        write_report(report, args.json)
    print(format_report(report))
    return 0
