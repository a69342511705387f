"""Automatic point transfer on the project's images (automatic tie points build on it: :mod:`prismstation.ops.tie_points`).

A point placed in one view is searched in the others around the current model's prediction
by shape-aware least-squares matching (:func:`prismstation.core.matching.lsm_search.match`, Gruen
1985). What the search assumes, and where it comes from:

* **height** (:func:`search_height`): the point's height from the reference DEM (else the
  mean height) and ±3 σ of it, at least ±:data:`MIN_HEIGHT_RANGE_M` (a DEM's σ is measured
  at the GCPs, not at every tree); ±:data:`FALLBACK_HEIGHT_RANGE_M` when nothing predicts it.
  The height range is searched along the parallax direction (where a height error moves the
  point).
* **geolocation** (:func:`~prismstation.ops.transfer_rays.model_sigma_m`): the model's σ per
  view — the ancillary model's a-priori σ (±85 px between two views) until every view's bias is
  fitted, then :data:`~prismstation.ops.transfer_rays.FITTED_SIGMA_M` (±9 px) — searched both
  along and across.
* **shape** (:func:`local_shape`): the 2×2 Jacobian of the source → target mapping at the
  point through the model, on the terrain plane the reference DEM gives around the point
  (its slope foreshortens F and B against N by ``tanθ × slope``: 15–30 % on mountains). With
  no DEM the plane is level at the model's height and the matcher lets the shape move
  further (:data:`FREE_SHAPE_CHANGE` instead of :data:`DEM_SHAPE_CHANGE`) after a smoothed
  first pass; a view that still fails is tried from slopes of
  :data:`~prismstation.ops.transfer_slope.SLOPE_HYPOTHESIS`; the
  first view found gives the height and, from its matched shape
  (:func:`~prismstation.ops.transfer_slope.fitted_slope`), the
  slope the other view is then searched at, over a short band.

Every match states its covariance; a match that fails says why (``status``, ``reason``). With
a reference DEM the prediction is a start of the search too, where the match ends more than
1 px from it (:func:`~prismstation.core.matching.lsm_search.match`, ``probe``). The relief
within the source template moves the point in every view by one height: each view's σ holds
the relief the views' matches show (:func:`~prismstation.ops.transfer_relief.shared_relief`).
Transferred from N to both F and B, the three rays must meet:
:func:`~prismstation.ops.transfer_rays.consistency` intersects them through the model (least
squares on ``(E, N, h)``) and a χ² of the image residuals beyond its quantile rejects both
(``inconsistent``). Found in one view only, the other is searched again at the height the found
one implies; a match still alone after a search band longer than :data:`CONFIRM_ALONG_PX` is
``unconfirmed``. docs/matching.md has the
method and its measured performance.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from prismstation.core.lazy_cv2 import lazy_module
from prismstation.core.matching.coarse import search_radius_px
from prismstation.core.matching.lsm import LsmResult
from prismstation.core.matching.lsm_search import AMBIGUITY, match, misfit
from prismstation.core.models.solution import Solution
from prismstation.io.windows import ImageWindows
from prismstation.ops.transfer_relief import RELIEF, shared_relief, smaller_on_relief, source_axes, with_relief
from prismstation.ops.transfer_slope import fitted_slope, from_slopes, plane, slope_shapes, slopes_disagree
from prismstation.ops.transfer_rays import consistency, intersect, model_sigma_m, view_sigma_px
from prismstation.ops.transfer_template import SOURCE_MARGIN, TEMPLATE_HALVES, template_halves
from prismstation.ops.predict import DEFAULT_HEIGHT_SPREAD_M, dem_sigma, height_spread

kernel = lazy_module("prismstation.core.matching.lsm_kernel")  # numba at first use: start-up saving

MIN_HEIGHT_RANGE_M = 50.0
"""Smallest ± height range searched (m)."""
FALLBACK_HEIGHT_RANGE_M = 600.0
"""± height range (m) when nothing predicts the point's height."""
DEM_SHAPE_CHANGE = 0.25
"""How far (largest singular value of ``A0⁻¹A − I``) the matched shape may move from the
one predicted on the reference DEM's slope (its 90 m cells smooth slopes of the template's
60 m)."""
FREE_SHAPE_CHANGE = 0.6
"""The same with no DEM: the slope is unknown (60 % slope foreshortens by about 30 %)."""
CONFIRM_ALONG_PX = 30.0
"""A match found in one view only, over a search longer than this (px, ±) along the parallax,
is ``unconfirmed`` (a failure): with no reference DEM the band spans hundreds of pixels."""
RETRY_STATUSES = ("not_converged", "shape", "texture", "low_correlation", "low_score", "moved")
"""The failures a different start shape may cure."""
MAX_SIGMA_PX = 0.5
"""A match stating a larger σ (px) is a failure (``texture``)."""
CREPT = ("not_converged",)
"""With a reference DEM (the shape known), the failures of a match after which it is made
again from the end of a pass on both images low-passed (σ 1.5 px, the search's ``coarse``):
a fit still creeping after its iterations, which on point-sampled texture moves between
minima a few tenths of a pixel apart that the low-pass removes (docs/matching.md). With no
DEM every failure is (the shape is known only roughly)."""
RESIZE_STATUSES = ("texture", "not_converged", "shape", "low_correlation")
"""A match failing so is tried with the smaller template sizes, the nearest first (with no
reference DEM: with the other of the two sizes of
:func:`~prismstation.ops.transfer_template.template_halves`): relief within a template grown
for point-sampled edges may spoil it."""


def known_ground(sol: Solution) -> dict:
    """id → ``(E, N, h)`` of the solution's points with known ground (for the σ of the DEM and
    of the mean height)."""
    out = {p.id: tuple(p.ground) for p in sol.observations if p.ground is not None}
    for p in sol.points:
        if p.id not in out and p.ground_residual is not None and p.ground_est is not None:
            out[p.id] = tuple(np.subtract(p.ground_est, p.ground_residual))
    return out


def ray_on_dem(sol: Solution, source: str, xy, h: float, height_of, iterations: int = 6):
    """Where the ray of ``source`` pixel ``xy`` meets the reference heights ``height_of``:
    ``(en, h, True)``; ``(en at h, h, False)`` where the DEM has no height. The ray is iterated
    as the straight line through its points at ``h`` and ``h + 100`` m, the ground point at the
    height found taken from the model."""
    xy = np.asarray(xy, float)
    if height_of is None:
        return sol.image_to_ground(source, xy, h), h, False
    ends = sol.image_to_ground(source, np.array([xy, xy]), np.array([h, h + 100.0]))
    step = (ends[1] - ends[0]) / 100.0
    h0, en, hit = h, ends[0], False
    for _ in range(iterations):
        hd = float(np.asarray(height_of(en[None]))[0])
        if not math.isfinite(hd):
            break
        hit = True
        if abs(hd - h) < 0.01:      # the ground point moves by less than a millimetre
            break
        h = hd
        en = ends[0] + step * (h - h0)
    if hit and h != h0:
        en = sol.image_to_ground(source, xy, h)
    return en, h, hit


def search_sigmas(sol: Solution, height_of=None) -> tuple[float, float]:
    """``(sigma_dem, sigma_mean)`` (m) that :func:`search_height` assumes for ``sol``: the
    reference DEM's σ and the spread of the heights, measured at the solution's known points
    (compute once for many transfers)."""
    ground = known_ground(sol)
    spread = height_spread(g[2] for g in ground.values()) if ground else DEFAULT_HEIGHT_SPREAD_M
    return dem_sigma(height_of, ground), spread


def search_height(sol: Solution, source: str, xy, *, height_of=None, sigma_dem: float | None = None,
                  sigma_mean: float | None = None, ray=None) -> tuple[float, float]:
    """``(h, h_range)`` metres searched for a point at ``xy`` of ``source``: where its ray meets
    the reference DEM ``height_of`` (σ ``sigma_dem``), else the mean height (σ ``sigma_mean``),
    and ±3 σ of it, at least ±:data:`MIN_HEIGHT_RANGE_M`; the mean height and
    ±:data:`FALLBACK_HEIGHT_RANGE_M` when the ray cannot be placed. ``sigma_dem``,
    ``sigma_mean`` default to what the solution's known points measure
    (:func:`prismstation.ops.predict.dem_sigma`, :func:`~prismstation.ops.predict.height_spread`).
    This is the height :func:`prismstation.ops.predict.predict_point` gives a point measured in
    one view, with its σ. ``ray``: :func:`ray_on_dem` of the point from the mean height, when
    computed already."""
    ground = known_ground(sol) if sigma_dem is None or sigma_mean is None else {}
    en, h, hit = ray if ray is not None else ray_on_dem(sol, source, xy, float(sol.mean_height), height_of)
    if not np.all(np.isfinite(en)):
        return float(sol.mean_height), FALLBACK_HEIGHT_RANGE_M
    if hit:
        sigma = dem_sigma(height_of, ground) if sigma_dem is None else sigma_dem
    else:
        sigma = (height_spread(g[2] for g in ground.values()) if ground else DEFAULT_HEIGHT_SPREAD_M) \
            if sigma_mean is None else sigma_mean
    return float(h), max(3.0 * float(sigma), MIN_HEIGHT_RANGE_M)


@dataclass(frozen=True)
class LocalShape:
    """The source → ``view`` mapping at a point: ``pred`` its image (px), ``A`` the 2×2
    Jacobian (``view`` px per source px), ``dh`` the image motion per metre of height along
    the source ray (px/m), ``slope`` the terrain gradient used (dh/dE, dh/dN; None: level)."""

    view: str
    pred: np.ndarray
    A: np.ndarray
    dh: np.ndarray
    slope: tuple | None


def terrain_gradient(height_of, en, radius_m: float):
    """(dh/dE, dh/dN) of the reference heights by central differences over ``±radius_m``; where
    a void takes one side, the one-sided difference from the height at ``en`` (None where a
    direction has no height on either side, or ``en`` none). A void beside a point would
    otherwise send it to the search without a slope, which is made for no reference at all."""
    pts = np.array([en + [radius_m, 0], en - [radius_m, 0], en + [0, radius_m], en - [0, radius_m], en])
    z = np.asarray(height_of(pts), float)
    out = []
    for up, down in ((z[0], z[1]), (z[2], z[3])):
        if math.isfinite(up) and math.isfinite(down):
            out.append((up - down) / (2 * radius_m))
        elif math.isfinite(z[4]) and (math.isfinite(up) or math.isfinite(down)):
            out.append((up - z[4]) / radius_m if math.isfinite(up) else (z[4] - down) / radius_m)
        else:
            return None
    return tuple(out)


def local_shape(sol: Solution, source: str, xy, views, *, h: float, height_of=None,
                half_window: int = 12, ray=None) -> tuple[np.ndarray, float, dict[str, LocalShape]]:
    """The predicted position, shape and parallax direction of the point ``xy`` of ``source``
    in each of ``views``.

    ``h``: the point's height (m, ellipsoidal). With ``height_of`` (a reference DEM: map
    metres ``(n, 2)`` → ellipsoidal metres ``(n,)``) the point sits on the DEM and the terrain
    is the plane of the DEM's gradient over the template's footprint (±``half_window`` px);
    otherwise the level plane at ``h``. The shape is the central difference of the mapping
    over ±``half_window`` px. ``ray``: :func:`ray_on_dem` of the point from ``h``, when computed
    already. Returns ``(en, h, {view: LocalShape})``, the ground point first."""
    xy = np.asarray(xy, float)
    en, h, hit = ray if ray is not None else ray_on_dem(sol, source, xy, float(h), height_of)
    grad = None
    if hit:
        radius = max(half_window * sol.scene.views[source].pixel_size_m, 15.0)
        grad = terrain_gradient(height_of, en, radius)
    g = np.zeros(2) if grad is None else np.asarray(grad, float)
    step = float(half_window)
    # four rays ±step px about the point meet the terrain plane (each ray the straight line
    # through its points at h and h + 100 m); a fifth, the point's own, 1 m up
    pix = xy + np.array([[step, 0], [-step, 0], [0, step], [0, -step]])
    ground = sol.image_to_ground(source, np.vstack([pix, pix, xy]), np.r_[np.full(4, h), np.full(4, h + 100.0), h + 1.0])
    hs = np.r_[np.full(4, h), h + 1.0]
    if np.any(g != 0):
        k = (ground[4:8] - ground[:4]) / 100.0                 # ground metres per metre of height
        hs[:4] = h + ((ground[:4] - en) @ g) / (1.0 - k @ g)
        ground[:4] += k * (hs[:4] - h)[:, None]
    ground = np.vstack([ground[:4], ground[8]])
    pts = np.vstack([ground[:4], en, ground[4]])
    hh = np.concatenate([hs[:4], [h, h + 1.0]])
    out = {}
    for v in views:
        q = sol.ground_to_image(v, pts, hh)
        A = np.column_stack([(q[0] - q[1]) / (2 * step), (q[2] - q[3]) / (2 * step)])
        out[v] = LocalShape(v, q[4], A, q[5] - q[4], grad)
    return en, h, out


@dataclass(frozen=True)
class Transfer:
    """Where a point of ``source`` view was found in ``view`` (image pixels) and how well:
    ``match`` the :class:`~prismstation.core.matching.lsm.LsmResult` (``cov`` its 2×2 covariance,
    ``status``/``reason``), ``predicted`` the model's prediction."""

    view: str
    x: float
    y: float
    predicted: tuple
    match: LsmResult

    @property
    def ok(self) -> bool:
        return self.match.ok


def transfer(sol: Solution, images: ImageWindows, source: str, xy, *, h=None, h_range=None,
             height_of=None, sigma_dem: float | None = None, sigma_mean: float | None = None,
             half_window: int | None = None, check: bool = True) -> dict[str, Transfer]:
    """Find the point at ``xy`` of ``source`` in every other view.

    ``h``, ``h_range``: the height searched and its ± range (m; default
    :func:`search_height`); ``height_of``: the reference DEM (ellipsoidal heights at map
    points), which also gives the terrain slope for the predicted shape; ``sigma_dem``,
    ``sigma_mean``: passed to :func:`search_height`. ``half_window``: the template's half size
    (px; default as large as its texture needs,
    :func:`~prismstation.ops.transfer_template.template_halves`; a failing match is tried with
    the other sizes, :data:`RESIZE_STATUSES`; relief within a large one is weighed by its
    central part, :func:`~prismstation.core.matching.lsm.refine`). ``check``: the rays' consistency
    test (:func:`consistency`): in height and across the parallax when the point is found in
    two other views, across the parallax when in one.
    """
    kernel.compile_kernels()      # once per process (and the start-up's objects out of the collector)
    sc = sol.scene
    xy = np.asarray(xy, float)
    if height_of is not None and sigma_dem is None:
        sigma_dem = dem_sigma(height_of, known_ground(sol))      # for the search and the relief
    adaptive = half_window is None
    h_noise = None
    if adaptive:
        # the source read once: for the template's size and for the templates
        source_window = images.around(source, xy[0], xy[1], TEMPLATE_HALVES[-1] + SOURCE_MARGIN)
        half_window, h_noise = template_halves(source_window, xy)
    # a failing match is tried with the smaller sizes, the nearest first (relief within the
    # template spoils a large one)
    others = sorted((h for h in TEMPLATE_HALVES if h < half_window), reverse=True) if adaptive else []
    biggest = max([half_window, *others])
    ray = None
    if h is None or h_range is None:
        ray = ray_on_dem(sol, source, xy, float(sol.mean_height), height_of)
        h0, r0 = search_height(sol, source, xy, height_of=height_of, sigma_dem=sigma_dem,
                               sigma_mean=sigma_mean, ray=ray)
        if h is not None or not np.all(np.isfinite(ray[0])):
            ray = None          # the point's ray from another height
        h = h0 if h is None else float(h)
        h_range = r0 if h_range is None else float(h_range)
    targets = [v for v in sc.views if v != source]
    en_pt, h_pt, shapes = local_shape(sol, source, xy, targets, h=float(h), height_of=height_of,
                                      half_window=half_window, ray=ray)
    free = next(iter(shapes.values())).slope is None if shapes else True
    if free and adaptive:
        # no DEM: every size is a search over hundreds of pixels (and a coarse pass, and slope
        # starts): the size the noise asks for, the one point-sampled edges ask for its second
        half_window, h_noise = h_noise, half_window
    radius = search_radius_px(model_sigma_m(sol) * np.sqrt(2), sc.views[source].pixel_size_m)
    ref, rc0, rr0 = source_window if adaptive else images.around(source, xy[0], xy[1], biggest + SOURCE_MARGIN)
    out, guided = {}, set()
    for v in targets:
        if v in out and out[v].ok:
            continue            # found already, guided by another view
        s = shapes[v]
        if ref is None or not np.all(np.isfinite(s.A)):
            continue
        along = radius + float(np.hypot(*s.dh)) * h_range
        d = s.dh if np.hypot(*s.dh) > 1e-9 else np.array([0.0, 1.0])
        reach = int(along + radius + 2 * biggest * np.abs(s.A).max() + 12)
        win, c0, r0 = images.around(v, s.pred[0], s.pred[1], reach)
        if win is None:
            continue
        m = match(ref, xy[0] - rc0, xy[1] - rr0, win, s.pred - [c0, r0], s.A, d, along=along,
                  across=radius, half=half_window, max_sigma=MAX_SIGMA_PX,
                  max_shape_change=FREE_SHAPE_CHANGE if free else DEM_SHAPE_CHANGE,
                  coarse=1.5, coarse_after=None if free else CREPT, rival=6.0 if free else 3.0, parallax=d,
                  probe=not free)
        if free:
            # the level start may miss a steep slope's shape: start from slopes too
            m = from_slopes(m, slope_shapes(sol, source, xy, v, h_pt, half_window),
                            (ref, xy[0] - rc0, xy[1] - rr0, win, s.pred - [c0, r0]), d, along, radius,
                            half_window, RETRY_STATUSES, FREE_SHAPE_CHANGE * half_window, max_sigma=MAX_SIGMA_PX,
                            max_shape_change=DEM_SHAPE_CHANGE, rival=6.0, parallax=d)
        resize = dict(along=along, across=radius, max_sigma=MAX_SIGMA_PX, parallax=d,
                      max_shape_change=FREE_SHAPE_CHANGE if free else DEM_SHAPE_CHANGE,
                      coarse=1.5, coarse_after=None if free else CREPT, rival=6.0 if free else 3.0,
                      probe=not free)
        # with no DEM each size is a search over hundreds of pixels: only the edges' size
        for h in ([h_noise] if adaptive and h_noise != half_window else []) if free else others:
            if m.ok or m.status not in RESIZE_STATUSES:
                break
            m = match(ref, xy[0] - rc0, xy[1] - rr0, win, s.pred - [c0, r0], s.A, d, half=h, **resize)
        m = replace(m, x=m.x + c0, y=m.y + r0, extra={**m.extra, "along": along})
        out[v] = Transfer(v, m.x, m.y, (float(s.pred[0]), float(s.pred[1])), m)
        if check and free and m.ok and len(targets) >= 2:
            # no reference DEM: the found view gives the height and the slope the others are
            # searched at (a short band, the shape predicted)
            out = _confirm(sol, images, source, xy, ref, (rc0, rr0), out, v, shapes, (en_pt, h_pt),
                           half_window, free, mark=False)
            guided.add(v)
    found = [v for v in targets if v in out and out[v].ok]
    if check and free and len(found) == 2 and slopes_disagree(sol, source, xy, {v: out[v].match.shape for v in found},
                                                               en_pt, h_pt, half_window, DEM_SHAPE_CHANGE):
        # one plane gives both shapes: each view searched again at the height and slope the
        # other's match implies replaces its match where it fits clearly better
        again = {v: _confirm(sol, images, source, xy, ref, (rc0, rr0), {w: out[w]}, w, shapes, (en_pt, h_pt),
                             half_window, free, mark=False).get(v) for v, w in (found, found[::-1])}
        out = {**out, **{v: t for v, t in again.items() if t is not None and t.ok
                         and misfit(t.match.rho) * AMBIGUITY < misfit(out[v].match.rho)}}
    if check and len(targets) >= 2 and len(found) == 1:
        out = _confirm(sol, images, source, xy, ref, (rc0, rr0), out, found[0], shapes, (en_pt, h_pt),
                       half_window, free, search=found[0] not in guided)
    if not free and any(t.ok for t in out.values()):
        # the relief within each template that its patch cannot follow, as the DEM shows it
        axes = source_axes(sol, source, (*en_pt, h_pt))
        shares = {}         # the point's share of relief, one for its views
        kept = {v: with_relief(t.match, ref, xy - (rc0, rr0), axes, (*en_pt, h_pt), shapes[v].dh, height_of,
                               sigma_dem, MAX_SIGMA_PX, shares) for v, t in out.items() if t.ok}
        out = {**out, **{v: replace(out[v], x=m.x, y=m.y, match=m) for v, m in kept.items()}}
        for v, t in list(out.items()):
            if adaptive and t.match.status == RELIEF:     # a smaller template sees less relief
                win = images.around(v, t.x, t.y, int(2 * biggest * np.abs(shapes[v].A).max() + 12))
                m = smaller_on_relief(t.match, ref, xy - (rc0, rr0), win, TEMPLATE_HALVES, shapes[v].A,
                                      (axes, (*en_pt, h_pt), shapes[v].dh, height_of, sigma_dem), MAX_SIGMA_PX,
                                      DEM_SHAPE_CHANGE)
                out[v] = replace(t, x=m.x, y=m.y, match=m) if m.ok else t
    # the relief within the template moves the point in every view by one height
    out = shared_relief(out, {v: shapes[v].dh for v in out}, MAX_SIGMA_PX)
    if check and any(t.ok for t in out.values()):
        # the rays must meet: with two views found, in height; with one, across its parallax
        out = consistency(sol, source, xy, out, h_pt, en0=en_pt)
    return out


def _confirm(sol, images, source, xy, ref, ref_origin, out, v1, shapes, ground, half_window, free, mark=True,
             search=True):
    """One view found (``v1``), another not: search the other at the height the found one
    implies (±3 σ of it along the parallax) and — with no reference DEM (``free``) — in the
    shape the slope fitted to ``v1``'s matched shape predicts. With ``mark``, when that fails
    too, a match whose band was wider than :data:`CONFIRM_ALONG_PX` (a wide height range: no
    reference DEM) is ``unconfirmed`` — nothing checks it, and over hundreds of pixels a
    repeated texture can correlate as well. ``ground``: ``(en, h)`` of the source point at the
    height searched. ``search=False``: the marking only."""
    if not search:
        return _mark_unconfirmed(out, v1) if mark else out
    obs = {source: (np.asarray(xy, float), view_sigma_px(sol, source) ** 2 * np.eye(2)),
           v1: ((out[v1].x, out[v1].y), out[v1].match.cov + view_sigma_px(sol, v1) ** 2 * np.eye(2))}
    try:
        g, _, _, _, C = intersect(sol, obs, ground[1], en0=ground[0])
    except np.linalg.LinAlgError:
        return out
    sigma_h = float(np.sqrt(max(C[2, 2], 0.0)))
    slope = fitted_slope(sol, source, xy, v1, out[v1].match.shape, g[:2], g[2], half_window=half_window) \
        if free else None
    for v, s in shapes.items():
        if v in (source, v1) or (v in out and out[v].ok) or not np.all(np.isfinite(s.A)):
            continue
        pred, A = np.asarray(sol.ground_to_image(v, g[:2], g[2]), float), s.A
        if slope is not None:
            ls = local_shape(sol, source, xy, [v], h=g[2], height_of=plane(g[:2], g[2], slope),
                             half_window=half_window)[2][v]
            if np.all(np.isfinite(ls.A)):
                pred, A = ls.pred, ls.A
        along = 3 * sigma_h * float(np.hypot(*s.dh)) + 2.0
        win, c0, r0 = images.around(v, pred[0], pred[1], int(along + 2 * half_window * np.abs(A).max() + 12))
        if win is None:
            continue
        d = s.dh if np.hypot(*s.dh) > 1e-9 else np.array([0.0, 1.0])
        guided = slope is not None or not free
        m = match(ref, xy[0] - ref_origin[0], xy[1] - ref_origin[1], win, pred - [c0, r0], A, d,
                  along=along, across=2.0, half=half_window, max_sigma=MAX_SIGMA_PX,
                  max_shape_change=DEM_SHAPE_CHANGE if guided else FREE_SHAPE_CHANGE,
                  coarse=1.5, coarse_after=CREPT if guided else None, rival=3.0 if guided else 6.0, parallax=d,
                  probe=not free)
        if m.ok:
            m = replace(m, x=m.x + c0, y=m.y + r0, extra={**m.extra, "along": along})
            out = dict(out)
            out[v] = Transfer(v, m.x, m.y, (float(pred[0]), float(pred[1])), m)
    return _mark_unconfirmed(out, v1) if mark else out


def _mark_unconfirmed(out, v1):
    """``out`` with ``v1``'s match ``unconfirmed`` when it is the only one found and its band
    was wider than :data:`CONFIRM_ALONG_PX`."""
    first = out[v1]
    if sum(t.ok for t in out.values()) == 1 and first.match.extra.get("along", 0.0) > CONFIRM_ALONG_PX:
        m = replace(first.match, status="unconfirmed",
                    reason=f"found in {v1} only, over a search of ±{first.match.extra['along']:.0f} px "
                           "along the parallax: no other view confirms it")
        out = dict(out)
        out[v1] = replace(first, match=m)
    return out
