"""Fit a scene's sensor model to a project's points and compute everything the operator reads.

:func:`solve` fits the scene's sensor model (:mod:`prismstation.core.sensor`); the
:class:`Solution` is the same for every model. :func:`solve_prism` is the empirical PRISM
model's fit (Gonçalves 2008). Neither raises for data the operator can fix (too few GCPs,
collinear GCPs, a point seen in too few views): such parts are left out of the
:class:`Solution` and :attr:`Solution.messages` says why.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Callable, Mapping

import numpy as np

from prismstation.core import prism
from prismstation.core.prism import BiasFit, ParallaxLine
from prismstation.core.ray_dem import ray_meets_surface
from prismstation.core.recent import Recent, key_of
from prismstation.core.results import PointColumns, PointResult, rows_array
from prismstation.core.scene import Scene
from prismstation.core.stats import ComponentStats, FitStatistics, ImageStats, VectorStats
from prismstation.errors import ModelError

HeightFn = Callable[[np.ndarray], np.ndarray]  # (n, 2) map metres -> (n,) ellipsoidal metres


@dataclass(frozen=True)
class Settings:
    """Model choices. ``sigma_px``: a-priori σ of a measurement without its own (σ0 then
    reads in pixels). ``blunder_threshold``: |standardised residual| that marks a blunder, on
    the normal scale (3.29: α = 0.001 per test; :func:`normal_equivalent`)."""

    bias_model: str = "affine"
    parallax_model: str = "line"
    sigma_px: float = 1.0
    blunder_threshold: float = 3.29
    mean_height: float | None = None
    orientation: str = "gcp"      # "gcp": fitted to GCPs; "dem": from reference-DEM control
    fixed_view: str | None = None  # the view held fixed as the datum (models that hold one)


@dataclass(frozen=True)
class PointObs:
    """A point as the solver sees it: ``ground`` = (E, N, h ellipsoidal) or None (tie);
    ``image`` maps view name → (x, y) pixels; ``sigma_px`` view → σ (optional);
    ``sigma_ground`` the survey's ``(σ plan, σ h)`` metres, None or an item None where not
    given (a model that weighs ground control takes such a point as exact)."""

    id: str
    kind: str
    ground: tuple[float, float, float] | None
    image: Mapping[str, tuple[float, float]]
    sigma_px: Mapping[str, float] = field(default_factory=dict)
    sigma_ground: tuple | None = None


@dataclass(frozen=True, eq=False)
class Solution:
    """An immutable fit: bias per view, parallax line (the PRISM model's; None otherwise),
    per-point results and statistics. ``failures`` holds the typed reason (a falsy
    :class:`~prismstation.core.estimate.FailedFit`: ``degenerate``, ``condition``) when the
    reference view's bias could not be fitted; ``messages`` says it in words. ``model`` is
    the fitted sensor model (:mod:`prismstation.core.sensor`) the geometry goes through,
    made from ``scene.sensor`` and ``bias``."""

    scene: Scene
    settings: Settings
    bias: dict                    # view -> BiasFit (identity where it could not be fitted)
    parallax: ParallaxLine | None
    columns: PointColumns         # every point's results as arrays (the window reads these)
    stats: FitStatistics
    messages: tuple
    mean_height: float
    revision: int = 0
    failures: dict = field(default_factory=dict)  # view -> FailedFit of its bias (reference view)
    observations: tuple = ()      # the PointObs of a GCP fit (to refit it without some of them)
    model: object = field(init=False, repr=False)  # the fitted sensor model (core/sensor.py)

    def __post_init__(self):
        object.__setattr__(self, "model", self.scene.sensor(self.scene, self.bias))

    # ---- geometry through the current model (linked cursors, predictions)
    def ground_to_image(self, view: str, en, h) -> np.ndarray:
        return self.model.ground_to_image(view, en, h)

    def image_to_ground(self, view: str, xy, h) -> np.ndarray:
        return self.model.image_to_ground(view, xy, h)

    def transfer(self, view: str, xy, h=None) -> dict:
        """Where the ground point under ``xy`` in ``view`` (at height ``h``, default the mean
        height) falls in every view: ``{view: (..., 2)}``."""
        h = self.mean_height if h is None else h
        en = self.image_to_ground(view, xy, h)
        return {name: self.ground_to_image(name, en, h) for name in self.scene.views}

    @property
    def points(self) -> tuple:
        """Every point's :class:`PointResult`, in the order of the fit's input (made once)."""
        return self.columns.results()

    def point(self, pid: str) -> PointResult | None:
        return self.columns.result(pid)

    @property
    def ok(self) -> bool:
        """The fit succeeded: nothing failed and the model has what it needs (for the PRISM
        model, the reference view's bias)."""
        return not self.failures and self.model.ok

    @property
    def reference_view(self) -> str:
        return self.scene.reference_view


@dataclass(frozen=True, eq=False)
class Control:
    """An orientation obtained without GCPs (docs/model.md §3): bias per view and parallax line
    derived elsewhere (from a reference DEM); :func:`solve` then only evaluates points."""

    bias: dict
    parallax: ParallaxLine | None
    source: str
    mean_height: float


def solve(scene: Scene, points, settings: Settings = Settings(), *,
          height_of: HeightFn | None = None, height_sigma_m: float | None = None, revision: int = 0,
          control: Control | None = None) -> Solution:
    """Fit the scene's sensor model (``scene.sensor.fit``) to ``points`` (iterable of
    :class:`PointObs`). ``height_of``: the reference DEM's ellipsoidal heights at map points
    (heights of points no ray pair places; a model may also hold tie points to it, with
    ``height_sigma_m``, its σ in metres); ``control``: an orientation made elsewhere."""
    return scene.sensor.fit(scene, points, settings, height_of=height_of, height_sigma_m=height_sigma_m,
                            revision=revision, control=control)


_RECENT = Recent()
"""The bias fits and parallax lines of the last fits: a click moves the inputs of one view."""


def solve_prism(scene: Scene, points, settings: Settings = Settings(), *,
                height_of: HeightFn | None = None, revision: int = 0,
                control: Control | None = None) -> Solution:
    """Fit the model of docs/model.md §2 to ``points`` (iterable of :class:`PointObs`).

    With ``control`` the model is taken as given and every point with ground coordinates is
    in effect a check point.
    """
    points = list(points)
    messages: list[str] = []
    gcps = [p for p in points if p.kind == "GCP" and p.ground is not None]
    heights = [p.ground[2] for p in points if p.ground is not None]
    mean_h = (settings.mean_height if settings.mean_height is not None
              else control.mean_height if control is not None
              else float(np.mean([p.ground[2] for p in gcps])) if gcps
              else float(np.mean(heights)) if heights else 0.0)
    if control is not None:
        messages.append(f"oriented by {control.source}: no GCP used in the fit; every ground point checks it")
        columns, stats = _point_results(scene, points, control.bias, control.parallax, mean_h, height_of,
                                        settings)
        return Solution(scene, settings, dict(control.bias), control.parallax, columns,
                        stats, tuple(messages), mean_h, revision)

    # 1. bias per view, fitted on the GCPs measured in it
    bias: dict[str, BiasFit] = {}
    failures: dict = {}
    ref = scene.reference_view
    for name, view in scene.views.items():
        sel = [p for p in gcps if name in p.image]
        fit = BiasFit.identity()
        model = settings.bias_model
        if sel:
            xy0 = prism.ground_to_ancillary(scene, view, [p.ground[:2] for p in sel],
                                            [p.ground[2] for p in sel])
            xy = np.array([p.image[name] for p in sel], float)
            sig = [p.sigma_px.get(name, settings.sigma_px) for p in sel]
            ladder = [m for m in prism.BIAS_MODELS if prism.BIAS_MODELS[m] <= prism.BIAS_MODELS[model]]
            for m in reversed(ladder):  # N follows the setting; F, B may step down for prediction
                result = _RECENT.get(key_of("bias", name, m, xy0, xy, sig),
                                     lambda: BiasFit.fit(xy0, xy, m, sig, what=f"view {name}"))
                if result:
                    fit = result
                    break
                if name == ref:
                    messages.append(result.reason)
                    failures[name] = result
                    break
        elif name in ("N",) or len(scene.views) == 1:
            messages.append(f"view {name}: no GCP measured; the ancillary model is used without bias correction")
        bias[name] = fit

    # 2. parallax line over GCPs measured in F and B
    triplet = scene.is_triplet
    parallax = None
    if triplet:
        fb = [p for p in gcps if "F" in p.image and "B" in p.image]
        py, h_fb, c1 = _parallax(scene, fb), [p.ground[2] for p in fb], prism.theoretical_c1(scene)
        try:
            parallax = _RECENT.get(key_of("parallax", settings.parallax_model, c1, py, h_fb),
                                   lambda: prism.fit_parallax(py, h_fb, settings.parallax_model, c1))
            if parallax.note:
                messages.append(parallax.note)
        except ModelError as exc:
            messages.append(str(exc))

    # 3. per point
    adjustment = _adjustment_stats(gcps, bias, parallax, scene, settings)
    columns, stats = _point_results(scene, points, bias, parallax, mean_h, height_of, settings, adjustment)
    return Solution(scene, settings, bias, parallax, columns, stats, tuple(messages),
                    mean_h, revision, failures, tuple(points))


def _parallax(scene: Scene, pts) -> np.ndarray:
    """F−B parallax (pixels, along track in N space) of points measured in F and B."""
    if not pts:
        return np.zeros(0)
    return prism.fb_parallax(scene, [p.image["F"] for p in pts], [p.image["B"] for p in pts])[0]


def _point_results(scene, points, bias, parallax, mean_h, height_of, settings,
                   adjustment=None) -> tuple[PointColumns, FitStatistics]:
    """Every point's predictions, residuals and ground estimate, vectorised over points, and
    their :func:`statistics` (from the same arrays). ``adjustment`` maps a GCP's id to its
    ``(std_residual, redundancy, blunder)``."""
    views = scene.views
    n = len(points)
    unmeasured = (np.nan, np.nan)
    X = {v: rows_array([p.image.get(v, unmeasured) for p in points], 2) for v in views}
    has = {v: _finite_rows(X[v]) for v in views}
    any_m = np.any(np.column_stack([has[v] for v in views]), axis=1) if n else np.zeros(0, bool)
    triplet = scene.is_triplet
    py = np.full(n, np.nan)
    mid = np.full((n, 2), np.nan)              # F–B midpoint in N space: where the parallax is
    across = {"F": np.full(n, np.nan), "B": np.full(n, np.nan)}
    if triplet and n:
        T = {v: prism.to_nadir_space(scene, views[v]) for v in ("F", "B")}
        n_inv = prism.image_to_map(views["N"])
        fb = has["F"] & has["B"]
        if fb.any():
            py[fb], mid[fb] = prism.fb_parallax(scene, X["F"][fb], X["B"][fb])
        if has["N"].any():
            ct = prism.along_track_unit(scene, n_inv(X["N"][has["N"]]))
            cross = np.column_stack([ct[:, 1], -ct[:, 0]])
            for v in ("F", "B"):
                sel = has[v][has["N"]]
                idx = np.flatnonzero(has["N"])[sel]
                across[v][idx] = np.einsum("ij,ij->i", T[v](X[v][idx]) - X["N"][idx], cross[sel])

    # heights: parallax, else the reference DEM (iterated with planimetry), else the mean
    use_py = np.isfinite(py) & (parallax is not None)
    h = np.where(use_py, parallax.height(py, np.nan_to_num(mid)) if parallax is not None else np.nan, mean_h)
    source = np.where(use_py, "parallax", "mean").astype(object)

    def planimetry(h):
        en = np.full((n, 2), np.nan)
        if "N" in views and has["N"].any():
            m = has["N"]
            en[m] = prism.ancillary_to_ground(scene, views["N"], bias["N"].invert(X["N"][m]), h[m])
        rest = any_m & ~has.get("N", np.zeros(n, bool))
        if rest.any():
            acc, cnt = np.zeros((n, 2)), np.zeros(n)
            for v in views:
                m = rest & has[v]
                if m.any():
                    acc[m] += prism.ancillary_to_ground(scene, views[v], bias[v].invert(X[v][m]), h[m])
                    cnt[m] += 1
            en[rest] = acc[rest] / cnt[rest, None]
        return en

    en = planimetry(h)
    need = np.flatnonzero(any_m & ~use_py) if height_of is not None else np.zeros(0, int)
    if need.size:                   # the rays meet the DEM; those that do not keep their height

        def ground_at(hn):
            hh = h.copy()
            hh[need] = hn
            return planimetry(hh)[need]
        hit = ray_meets_surface(ground_at, lambda e: np.asarray(height_of(e), float), h[need])
        idx = need[hit.converged]
        h[idx], source[idx] = hit.h[hit.converged], "reference"
        en = planimetry(h)

    known = np.array([p.ground is not None for p in points], bool)
    G = rows_array([p.ground if p.ground is not None else (np.nan,) * 3 for p in points], 3)
    en_k = np.where(known[:, None], G[:, :2], en)
    h_k = np.where(known, G[:, 2], h)
    have_k = _finite_rows(en_k) & np.isfinite(h_k)
    pred = {}
    for v, view in views.items():
        pv = np.full((n, 2), np.nan)
        if have_k.any():
            pv[have_k] = bias[v].apply(prism.ground_to_ancillary(scene, view, en_k[have_k], h_k[have_k]))
        pred[v] = pv

    # the columns of every point (a PointResult is made only for a point asked for)
    names = list(views)
    res_ok = {v: has[v] & known & have_k for v in names}
    res = {v: np.where(res_ok[v][:, None], X[v] - pred[v], np.nan) for v in names}
    est_a = np.column_stack([en, h])
    g_res_a = np.where((known & any_m)[:, None], est_a - G, np.nan)
    kinds = np.array([p.kind for p in points], str)
    tie_res = (kinds == "TIE") & np.logical_or.reduce([res_ok[v] for v in names])
    stats = _statistics(scene, kinds, res, g_res_a, any_m & (source == scene.sensor.height_source),
                        across, bool(tie_res.any()))
    std_res, red, blunder = np.full(n, np.nan), np.full(n, np.nan), np.zeros(n, bool)
    for i, p in enumerate(points):
        a = adjustment.get(p.id) if adjustment and p.kind == "GCP" else None
        if a is not None:
            std_res[i] = math.nan if a[0] is None else a[0]
            red[i], blunder[i] = a[1], a[2]
    source_l, any_m_l = source.tolist(), any_m.tolist()
    notes = tuple("not measured in any view" if not any_m_l[i] else
                  "height not from parallax: measure the point in F and B"
                  if triplet and source_l[i] != "parallax" else "" for i in range(n))
    return PointColumns(tuple(p.id for p in points), tuple(kinds.tolist()),
                        {v: np.where(has[v][:, None], X[v], np.nan) for v in names}, pred, res, py,
                        across if triplet else {}, np.where(any_m[:, None], est_a, np.nan),
                        tuple(source_l), g_res_a, std_res, red, blunder, notes), stats


def _finite_rows(xy: np.ndarray) -> np.ndarray:
    """``(n,)`` True where both values of a row of ``xy`` ``(n, 2)`` are finite (the same as
    ``np.all(np.isfinite(xy), axis=1)``, which is slow on rows of two)."""
    return np.isfinite(xy[:, 0]) & np.isfinite(xy[:, 1])


@functools.lru_cache(maxsize=256)
def critical_value(threshold: float, dof: int) -> float:
    """Critical |externally studentised residual| for ``dof`` redundancy: Student's t with
    ``dof − 1`` degrees of freedom at the two-sided α of ``threshold`` under the normal law
    (3.29 ↔ α = 0.001, Baarda). With few GCPs the t tails are heavy, hence a larger value."""
    # scipy.special holds what scipy.stats' norm.sf and t.isf evaluate (same numbers); the
    # first fit of a session then does not wait about a second for scipy.stats to import
    from scipy import special
    alpha = 2 * special.ndtr(-threshold)
    if alpha == 0:  # beyond the normal law's range in floating point: t.isf(0) is +inf
        return math.inf
    return float(-special.stdtrit(max(dof - 1, 1), alpha / 2))


def normal_equivalent(w, dof: int) -> np.ndarray:
    """|w| of externally studentised residuals of a fit with redundancy ``dof``, on the normal
    scale: the normal quantile of the same two-sided tail probability as |w| under Student's t
    with ``dof − 1`` degrees of freedom. It exceeds a threshold exactly when |w| exceeds
    :func:`critical_value` (threshold, dof), so one threshold holds for every fit whatever its
    redundancy (``w`` array-like; NaN stays NaN)."""
    from scipy import special
    w = np.abs(np.asarray(w, float))
    tail = special.stdtr(max(dof - 1, 1), -w)
    with np.errstate(divide="ignore"):
        z = -special.ndtri(tail)
    # beyond double precision (|w| of hundreds): the tail underflows; |w| itself is then far
    # beyond any threshold
    return np.where(np.isfinite(z) | np.isnan(w), z, w)


def _adjustment_stats(gcps, bias, parallax, scene, settings) -> dict:
    """Standardised residual (on the normal scale, :func:`normal_equivalent`) and redundancy of
    each GCP from the N bias and parallax fits: ``{id: (largest standardised residual or None,
    smallest redundancy, blunder)}``. Every GCP beyond ``settings.blunder_threshold`` is a
    blunder."""
    ref = scene.reference_view
    w: dict[str, list] = {}  # id -> [max standardised residual, min redundancy]

    def add(pid, s, r):
        cur = w.setdefault(pid, [math.nan, r])
        if math.isfinite(s):
            cur[0] = s if not math.isfinite(cur[0]) else max(cur[0], s)
        cur[1] = min(cur[1], r)

    fit = bias[ref]
    if fit.lsq is not None:
        ids = [p.id for p in gcps if ref in p.image]
        std_res = normal_equivalent(fit.lsq.std_residuals, fit.lsq.dof).tolist()
        red = fit.lsq.redundancy.tolist()
        for i, pid in enumerate(ids):  # x and y of one GCP: the larger one ignoring NaN
            s = [v for v in std_res[2 * i:2 * i + 2] if not math.isnan(v)]
            add(pid, max(s) if any(map(math.isfinite, s)) else math.nan, min(red[2 * i:2 * i + 2]))
    if parallax is not None and parallax.lsq is not None:
        ids = [p.id for p in gcps if "F" in p.image and "B" in p.image]
        std_res = normal_equivalent(parallax.lsq.std_residuals, parallax.lsq.dof).tolist()
        red = parallax.lsq.redundancy.tolist()
        for i, pid in enumerate(ids):
            add(pid, std_res[i], red[i])
    thr = settings.blunder_threshold
    return {pid: (s if math.isfinite(s) else None, red, math.isfinite(s) and s > thr)
            for pid, (s, red) in w.items()}


def statistics(scene: Scene, columns: PointColumns) -> FitStatistics:
    """Tables 1–3 of the paper and their extensions, for GCPs and ICPs (and tie points, in
    the image, where a model gives them residuals); height residuals of the points whose
    height comes from the model's own rays (``scene.sensor.height_source``)."""
    n = len(columns)
    kinds = np.array(columns.kinds, str).reshape(n)
    nan2 = np.full((n, 2), np.nan)
    residual = {v: columns.residual.get(v, nan2) for v in scene.views}
    own = np.array([s == scene.sensor.height_source for s in columns.height_source], bool).reshape(n)
    across = ({v: columns.across.get(v, np.full(n, np.nan)) for v in ("F", "B")} if scene.is_triplet else {})
    fitted = np.zeros(n, bool)
    for a in residual.values():
        fitted |= _finite_rows(a)
    ties = bool(np.any((kinds == "TIE") & fitted))
    return _statistics(scene, kinds, residual, columns.ground_residual, own, across, ties)


def _statistics(scene: Scene, kinds: np.ndarray, residual: dict, ground: np.ndarray, own_height: np.ndarray,
                across: dict, ties: bool) -> FitStatistics:
    """:func:`statistics` of ``n`` points from arrays, NaN where a point has no value:
    ``kinds`` (n,) point kinds, ``residual`` view → (n, 2) image residuals (px), ``ground``
    (n, 3) ground residuals (m), ``own_height`` (n,) True where the height comes from the
    model's own rays, ``across`` 'F', 'B' → (n,) across-track differences (px; triplets);
    ``ties``: tie points have image residuals."""
    of_kind = {k: kinds == k for k in ("GCP", "ICP") + (("TIE",) if ties else ())}
    image = {}
    for v, view in scene.views.items():
        image[v] = {}
        for k, sel in of_kind.items():
            px = VectorStats.of(residual[v][sel])
            image[v][k] = ImageStats(px, px.scaled(view.pixel_size_m))
    ground_stats = {k: VectorStats.of(ground[of_kind[k], :2]) for k in ("GCP", "ICP")}
    height = {k: ComponentStats.of(ground[of_kind[k] & own_height, 2]) for k in ("GCP", "ICP")}
    across_stats = ({v: ComponentStats.of(across[v]) for v in ("F", "B")} if scene.is_triplet else {})
    return FitStatistics(image, ground_stats, height, across_stats, scene.reference_view)
