"""The terrain slope with no reference DEM (:mod:`prismstation.ops.transfer`): the shapes a
point's patch takes on sloping planes through the model, the matches started from them beside
the level plane's, the slope a matched shape implies, and whether two views' shapes share one.

Shapes are 2×2 (target px per source px) as :func:`prismstation.ops.transfer.local_shape` makes
them (the mapping's central difference over ±``half_window`` px), the rays as straight lines
through their points at ``h`` and ``h + 100`` m; gradients are (dh/dE, dh/dN).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from prismstation.core.matching.lsm_search import AMBIGUITY, AMBIGUOUS, best_score, match, misfit
from prismstation.core.models.solution import Solution

SLOPE_HYPOTHESIS = 0.4
"""With no reference DEM, a match that fails from the level plane's shape is tried again from
the shapes of slopes this steep (rising along and across the track, both ways)."""


def slope_shapes(sol: Solution, source: str, xy, view: str, h: float, half_window: int):
    """``view``'s predicted shapes of the point on planes of :data:`SLOPE_HYPOTHESIS` rising
    along and across the track (the source image's rows and columns on the ground), both ways."""
    xy = np.asarray(xy, float)
    g = sol.image_to_ground(source, np.array([xy, xy + [0.0, 10.0], xy + [10.0, 0.0]]), np.full(3, h))
    grads = [sign * SLOPE_HYPOTHESIS * axis / np.hypot(*axis) for axis in (g[1] - g[0], g[2] - g[0])
             for sign in (1.0, -1.0)]
    shapes = plane_shapes(sol, source, xy, view, g[0], h, half_window)
    return [A for A in shapes(grads) if np.all(np.isfinite(A))]


def from_slopes(m, starts, band, d, along: float, across: float, half: int, retry: tuple, reach: float,
                ambiguity: float = AMBIGUITY, **options):
    """With no reference DEM: ``m``, the match from the level plane's shape, weighed against
    matches from the shapes ``starts`` of :func:`slope_shapes`, the one correlating best first
    (:func:`~prismstation.core.matching.lsm_search.best_score`, a cheap test). ``band``:
    ``(reference, x, y, search, pred)`` of :func:`~prismstation.core.matching.lsm_search.match`,
    which ``options`` go to as well; ``reach``: how far (px) along the parallax from a found
    ``m`` the slopes' peaks are looked for.

    A failed ``m`` (its status in ``retry``) becomes the first of them found. A found ``m`` may
    be the level shape's minimum only: on a 50 % slope the true shape stretches the patch by a
    quarter, and its peak, never started from, correlates better. A start whose correlation
    peak beats ``m``'s score is matched; more than 1 px from ``m``, its match replaces ``m``
    where its misfit ``1 − ρ²`` is under ``m``'s by the factor ``ambiguity``, and makes ``m``
    ambiguous where it is within that factor of it."""
    if not m.ok and m.status not in retry:
        return m
    if m.ok:
        # the slope's stretch moves the template's peak by at most its change over the
        # template's half (FREE_SHAPE_CHANGE of transfer): a shorter band about the match
        band, along = (*band[:4], np.array([m.x, m.y])), min(along, reach)
    scores = [best_score(*band, A, d, along, across, half) for A in starts]
    for k in np.argsort(scores)[::-1]:
        if m.ok and scores[k] <= m.score:
            break
        m2 = match(*band, starts[k], d, along=along, across=across, half=half, ambiguity=ambiguity, **options)
        if not m.ok:
            if m2.ok:
                return m2
            continue
        if not m2.ok or np.hypot(m2.x - m.x, m2.y - m.y) <= 1.0:
            break
        first, second = misfit(m.rho), misfit(m2.rho)
        if second * ambiguity < first:
            return m2
        if second <= first * ambiguity:
            return replace(m, status=AMBIGUOUS, reason=f"from a slope's shape the texture fits "
                           f"{np.hypot(m2.x - m.x, m2.y - m.y):.1f} px away as well ({m.rho:.3f}, {m2.rho:.3f})")
        break
    return m


def slopes_disagree(sol: Solution, source: str, xy, shapes: dict, en, h: float, half_window: int,
                    limit: float) -> bool:
    """Whether two views' matched shapes ``shapes`` (view → 2×2) are more than ``limit`` apart
    as one plane would make them: each view's shape against the one the other's fitted slope
    (:func:`fitted_slope`) predicts for it, as the largest singular value of ``A_pred⁻¹A − I``
    (one terrain plane under the template gives both; the limit a reference DEM's slope
    allows). False when a slope cannot be fitted."""
    (v, A), (w, B) = shapes.items()
    g = {v: fitted_slope(sol, source, xy, v, A, en, h, half_window=half_window),
         w: fitted_slope(sol, source, xy, w, B, en, h, half_window=half_window)}
    if g[v] is None or g[w] is None:
        return False
    for a, b in ((v, w), (w, v)):
        pred = plane_shapes(sol, source, xy, a, en, h, half_window)([g[b]])[0]
        if not np.all(np.isfinite(pred)) or abs(np.linalg.det(pred)) < 1e-9:
            return False
        change = np.linalg.svd(np.linalg.solve(pred, np.asarray(shapes[a], float)) - np.eye(2), compute_uv=False)[0]
        if change > limit:
            return True
    return False


def plane(en0, h0: float, grad):
    """Heights ``(n,)`` of the plane through ``(en0, h0)`` with gradient ``grad`` (dh/dE, dh/dN)
    at map points ``(n, 2)``: a reference-height function for :func:`~prismstation.ops.transfer.local_shape`."""
    en0, g = np.asarray(en0, float), np.asarray(grad, float)
    return lambda en: h0 + (np.atleast_2d(en) - en0) @ g


def plane_shapes(sol: Solution, source: str, xy, view: str, en, h: float, half_window: int):
    """A function: gradients ``[(dh/dE, dh/dN), …]`` → ``view``'s shapes (2×2 each) of the point
    ``xy`` of ``source`` on the planes through ``(en, h)`` with those gradients, as
    :func:`~prismstation.ops.transfer.local_shape` makes them (over ±``half_window`` px, the rays as straight lines)."""
    w = float(half_window)
    pix = np.asarray(xy, float) + np.array([[w, 0], [-w, 0], [0, w], [0, -w]])
    ends = sol.image_to_ground(source, np.vstack([pix, pix]), np.r_[np.full(4, h), np.full(4, h + 100.0)])
    base, k = ends[:4], (ends[4:] - ends[:4]) / 100.0

    def shapes(grads):
        dh = [((base - en) @ g) / (1.0 - k @ g) for g in grads]
        q = sol.ground_to_image(view, np.vstack([base + k * d[:, None] for d in dh]),
                                np.concatenate([h + d for d in dh])).reshape(len(grads), 4, 2)
        return [np.column_stack([(c[0] - c[1]) / (2 * w), (c[2] - c[3]) / (2 * w)]) for c in q]

    return shapes


def fitted_slope(sol: Solution, source: str, xy, view: str, A, en, h: float, step: float = 0.2,
                 half_window: int = 12):
    """The terrain gradient (dh/dE, dh/dN) under the point ``xy`` of ``source`` that makes the
    model's shape in ``view`` (as :func:`~prismstation.ops.transfer.local_shape` makes it, over ±``half_window`` px) equal
    the matched shape ``A`` (2×2): Gauss–Newton on the shapes of planes through ``(en, h)``,
    two steps (the shape is near linear in the gradient); the rays as straight lines."""
    A, en = np.asarray(A, float), np.asarray(en, float)
    shapes = plane_shapes(sol, source, xy, view, en, h, half_window)
    g = np.zeros(2)
    for _ in range(2):
        s0, sE, sN = shapes([g, g + [step, 0.0], g + [0.0, step]])
        J = np.column_stack([(sE - s0).ravel() / step, (sN - s0).ravel() / step])
        g = g + np.linalg.lstsq(J, (A - s0).ravel(), rcond=None)[0]
    return g if np.all(np.isfinite(g)) and np.hypot(*g) < 3.0 else None
