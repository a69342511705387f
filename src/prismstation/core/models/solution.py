"""What every sensor model's fit takes and gives: the shared result types.

:class:`Settings` (the model choices), :class:`PointObs` (a point as a fit sees it),
:class:`Control` (an orientation made elsewhere, as a fit takes it) and :class:`Solution` (a
fit: the fitted sensor model, every point's results, the statistics). :func:`solve` fits the
scene's sensor model (:mod:`prismstation.core.models.sensor`); the statistics and the blunder tests
(:func:`statistics`, :func:`critical_value`, :func:`normal_equivalent`) are the same for every
model. A fit never raises for data the operator can fix (too few GCPs, collinear GCPs, a point
seen in too few views): such parts are left out of the :class:`Solution` and
:attr:`Solution.messages` says why.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Callable, Mapping

import numpy as np
from scipy import special

from prismstation.core.models.results import PointColumns, PointResult
from prismstation.core.models.scene import Scene
from prismstation.core.adjustment.stats import ComponentStats, FitStatistics, ImageStats, VectorStats

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
    # models that fit an image-space bias per view and hold tie points to a reference DEM
    # (images with RPCs): ((view, bias model), ...) where a view departs from ``bias_model``;
    # the reference DEM's height σ (m; None: the default of an SRTM-class DEM); whether GCPs
    # enter the fit (False: they are checked, as check points are)
    view_bias: tuple = ()
    reference_sigma_m: float | None = None
    use_gcps: bool = True

    def bias_of(self, view: str) -> str:
        """The bias model of ``view``: its own in ``view_bias``, else ``bias_model``."""
        return dict(self.view_bias).get(view, self.bias_model)


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
    """An immutable fit, the same for every sensor model: ``model`` the fitted sensor model
    (:mod:`prismstation.core.models.sensor`: its geometry with the fitted biases, and whatever is its
    own — the PRISM model's parallax line), per-point results and statistics. ``failures``
    holds the typed reason (a falsy :class:`~prismstation.core.adjustment.estimate.FailedFit`:
    ``degenerate``, ``condition``) when the reference view's bias could not be fitted;
    ``messages`` says it in words; ``revision`` the project revision it was fitted at."""

    scene: Scene
    settings: Settings
    model: object                 # the fitted sensor model (core/models/sensor.py)
    columns: PointColumns         # every point's results as arrays (the window reads these)
    stats: FitStatistics
    messages: tuple
    mean_height: float
    revision: int = 0
    failures: dict = field(default_factory=dict)  # view -> FailedFit of its bias (reference view)
    observations: tuple = ()      # the PointObs of a GCP fit (to refit it without some of them)

    @property
    def bias(self) -> Mapping:
        """View → its fitted bias (:class:`~prismstation.core.models.sensor.BiasParameters`)."""
        return self.model.bias

    # ---- geometry through the fitted model (linked cursors, predictions)
    def ground_to_image(self, view: str, en, h) -> np.ndarray:
        """Image ``(..., 2)`` px of ground ``en`` ``(..., 2)`` map metres at ellipsoidal ``h``
        (:meth:`SensorModel.ground_to_image <prismstation.core.models.sensor.SensorModel>`)."""
        return self.model.ground_to_image(view, en, h)

    def image_to_ground(self, view: str, xy, h) -> np.ndarray:
        """Map ``(E, N)`` ``(..., 2)`` of image ``xy`` ``(..., 2)`` px at ellipsoidal ``h``."""
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
    """An orientation made elsewhere (from a reference DEM, docs/model.md §3) as a model's fit
    takes it: ``source`` in words (the fit's messages say it), ``part`` the model's own (the
    PRISM model: its bias per view and parallax line, which the fit then only evaluates —
    :class:`~prismstation.core.models.prism.FixedPrism`; the RPC model: each view's a-priori
    bias, view → :class:`~prismstation.core.models.rpc_solve.BiasPrior`, which the fit adjusts with),
    ``mean_height`` the height of points nothing else places (m, ellipsoidal; None: the fit's
    own). Made by the model's ``control_from_record`` from a project's saved record."""

    source: str
    part: object
    mean_height: float | None = None


def solve(scene: Scene, points, settings: Settings = Settings(), *,
          height_of: HeightFn | None = None, height_sigma_m: float | None = None, revision: int = 0,
          control: Control | None = None, recent=None) -> Solution:
    """Fit the scene's sensor model (``scene.sensor.fit``) to ``points`` (iterable of
    :class:`PointObs`). ``height_of``: the reference DEM's ellipsoidal heights at map points
    (heights of points no ray pair places; a model may also hold tie points to it, with
    ``height_sigma_m``, its σ in metres); ``control``: an orientation made elsewhere;
    ``recent``: a :class:`~prismstation.core.models.recent.Recent` the caller keeps between fits (a
    model may take again what an earlier fit computed from the same inputs)."""
    return scene.sensor.fit(scene, points, settings, height_of=height_of, height_sigma_m=height_sigma_m,
                            revision=revision, control=control, recent=recent)


def finite_rows(xy: np.ndarray) -> np.ndarray:
    """``(n,)`` True where both values of a row of ``xy`` ``(n, 2)`` are finite (the same as
    ``np.all(np.isfinite(xy), axis=1)``, which is slow on rows of two)."""
    return np.isfinite(xy[:, 0]) & np.isfinite(xy[:, 1])


@functools.lru_cache(maxsize=256)
def critical_value(threshold: float, dof: int) -> float:
    """Critical |externally studentised residual| for ``dof`` redundancy: Student's t with
    ``dof − 1`` degrees of freedom at the two-sided α of ``threshold`` under the normal law
    (3.29 ↔ α = 0.001, Baarda). With few GCPs the t tails are heavy, hence a larger value."""
    # scipy.special holds what scipy.stats' norm.sf and t.isf evaluate (same numbers): the
    # first fit of a session does not wait about a second for scipy.stats to import
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
    w = np.abs(np.asarray(w, float))
    tail = special.stdtr(max(dof - 1, 1), -w)
    with np.errstate(divide="ignore"):
        z = -special.ndtri(tail)
    # beyond double precision (|w| of hundreds): the tail underflows; |w| itself is then far
    # beyond any threshold
    return np.where(np.isfinite(z) | np.isnan(w), z, w)


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
        fitted |= finite_rows(a)
    ties = bool(np.any((kinds == "TIE") & fitted))
    return statistics_of(scene, kinds, residual, columns.ground_residual, own, across, ties)


def statistics_of(scene: Scene, kinds: np.ndarray, residual: dict, ground: np.ndarray, own_height: np.ndarray,
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
