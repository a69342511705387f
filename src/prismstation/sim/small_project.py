"""Small triplet projects with pictures for the window's tests, benchmark and screenshots.

The geometry is the empirical model itself (sim/model_triplet.py) with the paper's N bias and an
F/B offset; the images are rendered through that geometry from a terrain (hillshade plus a
multi-scale texture), so that one ground point shows the same detail in N, F and B and the
known image position of every point is exact (before the operator-like noise).
"""
from __future__ import annotations

import json
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import rasterio
from rasterio.errors import NotGeoreferencedWarning
from scipy import ndimage

from prismstation.core.models import prism
from prismstation.io.project import save_project
from prismstation.io.scene import read_scene
from prismstation.model.points import GroundPoint, Measurement
from prismstation.model.project import Project
from prismstation.sim.model_triplet import PAPER_B, PAPER_M, make_scene

FB_BIAS = {"F": np.array([3.0 - 4.0, -5.0]), "B": np.array([3.0, -5.0])}


@dataclass
class DemoProject:
    path: Path
    scene_path: Path
    truth: dict          # id -> {view: (x, y)} exact image positions
    ground: dict         # id -> (E, N, h)


class Terrain:
    """Smooth relief 80–1300 m over the scene (E, N metres → h metres)."""

    def __init__(self, centre, extent_m, seed):
        rng = np.random.default_rng(seed)
        self.c = np.asarray(centre, float)
        self.k = rng.uniform(0.6, 1.6, (4, 2)) * 2 * np.pi / extent_m
        self.ph = rng.uniform(0, 2 * np.pi, 4)

    def __call__(self, en):
        d = np.asarray(en, float) - self.c
        s = sum(np.sin(d @ k + ph) / (i + 1) for i, (k, ph) in enumerate(zip(self.k, self.ph)))
        return 690.0 + 300.0 * s


def _bias(view):
    if view == "N":
        return PAPER_M, PAPER_B
    return np.zeros((2, 2)), FB_BIAS[view]


def to_image(scene, view, en, h):
    x0 = prism.ground_to_ancillary(scene, scene.views[view], en, h)
    M, b = _bias(view)
    return x0 + x0 @ M.T + b


def from_image(scene, view, xy, terrain, iterations=4):
    M, b = _bias(view)
    x0 = (np.asarray(xy, float) - b) @ np.linalg.inv(np.eye(2) + M).T
    h = np.full(x0.shape[:-1], 690.0)
    for _ in range(iterations):
        en = prism.ancillary_to_ground(scene, scene.views[view], x0, h)
        h = terrain(en)
    return en, h


def _texture(scene, terrain, size, p, seed):
    """A ground texture function (E, N) → grey 0..255 from hillshade and noise."""
    rng = np.random.default_rng(seed + 7)
    c = scene.views["N"].map_to_image.inverse()(np.array([size / 2, size / 2]))
    half = size * p * 0.9
    n = 1024
    step = 2 * half / n
    gE, gN = np.meshgrid(c[0] - half + step * np.arange(n), c[1] - half + step * np.arange(n))
    h = terrain(np.stack([gE, gN], -1))
    dzdx, dzdy = np.gradient(h, step)
    shade = (1 + (-dzdx - dzdy) * 2.0) / np.sqrt(1 + dzdx ** 2 + dzdy ** 2)
    noise = sum(ndimage.gaussian_filter(rng.normal(size=(n, n)), s) * s for s in (1, 3, 9, 27))
    fields = ndimage.gaussian_filter((rng.random((n, n)) > 0.5).astype(float), 12)
    g = 0.55 * (shade - shade.mean()) / shade.std() + 0.35 * noise / noise.std() + 0.5 * (fields - 0.5) / fields.std()
    g = np.clip(110 + 38 * g, 5, 250)

    def tex(en):
        col = (en[..., 0] - (c[0] - half)) / step
        row = (en[..., 1] - (c[1] - half)) / step
        return ndimage.map_coordinates(g, [row, col], order=1, mode="reflect")
    return tex


def _write_image(path, arr):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        with rasterio.open(path, "w", driver="GTiff", width=arr.shape[1], height=arr.shape[0], count=1,
                           dtype="uint8", tiled=True, blockxsize=256, blockysize=256) as ds:
            ds.write(arr, 1)
            f, fs = 2, []
            while max(arr.shape) / f >= 256:
                fs.append(f)
                f *= 2
            if fs:
                ds.build_overviews(fs, rasterio.enums.Resampling.average)


def make_project(outdir, *, n_gcp=9, n_icp=20, size=1200, p=20.0, noise_px=0.3, seed=3,
                 unmeasured=(), images=True, name="demo") -> DemoProject:
    """Write ``scene.json``, ``N.tif``, ``F.tif``, ``B.tif`` and ``<name>.prismproj`` in ``outdir``.

    Points ``G1..`` are GCPs and ``I1..`` ICPs, all measured with ``noise_px`` noise except the
    ids in ``unmeasured`` (ground coordinates only). ``truth`` holds their exact image positions.
    """
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    scene = make_scene(192.0, True, size=size, p=p)
    rng = np.random.default_rng(seed)
    centre = scene.views["N"].map_to_image.inverse()(np.array([size / 2, size / 2]))
    terrain = Terrain(centre, size * p, seed)
    views = {}
    for name_, v in scene.views.items():
        views[name_] = {"image": f"{name_}.tif", "pixel_size_m": v.pixel_size_m,
                        "along_track_angle_deg": v.along_track_angle_deg,
                        "map_to_image": v.map_to_image.coeffs()}
    doc = {"format": "prismstation-scene/1", "crs": scene.crs,
           "satellite_altitude_m": scene.satellite_altitude_m,
           "ground_track": scene.track.points.tolist(), "views": views}
    if images:
        tex = _texture(scene, terrain, size, p, seed)
        step = 8  # ground positions on a coarse grid of pixels, interpolated (smooth mapping)
        g = np.arange(0, size + step, step, dtype=float)
        gx, gy = np.meshgrid(g, g)
        fine = (np.arange(size) + 0.5) / step
        rows, cols = np.meshgrid(fine, fine, indexing="ij")
        for name_ in scene.views:
            en, _ = from_image(scene, name_, np.stack([gx, gy], -1), terrain)
            en_f = np.stack([ndimage.map_coordinates(en[..., k], [rows, cols], order=1, mode="nearest")
                             for k in range(2)], -1)
            _write_image(out / f"{name_}.tif", tex(en_f).astype(np.uint8))
    (out / "scene.json").write_text(json.dumps(doc, indent=1))
    scene = read_scene(out / "scene.json")
    # points inside all three images
    ids = [f"G{i + 1}" for i in range(n_gcp)] + [f"I{i + 1}" for i in range(n_icp)]
    truth, ground = {}, {}
    while len(truth) < len(ids):
        xy = rng.uniform(0.08 * size, 0.92 * size, 2)
        en, h = from_image(scene, "N", xy, terrain)
        img = {v: to_image(scene, v, en, h) for v in scene.views}
        if all(np.all((q > 10) & (q < size - 10)) for q in img.values()):
            pid = ids[len(truth)]
            truth[pid] = {v: (float(q[0]), float(q[1])) for v, q in img.items()}
            ground[pid] = (float(en[0]), float(en[1]), float(h))
    project = Project(scene, str(out / "scene.json"))
    points = [GroundPoint(pid, *ground[pid], kind="GCP" if pid.startswith("G") else "ICP") for pid in ids]
    ms = [Measurement(pid, v, x + rng.normal(0, noise_px), y + rng.normal(0, noise_px))
          for pid in ids if pid not in unmeasured for v, (x, y) in truth[pid].items()]
    project.load(points, ms)
    path = out / f"{name}.prismproj"
    save_project(project, path)
    return DemoProject(path, out / "scene.json", truth, ground)
