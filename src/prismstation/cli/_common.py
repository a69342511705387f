"""Helpers shared by the sub-commands."""
from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from pathlib import Path

from prismstation.cli._gdal_lines import stderr_is_terminal
from prismstation.errors import InputError
from prismstation.io.inputs import local_file
from prismstation.ops.fit import DEFAULT_REFERENCE_SIGMA_M, PARALLAX_MODELS
from prismstation.ops.reference_heights import load_for_scene


def add_model_options(p, *, reference: bool = True) -> None:
    """The fit's options: ``--bias`` (every view, or ``VIEW=MODEL`` for one), ``--parallax``,
    ``--fixed-view``, ``--gcps``/``--no-gcps`` and (``reference``) the reference DEM of the
    fit's heights, ``--dem`` (``--no-dem``) and ``--dem-sigma``. Given to ``fit`` they become
    the project's stored settings."""
    p.add_argument("--bias", action="append", metavar="MODEL|VIEW=MODEL",
                   help="bias compensation model of every view, or VIEW=MODEL for one (repeatable; default: "
                        "the project's; PRISM: shift, similarity, affine; RPC: none, shift, shift_drift, affine)")
    p.add_argument("--parallax", choices=list(PARALLAX_MODELS), help="height–parallax relation (default: the project's)")
    p.add_argument("--fixed-view", metavar="VIEW",
                   help="RPC images: the view held fixed (zero bias) as the datum when there is no GCP "
                        "('auto': the first view when there is no GCP)")
    p.add_argument("--gcps", action=argparse.BooleanOptionalAction, default=None,
                   help="RPC images: whether the GCPs enter the fit (--no-gcps: they are only checked; "
                        "default: the project's, at first yes)")
    if not reference:
        return
    p.add_argument("--dem", metavar="DEM",
                   help="reference DEM (GeoTIFF or SRTM .hgt, orthometric through the project's geoid): heights of "
                        "points seen in one view; for RPC images also the heights tie points are held to "
                        "when GCPs are too few")
    p.add_argument("--no-dem", action="store_true", help="fit without the project's reference DEM (and forget it)")
    p.add_argument("--dem-sigma", type=float, metavar="M",
                   help=f"σ of the reference DEM's heights, metres, before the slope term (default: the project's, "
                        f"at first {DEFAULT_REFERENCE_SIGMA_M:g})")


def apply_model_options(project, args) -> bool:
    """The options' model choices into the project's settings (and ``--dem``/``--no-dem``
    into its reference DEM), each checked against what the project's sensor model offers;
    True when anything changed."""
    sensor = project.scene.sensor
    kw = {}
    every, per_view = None, dict(project.settings.view_bias)
    for b in getattr(args, "bias", None) or ():
        view, _, model = b.rpartition("=")
        if model not in sensor.bias_models:
            raise InputError(f"--bias {b}: {sensor.description} offer {', '.join(sensor.bias_models)}")
        if view:
            if view not in project.scene.views:
                raise InputError(f"--bias {b}: {view!r} is not a view of the project ({', '.join(project.scene.views)})")
            if not sensor.holds_view_fixed:
                raise InputError(f"--bias {b}: {sensor.description} have one bias model for every view")
            per_view[view] = model
        else:
            every, per_view = model, {}
    if every is not None:
        kw["bias_model"] = every
    base = every or project.settings.bias_model
    view_bias = tuple(sorted((v, m) for v, m in per_view.items() if m != base))
    if view_bias != project.settings.view_bias:
        kw["view_bias"] = view_bias
    if getattr(args, "parallax", None):
        if args.parallax not in sensor.parallax_models:
            raise InputError(f"--parallax: {sensor.description} have no height–parallax relation"
                             if not sensor.parallax_models else
                             f"--parallax {args.parallax}: {sensor.description} offer {', '.join(sensor.parallax_models)}")
        kw["parallax_model"] = args.parallax
    if getattr(args, "fixed_view", None):
        if not sensor.holds_view_fixed:
            raise InputError(f"--fixed-view: {sensor.description} hold no view fixed (their biases are fitted to GCPs)")
        if args.fixed_view != "auto" and args.fixed_view not in project.scene.views:
            raise InputError(f"--fixed-view {args.fixed_view}: not a view of the project "
                             f"({', '.join(project.scene.views)}, or auto)")
        kw["fixed_view"] = None if args.fixed_view == "auto" else args.fixed_view
    if getattr(args, "gcps", None) is not None:
        if not sensor.holds_view_fixed:
            raise InputError(f"--{'' if args.gcps else 'no-'}gcps: {sensor.description} are fitted to their GCPs")
        kw["use_gcps"] = bool(args.gcps)
    if getattr(args, "dem_sigma", None) is not None:
        if not (args.dem_sigma > 0 and math.isfinite(args.dem_sigma)):
            raise InputError(f"--dem-sigma {args.dem_sigma:g}: expected a positive number of metres")
        kw["reference_sigma_m"] = float(args.dem_sigma)
    changed = False
    if getattr(args, "dem", None) and getattr(args, "no_dem", False):
        raise InputError("--dem and --no-dem: give one of them")
    if getattr(args, "dem", None):
        dem = str(existing(args.dem, "reference DEM").resolve())
        if dem != project.reference_dem:
            project.set_reference_dem(dem)
            changed = True
    elif getattr(args, "no_dem", False) and project.reference_dem:
        project.set_reference_dem(None)
        changed = True
    kw = {k: v for k, v in kw.items() if getattr(project.settings, k) != v}
    if kw:
        project.set_settings(replace(project.settings, **kw))
    return changed or bool(kw)


def reference_heights(project, args):
    """``(height_of, σ m)`` of the option ``--dem`` (None, None without it; σ None without
    ``--dem-sigma``: the project's, :func:`prismstation.ops.fit.reference_sigma`)."""
    if not getattr(args, "dem", None):
        return None, None
    sigma = getattr(args, "dem_sigma", None)
    if sigma is not None and not sigma > 0:
        raise InputError(f"--dem-sigma {sigma:g}: expected a positive number of metres")
    return load_for_scene(existing(args.dem, "reference DEM"), project), None if sigma is None else float(sigma)


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
