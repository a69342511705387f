"""A single-view project for the tool tests: a GeoTIFF with a known rotated geotransform and
GCPs/ICPs whose map coordinates follow a mildly non-affine (quadratic) image→map mapping."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import rasterio
from rasterio.transform import Affine

from prismstation.io.project import save_project
from prismstation.io.scene import read_scene
from prismstation.model.points import GroundPoint, Measurement
from prismstation.model.project import Project

CRS = "EPSG:32629"
E0, N0, P = 500000.0, 4600000.0, 10.0


def true_map(xy):
    """Image (x, y) pixels → map (E, N) metres: affine plus a small quadratic term."""
    x, y = np.asarray(xy, float).T
    e = E0 + P * x + 0.02 * y + 2e-4 * x * y
    n = N0 - P * y + 0.01 * x - 1e-4 * x * x
    return np.column_stack([e, n])


def make_single_view(outdir, n_gcp=14, n_icp=6, size=400, noise_px=0.2, seed=1,
                      blocky=False):
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:size, 0:size]
    img = (120 + 60 * np.sin(xx / 17.0) * np.cos(yy / 23.0) + rng.normal(0, 8, (size, size)))
    if blocky:  # JPEG-like: 8 × 8 blocks of constant grey plus the texture, so edges step
        img = img + 20 * rng.standard_normal((size // 8 + 1, size // 8 + 1)).repeat(8, 0).repeat(8, 1)[:size, :size]
    img = np.clip(img, 0, 255).astype(np.uint8)
    with rasterio.open(out / "A.tif", "w", driver="GTiff", width=size, height=size, count=1,
                       dtype="uint8", crs=CRS, transform=Affine(P, 0, E0, 0, -P, N0)) as ds:
        ds.write(img, 1)
    doc = {"format": "prismstation-scene/1", "crs": CRS, "satellite_altitude_m": 691650.0,
           "ground_track": [[E0 + 2000, N0 + 1000], [E0 + 2000, N0 - 6000]],
           "views": {"A": {"image": "A.tif", "pixel_size_m": P, "along_track_angle_deg": 0.0}}}
    (out / "scene.json").write_text(json.dumps(doc))
    scene = read_scene(out / "scene.json")
    project = Project(scene, str(out / "scene.json"))
    ids = [f"G{i + 1}" for i in range(n_gcp)] + [f"I{i + 1}" for i in range(n_icp)]
    xy = rng.uniform(20, 380, (len(ids), 2))
    en = true_map(xy)
    points = [GroundPoint(pid, float(e), float(n), 300.0, kind="ICP" if pid[0] == "I" else "GCP")
              for pid, (e, n) in zip(ids, en)]
    obs = xy + rng.normal(0, noise_px, xy.shape)
    ms = [Measurement(pid, "A", float(x), float(y)) for pid, (x, y) in zip(ids, obs)]
    project.load(points, ms)
    path = out / "single.prismproj"
    save_project(project, path)
    return path


FRAME_EO = np.array([E0 + 2000.0, N0 - 2000.0, 3000.0, 0.02, -0.03, 0.5])
"""Truth of :func:`make_frame_view`: X0, Y0, Z0 (m), ω, φ, κ (rad)."""


FRAME_EO_B = np.array([E0 + 2000.0, N0 - 2600.0, 3050.0, 0.2, 0.01, 0.45])
"""Second view of :func:`make_frame_view` with ``two_views``: 600 m base, tilted back."""


def make_frame_view(outdir, n=16, noise_px=0.1, seed=4, two_views=False):
    """A single view measured through a frame camera (f 100 mm, 50 µm pixels, principal point
    at the centre of a 400 px image; 1.5 m/px at 3 km): returns (project path, camera).
    With ``two_views`` a second view ``A2`` (same picture) sees the points from FRAME_EO_B."""
    from prismstation.core.models.resection import FrameCamera, project as frame_project

    out = Path(outdir)
    path = make_single_view(out, n_gcp=1, n_icp=0)
    rng = np.random.default_rng(seed)
    cam = FrameCamera(0.1, 50e-6, 200.0, 200.0)
    if two_views:
        doc = json.loads((out / "scene.json").read_text())
        doc["views"]["A2"] = dict(doc["views"]["A"])
        (out / "scene.json").write_text(json.dumps(doc))
    eos = {"A": FRAME_EO, "A2": FRAME_EO_B} if two_views else {"A": FRAME_EO}
    pts, ms = [], []
    for _ in range(20000):
        if len(pts) == n:
            break
        g = np.array([FRAME_EO[0] + rng.uniform(-330, 330), FRAME_EO[1] + rng.uniform(-330, 330),
                      rng.uniform(100, 700)])
        xy = {v: frame_project(cam, eo, g[None])[0] for v, eo in eos.items()}
        if all(np.all((q > 10) & (q < 390)) for q in xy.values()):
            pid = f"F{len(pts) + 1}"
            pts.append(GroundPoint(pid, float(g[0]), float(g[1]), float(g[2])))
            for v, q in xy.items():
                q = q + rng.normal(0, noise_px, 2)
                ms.append(Measurement(pid, v, float(q[0]), float(q[1])))
    assert len(pts) == n, "the views do not overlap enough"
    project = Project(read_scene(out / "scene.json"), str(out / "scene.json"))
    project.load(pts, ms)
    save_project(project, path)
    return path, cam
