"""Triplets made with the empirical model itself (for exact-recovery tests of the core)."""
import numpy as np

from prismstation.core.adjustment.affine import Affine2D
from prismstation.core.models.prism_model import PrismModel
from prismstation.core.models.scene import GroundTrack, Scene, View
from prismstation.core.models.solution import PointObs
from prismstation.core.models import prism

HS = 691650.0


def make_scene(heading_deg=192.0, path_oriented=True, size=14000, p=2.5):
    """Scene of ``size`` px at ``p`` m with the track through the image centre, shifted 3 km."""
    c = np.array([540000.0, 4560000.0])
    hd = np.radians(heading_deg)
    t = np.array([np.sin(hd), np.cos(hd)])
    across = np.array([t[1], -t[0]])  # to the left of flight
    views = {}
    for name, ang, off in (("N", 0.0, 0.0), ("F", 26.4, 13.0), ("B", 26.8, -9.0)):
        # image axes: x across (to the right of flight), y along flight (path-oriented)
        if path_oriented:
            ex, ey = -across, t
        else:
            ex, ey = np.array([1.0, 0.0]), np.array([0.0, -1.0])
        origin = c - (size / 2) * p * ex - (size / 2) * p * ey + off * ey
        lin = np.column_stack([ex * p, ey * p])  # image -> map
        img_to_map = Affine2D(np.column_stack([lin, origin]))
        views[name] = View(name, img_to_map.inverse(), p, ang, None, (size, size))
    track = GroundTrack(np.array([c - 3000 * across - 40000 * t, c - 3000 * across + 40000 * t]))
    return Scene("EPSG:32629", HS, track, views, sensor=PrismModel)


PAPER_M = np.array([[0.000073, 0.000048], [-0.000551, 0.000052]])
PAPER_B = np.array([-7.4, -27.7])


def make_points(scene, n_gcp=9, n_icp=41, noise_px=0.0, seed=0, M=PAPER_M, b=PAPER_B,
                fn_offset=(-4.0, 0.0), bias_fb=(3.0, -5.0)):
    rng = np.random.default_rng(seed)
    n = n_gcp + n_icp
    size = scene.views["N"].shape[1]
    xy = rng.uniform(0.05 * size, 0.95 * size, (n, 2))
    en = scene.views["N"].map_to_image.inverse()(xy)
    h = rng.uniform(50, 1400, n)
    pts = []
    for i in range(n):
        img = {}
        for v, view in scene.views.items():
            x0 = prism.ground_to_ancillary(scene, view, en[i], h[i])
            if v == "N":
                x = x0 + M @ x0 + b
            else:
                x = x0 + np.array(bias_fb) + (np.array(fn_offset) if v == "F" else 0)
            img[v] = tuple(x + rng.normal(0, noise_px, 2))
        kind = "GCP" if i < n_gcp else "ICP"
        pts.append(PointObs(f"P{i}", kind, (en[i, 0], en[i, 1], h[i]), img))
    return pts
