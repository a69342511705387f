"""Automatic tie points: a lattice over the reference view's image, each point transferred to
every other view (:func:`prismstation.ops.transfer.transfer`: shape-aware matching through the
fitted model, the rays' consistency checked), then the points that disagree with the others
across the parallax rejected. Image (x, y) = (column, row) px, pixel centre at +0.5."""
from __future__ import annotations

import math

import numpy as np

from prismstation.core import prism
from prismstation.core.solution import Solution
from prismstation.core.stats import nmad
from prismstation.io.windows import ImageWindows
from prismstation.ops.progress import ProgressFn, checkpoint
from prismstation.ops.transfer import search_sigmas, transfer


def auto_tie_points(sol: Solution, images: ImageWindows, *, grid: int = 8, margin: float = 0.05,
                    height_of=None, progress: ProgressFn | None = None,
                    summary: dict | None = None) -> list[dict]:
    """Tie points on a ``grid × grid`` lattice of the reference view's image (N for a
    triplet, else the scene's first view), transferred to every other view.

    Returns ``[{view: (x, y), …, "score": s}]`` for the points found in every other view whose
    rays meet (:func:`transfer`; ``score`` the lowest fitted correlation; ``progress`` per
    :mod:`prismstation.ops.progress`; a cancel raises :class:`~prismstation.errors.Cancelled`)
    and consistent with the others: a point whose difference to the source across the
    parallax direction (:func:`_across_parallax`: across the track for a triplet) departs
    from the median by more than 3 NMAD (at least 1 px) is a blunder. ``summary``, when given,
    is filled with ``tried`` (grid points), ``failed`` (``{status: count}``: the first failed
    view's status, in the scene's order; ``outside`` when a view could not be searched),
    ``blunders`` (rejected by the test across the parallax) and ``rms_px`` (RMS of the kept
    points' differences across the parallax about the median, every view together, source
    pixels; NaN with fewer than 4 found).
    """
    sc = sol.scene
    source = sc.reference_view
    targets = [v for v in sc.views if v != source]
    rows, cols = sc.views[source].shape
    g = margin + (1 - 2 * margin) * (np.arange(grid) + 0.5) / grid
    sigma_dem, sigma_mean = search_sigmas(sol, height_of)
    found, failed = [], {}
    for k, (x, y) in enumerate((cx * cols, cy * rows) for cy in g for cx in g):
        checkpoint(progress, k / grid**2, f"point {k + 1} of {grid**2}")
        tr = transfer(sol, images, source, (x, y), height_of=height_of, sigma_dem=sigma_dem,
                      sigma_mean=sigma_mean)
        bad = [tr[v].match.status if v in tr else "outside" for v in targets if v not in tr or not tr[v].ok]
        if not bad:
            found.append({source: (x, y), **{v: (tr[v].x, tr[v].y) for v in targets},
                          "score": min(tr[v].match.rho for v in targets)})
        else:
            failed[bad[0]] = failed.get(bad[0], 0) + 1
    if summary is not None:
        summary.update(tried=grid**2, failed=failed, blunders=0, rms_px=math.nan)
    if len(found) < 4:
        return found
    keep = np.ones(len(found), bool)
    xs = np.array([p[source] for p in found])
    dev = []
    for v in targets:
        a = _across_parallax(sol, source, xs, v, np.array([p[v] for p in found]))
        med = np.median(a)
        spread = max(nmad(a), 1.0 / 3)
        keep &= np.abs(a - med) <= 3 * spread
        dev.append(a - med)
    if summary is not None:
        summary.update(blunders=int((~keep).sum()),
                       rms_px=float(np.sqrt(np.mean(np.concatenate([e[keep] for e in dev]) ** 2))))
    return [p for p, k in zip(found, keep) if k]


def _across_parallax(sol: Solution, source: str, xs: np.ndarray, view: str, xt: np.ndarray) -> np.ndarray:
    """``(n,)`` px: the difference of ``view``'s points ``xt`` ``(n, 2)`` to the source's ``xs``
    across the direction a height moves them. A PRISM triplet: F or B in N space across the
    track; any other model: ``xt`` back to the source's image through the ground at the mean
    height, across the direction 100 m of height moves it there."""
    sc = sol.scene
    if sc.is_triplet:
        d = prism.along_track_unit(sc, sc.views[source].map_to_image.inverse()(xs))
        cross = np.column_stack([d[:, 1], -d[:, 0]])
        return np.einsum("ij,ij->i", prism.to_nadir_space(sc, sc.views[view])(xt) - xs, cross)
    h = float(sol.mean_height)
    back = [sol.ground_to_image(source, sol.image_to_ground(view, xt, hh), hh) for hh in (h, h + 100.0)]
    d = back[1] - back[0]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.einsum("ij,ij->i", back[0] - xs, np.column_stack([d[:, 1], -d[:, 0]]))