"""Automatic point transfer and tie points on the project's images.

A point placed in one view is searched in the others around the current model's prediction,
along the parallax (flight) direction as far as the height is uncertain, by NCC then
least-squares matching (:func:`prismstation.core.matching.match_point`). Both directions also
cover the model's geolocation σ per view (:func:`model_sigma_m`): with the ancillary model
alone the a-priori σ (50 m: ±85 px between two views), once the views' biases are fitted
:data:`FITTED_SIGMA_M` (±9 px); the radius is ``search_radius_px(σ·√2, GSD)`` (3 σ).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prismstation.core import prism
from prismstation.core.coarse import search_radius_px
from prismstation.core.matching import MatchResult, match_point
from prismstation.core.solve import Solution
from prismstation.core.stats import nmad
from prismstation.io.windows import ImageWindows
from prismstation.ops.coarse_offsets import SIGMA_APRIORI_M
from prismstation.ops.progress import ProgressFn, checkpoint

#: σ (m, per component) of a view's geolocation once its bias is fitted: the paper's
#: check-point accuracy without and with GCPs (Gonçalves with SRTM as control: under 5 m planimetric)
FITTED_SIGMA_M = 5.0


def model_sigma_m(sol: Solution) -> float:
    """σ (m) per view and component the searches assume for ``sol``: the ancillary model's
    a-priori σ until every view's bias is fitted (by GCPs or a reference DEM), then
    :data:`FITTED_SIGMA_M`."""
    fitted = all(b.model != "none" for b in sol.bias.values())
    return FITTED_SIGMA_M if fitted else SIGMA_APRIORI_M


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
    radius = search_radius_px(model_sigma_m(sol) * np.sqrt(2), sc.views[source].pixel_size_m)
    out = {}
    for v, view in sc.views.items():
        if v == source or ref is None:
            continue
        pred = sol.ground_to_image(v, en, h)
        d = view.map_to_image.apply_linear(t)
        # pixels per metre of height along the search direction, relative to the source view
        k = abs(view.look_sign * view.tan_theta - sc.views[source].look_sign * sc.views[source].tan_theta)
        rng = radius + k * h_range * np.hypot(*d)
        win, c0, r0 = images.around(v, pred[0], pred[1], int(rng) + half_window + 12)
        if win is None:
            continue
        m = match_point(ref, xy[0] - rc0, xy[1] - rr0, win, pred[0] - c0, pred[1] - r0, direction=d,
                        search_range=rng, across_range=radius, half_window=half_window, min_score=min_score)
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
        spread = max(nmad(a), 1.0 / 3)
        keep &= np.abs(a - med) <= 3 * spread
    return [p for p, k in zip(found, keep) if k]
