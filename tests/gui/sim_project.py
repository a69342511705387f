"""A simulated PRISM triplet project like the demo's (``prismstation simulate``: a rigorous
pushbroom geometry, orthometric GCP/ICP heights, a 55 m geoid, an SRTM-like reference DEM), small
enough for window tests; the fixtures of a test module make it once and copy it per test."""
from __future__ import annotations

import json
import shutil
from pathlib import Path


def make_sim(directory, size: int = 800, seed: int = 7) -> Path:
    """Simulate into ``directory`` and make ``p.prismproj`` there; returns the folder."""
    from prismstation.cli.new import create
    from prismstation.sim import simulate
    from prismstation.sim.reference import make_reference_dem
    d = Path(directory)
    simulate(d, size=size, seed=seed)
    make_reference_dem(d / "truth_dem.tif", d / "srtm.tif", seed=1)
    create(d / "p.prismproj", d / "scene.json", d / "points.csv", d / "measurements.csv")
    return d


def copy_sim(master: Path, target: Path) -> Path:
    shutil.copytree(master, target)
    return target


def truth(d: Path) -> dict:
    return {p["id"]: p for p in json.loads((Path(d) / "truth.json").read_text())["points"]}
