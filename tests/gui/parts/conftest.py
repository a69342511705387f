"""A fitted synthetic triplet (sim/model_triplet.py) with one GCP made a blunder."""
from __future__ import annotations

from dataclasses import replace

import pytest

from prismstation.core.models.solution import solve
from prismstation.sim.model_triplet import make_points, make_scene

BLUNDER_ID = "P4"


def blundered_points(scene, n_gcp=12, n_icp=41, seed=3, shift=(6.0, -3.0)):
    """Synthetic points with ``BLUNDER_ID``'s N measurement moved by ``shift`` pixels."""
    pts = make_points(scene, n_gcp=n_gcp, n_icp=n_icp, noise_px=0.3, seed=seed)
    i = next(k for k, p in enumerate(pts) if p.id == BLUNDER_ID)
    img = dict(pts[i].image)
    img["N"] = (img["N"][0] + shift[0], img["N"][1] + shift[1])
    pts[i] = replace(pts[i], image=img)
    return pts


@pytest.fixture(scope="module")
def fitted():
    """``(scene, points, solution)``; the solution flags ``BLUNDER_ID``."""
    scene = make_scene()
    pts = blundered_points(scene)
    return scene, pts, solve(scene, pts)
