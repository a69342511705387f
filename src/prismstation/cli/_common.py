"""Helpers shared by the sub-commands."""
from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

from prismstation.cli._gdal_lines import stderr_is_terminal
from prismstation.errors import InputError
from prismstation.io.inputs import local_file
from prismstation.ops.fit import BIAS_MODELS, PARALLAX_MODELS
from prismstation.ops.predict import DEFAULT_DEM_SIGMA_M
from prismstation.ops.reference_heights import load_for_scene


def add_model_options(p, *, reference: bool = True) -> None:
    """The fit's options: ``--bias``, ``--parallax``, ``--fixed-view`` and (``reference``) the
    reference DEM of the fit's heights, ``--dem`` and ``--dem-sigma``."""
    p.add_argument("--bias", choices=list(BIAS_MODELS),
                   help="bias compensation model (default: the project's; PRISM: shift, similarity, affine; "
                        "RPC: none, shift, shift_drift, affine)")
    p.add_argument("--parallax", choices=list(PARALLAX_MODELS), help="height–parallax relation (default: the project's)")
    p.add_argument("--fixed-view", metavar="VIEW",
                   help="RPC images: the view held fixed (zero bias) as the datum when there is no GCP")
    if not reference:
        return
    p.add_argument("--dem", metavar="DEM",
                   help="reference DEM (GeoTIFF or SRTM .hgt, orthometric through the project's geoid): heights of "
                        "points seen in one view; for RPC images also the heights tie points are held to "
                        "when GCPs are too few")
    p.add_argument("--dem-sigma", type=float, default=DEFAULT_DEM_SIGMA_M, metavar="M",
                   help=f"σ of the reference DEM's heights, metres (default {DEFAULT_DEM_SIGMA_M:g})")


def apply_model_options(project, args) -> None:
    """The options' model choices into the project's settings, each checked against what the
    project's sensor model offers."""
    sensor = project.scene.sensor
    kw = {}
    if getattr(args, "bias", None):
        if args.bias not in sensor.bias_models:
            raise InputError(f"--bias {args.bias}: {sensor.description} offer {', '.join(sensor.bias_models)}")
        kw["bias_model"] = args.bias
    if getattr(args, "parallax", None):
        if args.parallax not in sensor.parallax_models:
            raise InputError(f"--parallax: {sensor.description} have no height–parallax relation"
                             if not sensor.parallax_models else
                             f"--parallax {args.parallax}: {sensor.description} offer {', '.join(sensor.parallax_models)}")
        kw["parallax_model"] = args.parallax
    if getattr(args, "fixed_view", None):
        if not sensor.holds_view_fixed:
            raise InputError(f"--fixed-view: {sensor.description} hold no view fixed (their biases are fitted to GCPs)")
        if args.fixed_view not in project.scene.views:
            raise InputError(f"--fixed-view {args.fixed_view}: not a view of the project "
                             f"({', '.join(project.scene.views)})")
        kw["fixed_view"] = args.fixed_view
    if kw:
        project.set_settings(replace(project.settings, **kw))


def reference_heights(project, args):
    """``(height_of, σ m)`` of the option ``--dem`` (None, None without it)."""
    if not getattr(args, "dem", None):
        return None, None
    if not args.dem_sigma > 0:
        raise InputError(f"--dem-sigma {args.dem_sigma:g}: expected a positive number of metres")
    return load_for_scene(existing(args.dem, "reference DEM"), project), float(args.dem_sigma)


_open_line = False  # a progress line is on stderr, not ended yet


def progress_printer(what: str = ""):
    """A progress callable (:mod:`prismstation.ops.progress`) printing ``what``, the percentage
    and the message on one line of stderr when it is a terminal; it never asks to stop."""
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
    """``path`` when it is a regular local file (:func:`prismstation.io.inputs.local_file`)."""
    return local_file(path, what)
