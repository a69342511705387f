"""Ground points of the simulator: GCPs well spread, ICPs and tie points scattered, all
visible in N, F and B; their exact image coordinates, surveyed and measured values."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prismstation.sim import geometry as geo
from prismstation.sim.scenario import GEOID, Scenario
from prismstation.sim.terrain import Grid


@dataclass(frozen=True)
class SimPoint:
    """One point: true ground ``(E, N, h)`` (h ellipsoidal, m) and exact image coordinates
    ``xy[view] = (x, y)`` (px)."""

    id: str
    kind: str  # GCP, ICP or TIE
    E: float
    N: float
    h: float
    xy: dict


def _candidate(scenario: Scenario, dem: Grid, x, y, margin):
    """Ground point under N pixel (x, y) at h = 0 with its terrain height, if it is inside
    every view (by ``margin`` px) and not on the sea-level plain; else None."""
    en = geo.image_to_map(scenario.views["N"], np.array([x, y], dtype=float))
    h = float(dem.sample(en[0:1], en[1:2])[0])
    if h - GEOID < 1.0:
        return None
    # the image position of the terrain point at (E, N) moves with h: keep a margin
    enh = np.array([en[0], en[1], h])
    xy = {}
    size = scenario.size
    for name, view in scenario.views.items():
        p = geo.image_coords(scenario.orbit, view, enh)
        if not (margin <= p[0] <= size - margin and margin <= p[1] <= size - margin):
            return None
        xy[name] = (float(p[0]), float(p[1]))
    return enh, xy


def choose_points(rng, scenario: Scenario, dem: Grid, n_gcp: int, n_icp: int,
                  n_tie: int) -> list[SimPoint]:
    """GCPs one per cell of a k×k grid (k = ⌈√n_gcp⌉) over the inner image, ICPs and ties
    at random with a minimum spacing; ids ``G01``, ``I01``, ``T01``."""
    size = scenario.size
    margin = max(20.0, 0.05 * size)
    lo, hi = 1.5 * margin, size - 1.5 * margin
    points: list[SimPoint] = []
    taken: list[tuple[float, float]] = []
    k = int(np.ceil(np.sqrt(n_gcp))) if n_gcp else 0
    cells = sorted(rng.choice(k * k, size=n_gcp, replace=False)) if n_gcp else []
    for i, cell in enumerate(cells):
        cx = lo + (cell % k + 0.5) * (hi - lo) / k
        cy = lo + (cell // k + 0.5) * (hi - lo) / k
        for attempt in range(400):
            jitter = (hi - lo) / k * (0.3 if attempt < 100 else 0.45 if attempt < 300 else 1.0)
            x = float(np.clip(cx + rng.uniform(-jitter, jitter), lo, hi))
            y = float(np.clip(cy + rng.uniform(-jitter, jitter), lo, hi))
            got = _candidate(scenario, dem, x, y, margin)
            if got:
                break
        else:
            raise RuntimeError("no valid GCP position found")
        (e, n, h), xy = got
        points.append(SimPoint(f"G{i + 1:02d}", "GCP", e, n, h, xy))
        taken.append((x, y))
    for kind, prefix, count in (("ICP", "I", n_icp), ("TIE", "T", n_tie)):
        d_min = 0.4 * (hi - lo) / np.sqrt(max(1, n_gcp + n_icp + n_tie))
        made = 0
        attempts = 0
        while made < count:
            attempts += 1
            if attempts % 500 == 0:
                d_min *= 0.8
            x, y = rng.uniform(lo, hi, 2)
            if taken and min(np.hypot(x - tx, y - ty) for tx, ty in taken) < d_min:
                continue
            got = _candidate(scenario, dem, x, y, margin)
            if not got:
                continue
            (e, n, h), xy = got
            made += 1
            points.append(SimPoint(f"{prefix}{made:02d}", kind, e, n, h, xy))
            taken.append((x, y))
    return points
