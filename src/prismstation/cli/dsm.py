"""``prismstation dsm PROJECT -o dsm.tif [--window col row w h] [--posting m] [--orthometric]``."""
from __future__ import annotations

import sys

from prismstation.cli._common import existing
from prismstation.errors import ModelError
from prismstation.io.dem import write_dem
from prismstation.io.dsm import make_dsm
from prismstation.io.project import load_project, project_geoid
from prismstation.ops.fit import solve_project


def register(sub) -> None:
    p = sub.add_parser("dsm", help="dense matching of F and B → DSM GeoTIFF through the fitted model")
    p.add_argument("project")
    p.add_argument("-o", "--output", required=True, help="DSM GeoTIFF to write")
    p.add_argument("--window", nargs=4, type=int, metavar=("COL", "ROW", "W", "H"),
                   help="N-image window in pixels (default: a 4 × 4 km patch at the centre; 'all' via --all)")
    p.add_argument("--all", action="store_true", help="the whole N image")
    p.add_argument("--posting", type=float, default=10.0, help="grid posting, m (default 10)")
    p.add_argument("--orthometric", action="store_true", help="write orthometric heights (through the geoid)")
    p.set_defaults(func=run)


def run(args) -> int:
    project = load_project(existing(args.project, "project"))
    sol = solve_project(project)
    if not sol.ok and project.settings.orientation != "dem":
        raise ModelError("; ".join(sol.messages) or "the model could not be fitted")
    rows, cols = project.scene.views["N"].shape
    if args.all:
        window = None
    elif args.window:
        window = tuple(args.window)
    else:
        px = int(4000 / project.scene.views["N"].pixel_size_m)
        w, h = min(px, cols), min(px, rows)
        window = ((cols - w) // 2, (rows - h) // 2, w, h)

    def progress(fr, msg=""):
        print(f"\r{fr:5.0%} {msg:<24}", end="", file=sys.stderr, flush=True)
        return True

    dsm = make_dsm(sol, window, posting_m=args.posting, record=project.dem_control,
                   orthometric_geoid=project_geoid(project) if args.orthometric else None, progress=progress)
    print(file=sys.stderr)
    write_dem(args.output, dsm.heights, dsm.crs, dsm.transform)
    print(f"wrote {args.output}: {dsm.heights.shape[1]} × {dsm.heights.shape[0]} cells at {args.posting:g} m, "
          f"{dsm.height_kind} heights, {dsm.valid_fraction:.0%} filled")
    return 0
