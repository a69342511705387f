"""``prismstation demo [--no-gui | --screenshot PNG]``: the bundled demo project.

The demo is a simulated PRISM 1B2-R triplet (``prismstation simulate``) with 9 GCPs, 41 ICPs
and 20 tie points, and an SRTM-like reference DEM (``triplet/srtm.tif``), made once into the
user's data folder and then reused.
"""
from __future__ import annotations

import os
from pathlib import Path

from prismstation.io.project import load_project, save_project
from prismstation.io.recovery import recovery_for
from prismstation.io.text_report import format_report
from prismstation.ops.fit import fit_report
from prismstation.ops.project import create

DEMO_SEED = 2008
DEMO_SIZE = 2000


def default_dir() -> Path:
    env = os.environ.get("PRISMSTATION_DEMO_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_DATA_HOME") or Path.home() / ".local" / "share"
    return Path(base) / "prismstation" / "demo"


def ensure_demo(directory=None, *, rebuild: bool = False, progress=None) -> Path:
    """Make the demo project if absent; returns the project path."""
    # start-up: the simulator loads only to make the demo
    from prismstation.sim import simulate
    from prismstation.sim.reference import make_reference_dem

    d = Path(directory or default_dir())
    project = d / "demo.prismproj"
    if project.exists() and not rebuild:
        _record_reference_dem(project)
        return project
    data = d / "triplet"
    simulate(data, size=DEMO_SIZE, seed=DEMO_SEED, progress=progress)
    # an SRTM-like reference (90 m, orthometric, noise, voids) for the GCP-free workflow
    make_reference_dem(data / "truth_dem.tif", data / "srtm.tif", seed=DEMO_SEED)
    create(project, data / "scene.json", data / "points.csv", data / "measurements.csv", force=True)
    _record_reference_dem(project)
    return project


def _record_reference_dem(project: Path) -> None:
    """The demo's SRTM-like DEM as its project's reference DEM (a demo made before projects
    kept one gets it once, unless it has unsaved edits to recover)."""
    dem = reference_dem(project)
    if dem is None or recovery_for(project) is not None:
        return
    proj = load_project(project)
    if proj.reference_dem is None:
        proj.reference_dem = str(dem.resolve())
        save_project(proj, project)


def reference_dem(project) -> Path | None:
    """The demo's reference DEM beside its images (None if absent): the window loads it when
    the demo opens, so predictions and the linked cursor use its heights."""
    p = Path(project).parent / "triplet" / "srtm.tif"
    return p if p.is_file() else None


def register(sub) -> None:
    p = sub.add_parser("demo", help="open the bundled demo project (made on first use)")
    p.add_argument("--dir", help=f"where the demo lives (default {default_dir()})")
    p.add_argument("--no-gui", action="store_true", help="print the demo's report instead of opening the window")
    p.add_argument("--screenshot", metavar="PNG", help="load and fit the demo, save a PNG of the window, exit")
    p.add_argument("--rebuild", action="store_true", help="make the demo again")
    p.set_defaults(func=run)


def run(args) -> int:
    made = Path(args.dir or default_dir()) / "demo.prismproj"
    if not args.no_gui and not args.screenshot and (args.rebuild or not made.exists()):
        # the first time: the window at once, the demo made behind a progress dialog
        from prismstation.gui.app import run as run_gui  # start-up: Qt loads only for the window
        return run_gui(demo_maker=lambda progress=None: ensure_demo(args.dir, rebuild=args.rebuild, progress=progress),
                       open_demo=True)
    project = ensure_demo(args.dir, rebuild=args.rebuild)
    if args.no_gui:
        proj = load_project(project)
        print(format_report(fit_report(proj, project)[1]))
        return 0
    from prismstation.gui.app import run as run_gui  # start-up: Qt loads only for the window
    return run_gui(str(project), screenshot=args.screenshot, reference_dem=reference_dem(project))
