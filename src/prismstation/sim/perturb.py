"""Perturb the published geolocation of an already-rendered simulated triplet.

The error of a real product lives in its ancillary data, not in its pixels: the images stay,
only the claimed pixel → map relation (``map_to_image``) moves. So a sweep renders a scene
once (:func:`prismstation.sim.simulate`) and writes many scene files, one per error case::

    perturb_geolocation(sim_dir, {"N": (30, -10), "F": (-80, 55), "B": (0, 100)},
                        sim_dir / "scene_case7.json")

``errors`` gives each view's (along, across) error in metres at the scene centre at h = 0
(along = flight direction, across = 90° to its left), *total*, not added to the error the
scene was simulated with. The new scene file carries each view's ``map_to_image`` (which
takes precedence over the TIFF geotransform) and points at the original images.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from prismstation.errors import InputError
from prismstation.io.atomic import write_atomic
from prismstation.sim import geometry as geo
from prismstation.sim.scenario import publish


def truth_geometry(truth: dict):
    """``(orbit, {view: View with its render grid}, size)`` rebuilt from a truth.json dict."""
    c = truth["constants"]
    orbit = geo.Orbit(tuple(c["track_origin"]), float(np.radians(c["heading_deg"])),
                      c["altitude_m"], c["speed_m_s"], c["pixel_m"], c["tan_beta0"], c["col0"])
    views = {name: geo.View(name, v["theta_rad"], v["tau0_s"], geo.Attitude(**v["attitude"]),
                            tuple(v["map_to_image"]))
             for name, v in truth["views"].items()}
    return orbit, views, int(truth["arguments"]["size"])


def perturbed_grids(truth: dict, errors: dict) -> dict:
    """``{view: map_to_image}`` whose geolocation errors are ``errors`` {view: (along, across)} m."""
    orbit, views, size = truth_geometry(truth)
    missing = set(views) - set(errors)
    if missing:
        raise ValueError(f"no geolocation error given for view(s) {sorted(missing)}")
    return {v: publish(orbit, views[v], size, float(errors[v][0]), float(errors[v][1]))
            for v in views}


def perturb_geolocation(sim_dir, errors: dict, out) -> Path:
    """Write scene file ``out`` for the simulated triplet in ``sim_dir`` with each view's
    published geolocation off by ``errors[view] = (along_m, across_m)``; returns ``out``."""
    sim_dir, out = Path(sim_dir), Path(out)
    try:
        truth = json.loads((sim_dir / "truth.json").read_text(encoding="utf-8"))
        scene = json.loads((sim_dir / "scene.json").read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise InputError(f"not a simulated triplet ({exc})", file=sim_dir) from None
    grids = perturbed_grids(truth, errors)
    for name, v in scene["views"].items():
        image = (sim_dir / v["image"]).resolve()
        v["image"] = os.path.relpath(image, out.parent.resolve())
        v["map_to_image"] = [float(a) for a in grids[name]]
    write_atomic(out, json.dumps(scene, indent=2) + "\n", keep_backup=False)
    return out
