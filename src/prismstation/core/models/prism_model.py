"""The empirical PRISM 1B2 model (Gonçalves 2008) behind the sensor-model seam
(:mod:`prismstation.core.models.sensor`), whole: each view's ancillary geometry
(:mod:`prismstation.core.models.prism`) with its fitted bias (:class:`~prismstation.core.models.prism.BiasFit`)
and the F−B parallax line (:class:`~prismstation.core.models.prism.ParallaxLine`), the fit of a
project's points (:meth:`PrismModel.fit`: bias per view on the GCPs, the parallax line, every
point evaluated) and the orientation a reference DEM gives (:meth:`PrismModel.control_from_record`,
:mod:`prismstation.core.orientation.dem_orient`)."""
from __future__ import annotations

import math

import numpy as np

from prismstation.core.orientation import dem_orient
from prismstation.core.models import prism
from prismstation.core.models.prism import BiasFit, ParallaxLine
from prismstation.core.models.ray_dem import ray_meets_surface
from prismstation.core.models.recent import Recent, key_of
from prismstation.core.models.results import PointColumns, rows_array
from prismstation.core.models.scene import Scene
from prismstation.core.models.sensor import central_partials
from prismstation.core.models.solution import (Control, HeightFn, Settings, Solution, finite_rows, normal_equivalent,
                                        statistics_of)
from prismstation.core.adjustment.stats import FitStatistics
from prismstation.errors import ModelError


class PrismModel:
    """The PRISM model of ``scene`` with ``bias`` (view → :class:`BiasFit`; a view without one
    is uncorrected) and ``parallax`` (the F−B parallax line of a triplet's fit, or None): the
    model's own part, which its widgets, its report section and its DSM read. Ground ↔ image as
    :mod:`prismstation.core.models.prism` computes it: ``x = bias(map_to_image(P + relief_shift(P, h)))``."""

    name = "prism"
    bias_models = prism.BIAS_MODELS
    default_bias = "affine"
    parallax_models = prism.PARALLAX_MODELS
    height_source = "parallax"
    holds_view_fixed = False
    description = "ALOS-PRISM 1B2 views"
    workflows = frozenset({"fit", "report", "orient-dem", "dsm"})

    def __init__(self, scene, bias: dict | None = None, parallax: ParallaxLine | None = None):
        self.scene = scene
        self.bias = {v: (bias or {}).get(v, BiasFit.identity()) for v in scene.views}
        self.parallax = parallax

    @classmethod
    def fit(cls, scene: Scene, points, settings: Settings = Settings(), *, height_of: HeightFn | None = None,
            height_sigma_m=None, revision: int = 0, control: Control | None = None,
            recent: Recent | None = None) -> Solution:
        """Fit the model of docs/model.md §2 to ``points`` (iterable of
        :class:`~prismstation.core.models.solution.PointObs`): each
        view's bias on the GCPs measured in it (the reference view's as ``settings.bias_model``
        says, the others stepping down the ladder where it is not determined: they only serve
        predictions), the F−B parallax line on the GCPs seen in F and B; then every point. A
        point's height: from the parallax line where it is seen in F and B, else where its ray
        meets ``height_of`` (the reference DEM), else the mean height (``height_sigma_m`` is not
        used). With ``control`` (:class:`FixedPrism` in :attr:`Control.part`) the model is taken
        as given and every point with ground coordinates is in effect a check point.
        ``recent``: bias fits and parallax lines taken again from an earlier fit of the same
        inputs (a click moves the measurements of one view).
        """
        memo = recent.get if recent is not None else (lambda key, compute: compute())
        points = list(points)
        messages: list[str] = []
        gcps = [p for p in points if p.kind == "GCP" and p.ground is not None]
        heights = [p.ground[2] for p in points if p.ground is not None]
        mean_h = (settings.mean_height if settings.mean_height is not None
                  else control.mean_height if control is not None and control.mean_height is not None
                  else float(np.mean([p.ground[2] for p in gcps])) if gcps
                  else float(np.mean(heights)) if heights else 0.0)
        if control is not None:
            messages.append(f"oriented by {control.source}: no GCP used in the fit; every ground point checks it")
            fixed = control.part
            columns, stats = point_results(scene, points, fixed.bias, fixed.parallax, mean_h, height_of, settings)
            return Solution(scene, settings, cls(scene, fixed.bias, fixed.parallax), columns,
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
                    result = memo(key_of("bias", name, m, xy0, xy, sig),
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
            py, h_fb, c1 = fb_parallax(scene, fb), [p.ground[2] for p in fb], prism.theoretical_c1(scene)
            try:
                parallax = memo(key_of("parallax", settings.parallax_model, c1, py, h_fb),
                                lambda: prism.fit_parallax(py, h_fb, settings.parallax_model, c1))
                if parallax.note:
                    messages.append(parallax.note)
            except ModelError as exc:
                messages.append(str(exc))

        # 3. per point
        adjustment = adjustment_tests(gcps, bias, parallax, scene, settings)
        columns, stats = point_results(scene, points, bias, parallax, mean_h, height_of, settings, adjustment)
        return Solution(scene, settings, cls(scene, bias, parallax), columns, stats, tuple(messages),
                        mean_h, revision, failures, tuple(points))

    def ground_to_image(self, view: str, en, h) -> np.ndarray:
        """Image ``(..., 2)`` px of ground ``en`` ``(..., 2)`` at ellipsoidal ``h``."""
        v = self.scene.views[view]
        return self.bias[view].apply(prism.ground_to_ancillary(self.scene, v, en, h))

    def image_to_ground(self, view: str, xy, h) -> np.ndarray:
        """Map ``(E, N)`` ``(..., 2)`` of image ``xy`` ``(..., 2)`` at ellipsoidal ``h``."""
        v = self.scene.views[view]
        return prism.ancillary_to_ground(self.scene, v, self.bias[view].invert(xy), h)

    def partials(self, view: str, en, h) -> tuple[np.ndarray, np.ndarray]:
        """Central differences of :meth:`ground_to_image` (1 m steps): the model is piecewise
        (the ground track's segments), so its analytic derivative is not worth the code."""
        return central_partials(lambda e, hh: self.ground_to_image(view, e, hh), en, h)

    def bias_cov(self, view: str, xy) -> np.ndarray:
        """``(..., 2, 2)`` px²: the bias fit's parameter covariance at image points ``xy``
        ``(..., 2)`` (the bias acts on the ancillary position, ``invert(xy)``)."""
        fit = self.bias[view]
        xy = np.asarray(xy, float)
        if fit.cov is None or fit.cov.size == 0:
            return np.zeros(xy.shape[:-1] + (2, 2))
        J = bias_jacobian(fit, fit.invert(xy))
        return J @ fit.cov @ np.swapaxes(J, -1, -2)

    def fitted(self, view: str) -> bool:
        return self.bias[view].model != "none"

    @property
    def ok(self) -> bool:
        """The reference view's bias is fitted (the other views may step down or stay as they
        are: they only serve predictions)."""
        return self.bias[self.scene.reference_view].model != "none"

    @property
    def heights_fitted(self) -> bool:
        """Points get heights from the model's own rays: the parallax of a triplet's F and B."""
        return self.scene.is_triplet

    def adjustments(self) -> tuple:
        """``((label, LsqResult), ...)``: the reference view's bias fit and the parallax line,
        the adjustments whose residuals are tested for blunders."""
        ref = self.scene.reference_view
        out = [(f"{ref} bias", self.bias[ref].lsq)]
        if self.parallax is not None:
            out.append(("parallax line", self.parallax.lsq))
        return tuple((label, lsq) for label, lsq in out if lsq is not None)

    def describe(self) -> dict:
        """The model's own part of a report's ``model`` section: the parallax line."""
        par = self.parallax
        if par is None:
            return {}
        return {"parallax": {"requested": par.requested, "used": par.used, "c0": par.c0, "c1": par.c1,
                             "std_c0": par.std_c0, "std_c1": par.std_c1, "c1_theoretical": par.c1_theory,
                             "sigma0_m": par.sigma0, "dof": None if par.lsq is None else par.lsq.dof,
                             "note": par.note, "tilt_m_per_px": [float(par.tilt[0]), float(par.tilt[1])]}}

    @staticmethod
    def control_from_record(scene: Scene, record: dict) -> Control:
        """The orientation a project's saved ``dem_control`` record holds
        (:func:`prismstation.core.orientation.dem_orient.control_from_record`); a malformed record is a
        ``KeyError``, ``TypeError`` or ``ValueError``."""
        return dem_orient.control_from_record(scene, record)


def fb_parallax(scene: Scene, pts) -> np.ndarray:
    """F−B parallax (pixels, along track in N space) of points measured in F and B."""
    if not pts:
        return np.zeros(0)
    return prism.fb_parallax(scene, [p.image["F"] for p in pts], [p.image["B"] for p in pts])[0]


def point_results(scene, points, bias, parallax, mean_h, height_of, settings,
                  adjustment=None) -> tuple[PointColumns, FitStatistics]:
    """Every point's predictions, residuals and ground estimate, vectorised over points, and
    their statistics (:func:`~prismstation.core.models.solution.statistics_of`, from the same arrays).
    ``adjustment`` maps a GCP's id to its ``(std_residual, redundancy, blunder)``."""
    views = scene.views
    n = len(points)
    unmeasured = (np.nan, np.nan)
    X = {v: rows_array([p.image.get(v, unmeasured) for p in points], 2) for v in views}
    has = {v: finite_rows(X[v]) for v in views}
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
    have_k = finite_rows(en_k) & np.isfinite(h_k)
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
    stats = statistics_of(scene, kinds, res, g_res_a, any_m & (source == scene.sensor.height_source),
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




def adjustment_tests(gcps, bias, parallax, scene, settings) -> dict:
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


def bias_jacobian(fit: BiasFit, xy0) -> np.ndarray:
    """``(..., 2, u)`` derivative of the bias-corrected position at ancillary ``xy0`` ``(..., 2)``
    with respect to the fit's published parameters (``fit.names``)."""
    xy0 = np.asarray(xy0, float)
    x, y = xy0[..., 0], xy0[..., 1]
    one, zero = np.ones_like(x), np.zeros_like(x)
    if fit.model == "shift":
        rows = [[one, zero], [zero, one]]
    elif fit.model == "similarity":   # x += a x − c y + b1 ; y += c x + a y + b2
        rows = [[x, -y, one, zero], [y, x, zero, one]]
    elif fit.model == "affine":       # x += B1 x + B2 y + B5 ; y += B3 x + B4 y + B6
        rows = [[x, y, zero, zero, one, zero], [zero, zero, x, y, zero, one]]
    else:
        return np.zeros(xy0.shape[:-1] + (2, 0))
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)
