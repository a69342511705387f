"""Helpers shared by the sub-commands."""
from __future__ import annotations

import sys
from pathlib import Path

from prismstation.errors import InputError
from prismstation.ops.fit import BIAS_MODELS, PARALLAX_MODELS


def add_model_options(p) -> None:
    p.add_argument("--bias", choices=list(BIAS_MODELS), help="bias compensation model (default: the project's)")
    p.add_argument("--parallax", choices=list(PARALLAX_MODELS), help="height–parallax relation (default: the project's)")


def apply_model_options(project, args) -> None:
    from dataclasses import replace
    kw = {}
    if getattr(args, "bias", None):
        kw["bias_model"] = args.bias
    if getattr(args, "parallax", None):
        kw["parallax_model"] = args.parallax
    if kw:
        project.set_settings(replace(project.settings, **kw))


_open_line = False  # a progress line is on stderr, not ended yet


def progress_printer(what: str = ""):
    """A progress callable (:mod:`prismstation.ops.progress`) printing ``what``, the percentage
    and the message on one line of stderr when it is a terminal; it never asks to stop."""
    from prismstation.cli._gdal_lines import stderr_is_terminal
    show = stderr_is_terminal()

    def progress(fraction, message=""):
        global _open_line
        if show:
            print(f"\r{what}{fraction:5.0%} {message:<30}", end="", file=sys.stderr, flush=True)
            _open_line = True
    return progress


def end_progress() -> None:
    """End the progress line (if one was printed): what follows starts on a line of its own."""
    global _open_line
    if _open_line:
        print(file=sys.stderr)
        _open_line = False


def existing(path: str, what: str = "file") -> Path:
    p = Path(path)
    if not p.exists():
        raise InputError(f"{what} not found", p)
    return p
