"""The sensor-model seam: the one interface every sensor model implements.

A sensor model maps ground to the images of a scene and back, with what its fit estimated.
Two implement it, each whole in its own module beside its class: the empirical PRISM 1B2
model of Gonçalves (2008) (:class:`prismstation.core.models.prism_model.PrismModel`) and the rational
function model with an image-space bias of Grodecki & Dial (2003)
(:class:`prismstation.core.models.rpc_model.RpcModel`). ``core/models/sensors.py`` registers them by name;
``ops/sensors.py`` holds each model's workflows (orientation from a reference DEM, the DSM)
and ``gui/sensors.py`` its widgets, under the same name.

Conventions: ground ``en`` ``(..., 2)`` is map metres (E, N) in the scene's CRS and ``h``
ellipsoidal metres (broadcastable to ``en[..., 0]``); image ``xy`` ``(..., 2)`` is pixels,
x = column, y = row, origin at the top-left corner of the top-left pixel (a pixel's centre at
``+0.5``). Every geometry method takes arrays of any leading shape — a point, a list of
points, a grid ``(rows, cols, 2)`` — and returns the same leading shape.

**Where the model is chosen.** Once, where a scene is read (``io/scene.py``): the reader
builds the views of one model and records its class as :attr:`Scene.sensor
<prismstation.core.models.scene.Scene.sensor>`. From there :func:`prismstation.core.models.solution.solve`
fits ``scene.sensor.fit(...)``, and the fitted instance travels in
:attr:`Solution.model <prismstation.core.models.solution.Solution.model>`: predictions, linked cursors,
transfer, reports and an orthoimage call it and never ask which model it is.

**What the class offers** (the solver's and the front ends' side):

``name``
    the word the scene file uses (``"prism"``, ``"rpc"``);
``bias_models``
    the bias models offered, name → number of parameters per view (the model panel's and
    ``--bias``'s choices), and ``default_bias`` for a new project;
``parallax_models``
    the height–parallax relations offered (empty where points are intersected from rays);
``height_source``
    how a point measured in two or more views gets its height in the fit (``"parallax"``:
    the F−B parallax line; ``"intersection"``: multi-ray intersection with its σ) — the points
    whose height residuals the statistics count;
``holds_view_fixed``
    whether one view may be held fixed as the datum of a fit without ground control;
``description``, ``workflows``
    what the images are, in words (``"images with RPCs"``), and the commands that work on a
    project of this model (``"fit"``, ``"report"``, ``"orient-dem"``, ``"dsm"``): the others
    refuse it in one place (:func:`prismstation.ops.project.require_workflow`);
``fit(scene, points, settings, *, height_of, height_sigma_m, revision, control, recent)``
    the model fitted to :class:`~prismstation.core.models.solution.PointObs` → a
    :class:`~prismstation.core.models.solution.Solution`: each view's bias with its covariance, every
    point's ground estimate (how it is obtained from its measurements is the model's:
    parallax line or intersection, else the reference DEM, else the mean height), predictions,
    residuals (measured − predicted, px), blunder tests against
    ``settings.blunder_threshold`` (:func:`prismstation.core.models.solution.critical_value`) and the
    statistics. ``control`` (:class:`~prismstation.core.models.solution.Control`) an orientation made
    elsewhere; ``recent`` (:class:`~prismstation.core.models.recent.Recent`, owned by the caller) what
    an earlier fit of the same inputs computed. It never raises for data the operator can fix
    (messages say why);
``control_from_record(scene, record)``
    the :class:`~prismstation.core.models.solution.Control` of an orientation from a reference DEM
    as a project stores it (``Project.dem_control``; a malformed record is a ``KeyError``,
    ``TypeError`` or ``ValueError``).

**What a fitted instance offers** (everyone else's side), per view name:

``ground_to_image(view, en, h)``, ``image_to_ground(view, xy, h)``
    the model with its fitted bias: ``(..., 2)`` arrays in and out (``image_to_ground`` is
    NaN where the model cannot invert). An orthoimage resamples a view at
    ``ground_to_image(view, en, dem(en))`` over its grid ``en`` ``(rows, cols, 2)``;
``partials(view, en, h)``
    ``(xy, J)``: ``xy`` ``(n, 2)`` and ``J`` ``(n, 2, 3)`` = ∂(x, y)/∂(E, N, h), pixels per metre;
``bias[view]``
    the fitted parameters with their covariance (:class:`BiasParameters`);
``bias_cov(view, xy)``
    ``(..., 2, 2)`` px²: what the parameters' covariance adds to an image position ``xy``;
``fitted(view)``
    whether the view's geolocation is fitted (a bias estimated, or the view is the datum);
``ok``, ``heights_fitted``
    whether the fit succeeded (what :attr:`Solution.ok` reports); whether points get heights
    from the model's own rays (a PRISM triplet, images with RPCs: the height statistics mean
    something);
``adjustments()``
    ``((label, LsqResult), ...)``: the adjustments whose residuals are tested for blunders
    (the window lists their redundancy and critical value);
``describe()``
    the model's own part of a report's ``model`` section beyond the biases (a dict, e.g. the
    PRISM model's parallax line).
"""
from __future__ import annotations

from typing import ClassVar, Mapping, Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class BiasParameters(Protocol):
    """One view's fitted bias: what reports, the model panel and predictions read.

    ``model`` the bias model's name (``"none"``: nothing fitted), ``names`` / ``params`` /
    ``std`` the parameters in their published form, ``cov`` their covariance (a-posteriori
    where the fit has redundancy; None or empty when not fitted), ``M`` ``(2, 2)`` and ``b``
    ``(2,)`` the correction written as ``Δxy = M·xy + b`` px (where the model is linear in the
    image point), ``lsq`` the view's share of the adjustment
    (:class:`~prismstation.core.adjustment.lsq.LsqResult`: ``sigma0``, ``dof``, residuals, redundancy
    numbers, studentised residuals) or None, ``sigma0`` its a-posteriori σ0 (unitless: a
    measurement's σ is its a-priori σ times σ0), ``dof`` the fit's redundancy."""

    model: str
    names: tuple
    params: np.ndarray
    std: np.ndarray
    cov: np.ndarray | None
    M: np.ndarray
    b: np.ndarray
    lsq: object

    @property
    def sigma0(self) -> float | None: ...

    @property
    def dof(self) -> int: ...


@runtime_checkable
class SensorModel(Protocol):
    """A sensor model: the class's choices and fit, and a fitted instance's geometry (module
    docstring)."""

    name: ClassVar[str]
    bias_models: ClassVar[Mapping[str, int]]
    default_bias: ClassVar[str]
    parallax_models: ClassVar[tuple]
    height_source: ClassVar[str]
    holds_view_fixed: ClassVar[bool]
    description: ClassVar[str]
    workflows: ClassVar[frozenset]

    scene: object
    bias: Mapping[str, BiasParameters]

    @classmethod
    def fit(cls, scene, points, settings, *, height_of=None, height_sigma_m=None, revision: int = 0,
            control=None, recent=None): ...

    @staticmethod
    def control_from_record(scene, record: dict): ...

    def ground_to_image(self, view: str, en, h) -> np.ndarray: ...

    def image_to_ground(self, view: str, xy, h) -> np.ndarray: ...

    def partials(self, view: str, en, h) -> tuple[np.ndarray, np.ndarray]: ...

    def bias_cov(self, view: str, xy) -> np.ndarray: ...

    def fitted(self, view: str) -> bool: ...

    @property
    def ok(self) -> bool: ...

    @property
    def heights_fitted(self) -> bool: ...

    def adjustments(self) -> tuple: ...

    def describe(self) -> dict: ...


#: central-difference step of partials taken numerically (metres)
STEP_M = 1.0


def central_partials(ground_to_image, en, h, step_m: float = STEP_M) -> tuple[np.ndarray, np.ndarray]:
    """``(xy, J)`` of ``ground_to_image(en, h)`` at ``n`` points ``en`` ``(n, 2)``, ``h`` ``(n,)``
    by central differences of ``step_m`` metres in E, N and h: ``xy`` ``(n, 2)``, ``J``
    ``(n, 2, 3)`` pixels per metre. One call of ``ground_to_image`` on the ``7n`` points
    ``[g, g + s·e_k, g − s·e_k]`` (rows in that order for ``n = 1``)."""
    g = np.column_stack([np.asarray(en, float).reshape(-1, 2), np.asarray(h, float).reshape(-1)])
    n = len(g)
    steps = np.vstack([g, *(g + step_m * e for e in np.eye(3)), *(g - step_m * e for e in np.eye(3))])
    xy = ground_to_image(steps[:, :2], steps[:, 2]).reshape(7, n, 2)
    J = np.transpose(xy[1:4] - xy[4:7], (1, 2, 0)) / (2 * step_m)
    return xy[0], J
