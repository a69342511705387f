"""``prismstation report PROJECT -o OUT.{json,csv,html,pdf} [--operator NAME]``: the same report
the window's File ▸ Export report… writes."""
from __future__ import annotations

from pathlib import Path

from prismstation.cli._common import add_model_options, apply_model_options, existing, reference_heights
from prismstation.io.project import load_project
from prismstation.io.report import default_operator, write_report
from prismstation.ops.fit import fit_report


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
    height_of, sigma = reference_heights(project, args)
    sol, report = fit_report(project, args.project, height_of=height_of, height_sigma_m=sigma,
                             operator=args.operator)
    ext = Path(args.output).suffix.lower()
    if ext in (".html", ".htm", ".pdf"):
        from prismstation.gui.report_writer import write_document  # start-up: Qt's PDF writer, only for it
        write_document(report, args.output)
    else:
        write_report(report, args.output)
    print(f"wrote {args.output}")
    return 0
