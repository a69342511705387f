"""Automatic point transfer and tie points (issue 4 items 1–2) on the project's images.

A point placed in one view is searched in the others around the current model's prediction,
along the parallax (flight) direction as far as the height is uncertain, by NCC then
least-squares matching (:func:`prismstation.core.matching.match_point`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prismstation.core import prism
from prismstation.core.matching import MatchResult, match_point
from prismstation.core.solve import Solution
from prismstation.io.windows import ImageWindows
from prismstation.ops.progress import ProgressFn, checkpoint


@dataclass(frozen=True)
class Transfer:
    """Where a point of ``source`` view was found in ``view`` (image pixels) and how well."""

    view: str
    x: float
    y: float
    predicted: tuple
    match: MatchResult

    @property
    def ok(self) -> bool:
        return self.match.ok


def transfer(sol: Solution, images: ImageWindows, source: str, xy, *, h=None, h_range: float = 600.0,
             half_window: int = 12, min_score: float = 0.6) -> dict[str, Transfer]:
    """Find the point at ``xy`` of ``source`` in every other view.

    ``h``: expected height (default the solution's mean height), ``h_range``: its ± uncertainty
    (metres), which sets the search length along the parallax direction in each view.
    """
    sc = sol.scene
    h = sol.mean_height if h is None else float(h)
    xy = np.asarray(xy, float)
    en = sol.image_to_ground(source, xy, h)
    t = prism.scene_track_dir(sc, en)
    ref, rc0, rr0 = images.around(source, xy[0], xy[1], half_window + 8)
    out = {}
    for v, view in sc.views.items():
        if v == source or ref is None:
            continue
        pred = sol.ground_to_image(v, en, h)
        d = view.map_to_image.apply_linear(t)
        # pixels per metre of height along the search direction, relative to the source view
        k = abs(view.look_sign * view.tan_theta - sc.views[source].look_sign * sc.views[source].tan_theta)
        rng = 4.0 + k * h_range * np.hypot(*d)
        win, c0, r0 = images.around(v, pred[0], pred[1], int(rng) + half_window + 12)
        if win is None:
            continue
        m = match_point(ref, xy[0] - rc0, xy[1] - rr0, win, pred[0] - c0, pred[1] - r0, direction=d,
                        search_range=rng, across_range=3.0, half_window=half_window, min_score=min_score)
        out[v] = Transfer(v, m.x + c0, m.y + r0, (float(pred[0]), float(pred[1])), m)
    return out


def auto_tie_points(sol: Solution, images: ImageWindows, *, grid: int = 8, margin: float = 0.05,
                    h_range: float = 600.0, progress: ProgressFn | None = None) -> list[dict]:
    """Tie points on a ``grid × grid`` lattice of the N image, transferred to F and B.

    Returns ``[{"N": (x, y), "F": (x, y), "B": (x, y), "score": s}]`` for the points found in
    all three views and consistent with the others (``progress`` per
    :mod:`prismstation.ops.progress`; a cancel raises :class:`~prismstation.errors.Cancelled`): a point whose across-track F−N or B−N
    difference departs from the median by more than 3 NMAD (at least 1 px) is a blunder.
    """
    sc = sol.scene
    rows, cols = sc.views["N"].shape
    g = margin + (1 - 2 * margin) * (np.arange(grid) + 0.5) / grid
    found = []
    for k, (x, y) in enumerate((cx * cols, cy * rows) for cy in g for cx in g):
        checkpoint(progress, k / grid**2, f"point {k + 1} of {grid**2}")
        tr = transfer(sol, images, "N", (x, y), h_range=h_range)
        if all(v in tr and tr[v].ok for v in ("F", "B")):
            found.append({"N": (x, y), "F": (tr["F"].x, tr["F"].y), "B": (tr["B"].x, tr["B"].y),
                          "score": min(tr["F"].match.score, tr["B"].match.score)})
    if len(found) < 4:
        return found
    keep = np.ones(len(found), bool)
    xn = np.array([p["N"] for p in found])
    d = prism.along_track_unit(sc, sc.views["N"].map_to_image.inverse()(xn))
    cross = np.column_stack([d[:, 1], -d[:, 0]])
    for v in ("F", "B"):
        a = np.einsum("ij,ij->i", prism.to_nadir_space(sc, sc.views[v])(np.array([p[v] for p in found])) - xn, cross)
        med = np.median(a)
        nmad = max(1.4826 * np.median(np.abs(a - med)), 1.0 / 3)
        keep &= np.abs(a - med) <= 3 * nmad
    return [p for p, k in zip(found, keep) if k]
