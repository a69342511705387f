"""Helpers shared by the sub-commands."""
from __future__ import annotations

from pathlib import Path

from prismstation.core.prism import BIAS_MODELS, PARALLAX_MODELS
from prismstation.errors import InputError


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


def existing(path: str, what: str = "file") -> Path:
    p = Path(path)
    if not p.exists():
        raise InputError(f"{what} not found", p)
    return p
