"""``prismstation fit PROJECT [--json OUT] [--bias ...] [--parallax ...] [--fixed-view VIEW]
[--dem DEM [--dem-sigma M]]``."""
from __future__ import annotations

from prismstation.cli._common import add_model_options, apply_model_options, existing, reference_heights
from prismstation.io.project import load_project
from prismstation.io.report import write_report
from prismstation.io.text_report import format_report
from prismstation.ops.fit import fit_report


def register(sub) -> None:
    p = sub.add_parser("fit", help="fit the model and print (or write) the residual report")
    p.add_argument("project")
    p.add_argument("--json", metavar="OUT", help="write the report as JSON")
    add_model_options(p)
    p.set_defaults(func=run)


def fitted_report(args):
    project = load_project(existing(args.project, "project"))
    apply_model_options(project, args)
    height_of, sigma = reference_heights(project, args)
    return fit_report(project, args.project, height_of=height_of, height_sigma_m=sigma)


def run(args) -> int:
    sol, report = fitted_report(args)
    if args.json:
        write_report(report, args.json)
    print(format_report(report))
    return 0
