"""``prismstation report PROJECT -o OUT.{json,csv,html,pdf} [--operator NAME]``: the same report
the window's File ▸ Export report… writes, of the project's stored orientation
(:func:`prismstation.ops.fit.stored_solution`); the model options, when given, are this
report's only (``fit`` stores them)."""
from __future__ import annotations

from pathlib import Path

from prismstation.cli._common import add_model_options, apply_model_options, existing
from prismstation.errors import ModelError
from prismstation.io.project import load_project
from prismstation.io.report import default_operator, write_report
from prismstation.ops.fit import project_report, stored_solution


def register(sub) -> None:
    p = sub.add_parser("report", help="export the residual report (JSON, CSV, HTML, PDF)")
    p.add_argument("project")
    p.add_argument("-o", "--output", required=True, help="OUT.json, OUT.csv, OUT.html or OUT.pdf")
    p.add_argument("--operator", help=f"name printed on the report (default: the login name, {default_operator()})")
    add_model_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    project = load_project(existing(args.project, "project"))
    apply_model_options(project, args)
    sol, _ = stored_solution(project)
    if not sol.ok and project.settings.orientation != "dem":
        raise ModelError("; ".join(sol.messages) or "the model could not be fitted")
    report = project_report(project, sol, args.project, operator=args.operator)
    ext = Path(args.output).suffix.lower()
    if ext in (".html", ".htm", ".pdf"):
        from prismstation.gui.report_writer import write_document  # start-up: Qt's PDF writer, only for it
        write_document(report, args.output)
    else:
        write_report(report, args.output)
    print(f"wrote {args.output}")
    return 0
