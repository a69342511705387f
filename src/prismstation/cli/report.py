"""``prismstation report PROJECT -o OUT.{json,csv,html,pdf}``."""
from __future__ import annotations

from pathlib import Path

from prismstation.cli._common import add_model_options
from prismstation.cli.fit import fitted_report
from prismstation.io.report import write_report


def register(sub) -> None:
    p = sub.add_parser("report", help="export the residual report (JSON, CSV, HTML, PDF)")
    p.add_argument("project")
    p.add_argument("-o", "--output", required=True, help="OUT.json, OUT.csv, OUT.html or OUT.pdf")
    add_model_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    sol, report = fitted_report(args)
    ext = Path(args.output).suffix.lower()
    if ext in (".html", ".pdf"):
        from prismstation.gui.report_writer import write_document  # Qt's own PDF writer
        write_document(report, args.output)
    else:
        write_report(report, args.output)
    print(f"wrote {args.output}")
    return 0
