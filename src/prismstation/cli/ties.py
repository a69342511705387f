"""``prismstation ties PROJECT [--grid N] [--dem DEM [--dem-sigma M]]``: automatic tie points.

The window's matcher (:func:`prismstation.ops.tie_points.add_tie_points`: a lattice of
``grid × grid`` points over the reference view, each searched in every other view through the
project's current fit, the three rays checked when there are three views or more, blunders
across the parallax rejected), each measurement with its σ. Progress on stderr; Ctrl+C stops
it and nothing is saved (exit 130). The project is saved atomically with the points added,
then refitted: one line says what was found, kept and rejected, one the fit's tie-point
residuals. Exit status 3 (nothing saved) when no point is kept. ``new --images`` runs the same
unless ``--no-ties``.
"""
from __future__ import annotations

import argparse
import math
import sys

from prismstation.cli._common import end_progress, existing, progress_printer, reference_heights
from prismstation.io.project import load_project, save_project
from prismstation.ops.fit import solve_project
from prismstation.ops.predict import DEFAULT_DEM_SIGMA_M
from prismstation.ops.tie_points import add_tie_points

#: lattice points per side (the window's default)
DEFAULT_GRID = 8


def _grid(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = 0
    if not 2 <= n <= 100:
        raise argparse.ArgumentTypeError(f"{text!r}: a whole number of points per side, 2 to 100")
    return n


def add_tie_options(p) -> None:
    """``--grid``: the lattice of the automatic tie points."""
    p.add_argument("--grid", type=_grid, default=DEFAULT_GRID, metavar="N",
                   help=f"tie points: a lattice of N × N points over the first image, each searched in the "
                        f"others (default {DEFAULT_GRID})")


def register(sub) -> None:
    p = sub.add_parser("ties", help="match tie points automatically between the project's images")
    p.add_argument("project")
    add_tie_options(p)
    p.add_argument("--dem", metavar="DEM",
                   help="reference DEM (GeoTIFF or SRTM .hgt, orthometric through the project's geoid): the "
                        "heights searched around and the slope the matched shape is predicted from")
    p.add_argument("--dem-sigma", type=float, default=DEFAULT_DEM_SIGMA_M, metavar="M",
                   help=f"σ of the reference DEM's heights, metres (default {DEFAULT_DEM_SIGMA_M:g})")
    p.set_defaults(func=run)


def run(args) -> int:
    project = load_project(existing(args.project, "project"))
    height_of, sigma = reference_heights(project, args)
    return match_and_save(project, args.project, args.grid, height_of, sigma, command="ties")


def match_and_save(project, path, grid: int, height_of=None, height_sigma_m=None, *, command: str) -> int:
    """Match, add, save atomically, refit and say so (the commands ``ties`` and ``new``)."""
    try:
        done = add_tie_points(project, grid=grid, height_of=height_of, height_sigma_m=height_sigma_m,
                              progress=progress_printer("tie points "))
    except KeyboardInterrupt:
        end_progress()
        hint = f" (the project is saved without them: prismstation ties {path})" if command == "new" else ""
        print(f"prismstation {command}: interrupted: no tie point saved in {path}{hint}", file=sys.stderr)
        return 130
    end_progress()
    print(f"tie points: {done.text(project.scene)}")
    if not done.ids:
        if not done.summary.get("tried"):
            return 0                     # every lattice point is measured already
        print(f"prismstation {command}: no tie point found in {path}", file=sys.stderr)
        return 3
    save_project(project, path)
    print(fit_line(project, height_of, height_sigma_m))
    return 0


def fit_line(project, height_of=None, height_sigma_m=None) -> str:
    """One line: the refit's σ0 and each view's tie-point residual RMS (x / y px, where it has
    tie points), or why the fit failed."""
    sol = solve_project(project, height_of=height_of, height_sigma_m=height_sigma_m)
    if not sol.ok:
        return "fit: " + "; ".join(sol.messages)
    s0 = next((b.lsq.sigma0 for b in sol.bias.values() if getattr(b, "lsq", None) is not None), None)
    parts = []
    for v in project.scene.views:
        st = sol.stats.image.get(v, {}).get("TIE")
        if st is not None and st["px"].n:
            parts.append(f"{v} {st['px'].x.rms:.2f}/{st['px'].y.rms:.2f}")
    head = f"fit ({project.settings.bias_model} bias): σ0 {s0:.2f}" if s0 is not None and math.isfinite(s0) \
        else f"fit ({project.settings.bias_model} bias)"
    return head + ("; tie-point residual RMS x/y px: " + ", ".join(parts) if parts else "")
