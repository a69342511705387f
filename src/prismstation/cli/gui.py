"""``prismstation gui [PROJECT] [--screenshot PNG]``: the measurement workstation window."""
from __future__ import annotations

from prismstation.cli.demo import ensure_demo


def register(sub) -> None:
    p = sub.add_parser("gui", help="open the measurement workstation window")
    p.add_argument("project", nargs="?", help="a .prismproj file to open")
    p.add_argument("--screenshot", metavar="PNG",
                   help="load and fit, write a PNG of the window and exit (works offscreen)")
    p.set_defaults(func=run)


def run(args) -> int:
    from prismstation.gui.app import run as run_gui  # start-up: Qt loads only for the window
    return run_gui(args.project, screenshot=args.screenshot, demo_maker=ensure_demo)
