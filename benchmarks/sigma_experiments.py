"""The two experiments that calibrate the matcher's σ (:mod:`prismstation.core.matching.matching`),
run by ``benchmarks/match_sigma.py`` and checked by ``tests/core/matching/test_match_sigma.py``
(an experiment, not a test: it lives here and the test imports it).

Each returns rows ``(err_x, err_y, formal_σx, formal_σy, claimed_σx, claimed_σy)`` in pixels;
the search (parallax) direction is close to the image y axis in both.
"""
from __future__ import annotations

import json
import warnings
from pathlib import Path

import cv2
import numpy as np
import rasterio

from prismstation.core.matching.matching import match_point

HALF = 12


def _read(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with rasterio.open(path) as ds:
            return ds.read(1).astype(np.float32)


def closure_rows(triplet_dir, n=300, seed=1):
    """Real independent imagery without truth: points of image 1 matched into 2 and 3, then
    their match in 2 matched into 3; the closure (1→2→3 − 1→3) is the error of three matches.
    Rows hold the closure and the root-sum-square of the three matches' σ."""
    im = [_read(Path(triplet_dir) / f"img_0{i}.tif") for i in (1, 2, 3)]

    def shift(a, b):  # global offset of b from a (phase correlation)
        (dx, dy), _ = cv2.phaseCorrelate(a[:1000, :1000].astype(np.float64), b[:1000, :1000].astype(np.float64))
        return np.array([dx, dy])

    s12, s13 = shift(im[0], im[1]), shift(im[0], im[2])
    rows = []
    for p in np.random.default_rng(seed).uniform(120, 880, (n, 2)):
        d12, d13 = s12 / np.hypot(*s12), s13 / np.hypot(*s13)
        a = match_point(im[0], *p, im[1], *(p + s12), direction=d12, search_range=40, across_range=12,
                        half_window=HALF, max_sigma=10)
        b = match_point(im[0], *p, im[2], *(p + s13), direction=d13, search_range=40, across_range=12,
                        half_window=HALF, max_sigma=10)
        if not (a.ok and b.ok):
            continue
        c = match_point(im[1], a.x, a.y, im[2], b.x, b.y, direction=d13 - d12 if np.hypot(*(d13 - d12)) > 0.1
                        else d13, search_range=3, across_range=3, half_window=HALF, max_sigma=10)
        if not c.ok:
            continue
        rss = lambda *v: float(np.sqrt(np.sum(np.square(v))))  # noqa: E731
        rows.append([c.x - b.x, c.y - b.y,
                     rss(a.formal_sigma_x, b.formal_sigma_x, c.formal_sigma_x),
                     rss(a.formal_sigma_y, b.formal_sigma_y, c.formal_sigma_y),
                     rss(a.sigma_x, b.sigma_x, c.sigma_x), rss(a.sigma_y, b.sigma_y, c.sigma_y)])
    return np.array(rows)


def truth_rows(sim_dir, reps=3, seed=0):
    """A simulated triplet (``prismstation simulate``) with relief: each true point of N is
    matched into F and B from a prediction up to 2 px off; the error is against its truth."""
    sim_dir = Path(sim_dir)
    truth = json.loads((sim_dir / "truth.json").read_text())
    im = {v: _read(sim_dir / f"{v}.tif") for v in "NFB"}
    rng = np.random.default_rng(seed)
    rows = []
    for p in truth["points"]:
        n = np.array(p["image"]["N"])
        for v in "FB":
            t = np.array(p["image"][v])
            for _ in range(reps):
                pred = t + rng.uniform(-2, 2, 2)
                r = match_point(im["N"], *n, im[v], *pred, direction=(0.0, 1.0), search_range=6,
                                across_range=3, half_window=HALF, max_sigma=10)
                if r.ok:
                    rows.append([r.x - t[0], r.y - t[1], r.formal_sigma_x, r.formal_sigma_y, r.sigma_x, r.sigma_y])
    return np.array(rows)


def summary(rows) -> dict:
    """RMS error and RMS z (error/σ) per axis with formal and claimed σ, and the share of
    errors inside the 95 % ellipse of each."""
    e = rows[:, :2]
    out = {"n": len(rows), "rms_err": np.sqrt(np.mean(e ** 2, axis=0))}
    for name, s in (("formal", rows[:, 2:4]), ("claimed", rows[:, 4:6])):
        z = e / s
        out[f"rms_z_{name}"] = np.sqrt(np.mean(z ** 2, axis=0))
        out[f"in95_{name}"] = float(np.mean(np.sum(z ** 2, axis=1) < 5.991))
    return out
