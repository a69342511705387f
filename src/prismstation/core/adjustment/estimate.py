"""The one protocol every fitted transform of :mod:`prismstation.core` follows, and the one
shape of a result that failed.

Failure as a value
------------------
Every result that can fail — a fit, a co-registration, a resection, a parallax map, rays
meeting a DEM — is **falsy when it failed** and has a **``reason``** (a sentence for the
operator; ``""`` when it did not fail), after scikit-image's transforms::

    fit = Affine2D.fit(src, dst)          # or BiasFit.fit, FittedTransform.fit, ShiftField.fit
    if not fit:
        status(fit.reason)                # never a try/except around a click

The results: :class:`FailedFit` (what ``T.fit`` returns instead of a transform),
:class:`~prismstation.core.matching.coreg.CoregResult` (no shift found: ``converged`` False),
:class:`~prismstation.core.models.resection.ResectionResult` (not converged),
:class:`~prismstation.core.matching.dense.ParallaxMap` (cancelled: incomplete),
:class:`~prismstation.core.models.ray_dem.RayHits` (a ray did not meet the surface),
:class:`~prismstation.ops.coregister.Coregistration`. A failed result may still carry what
was computed (statistics, a partial map) for display; it must not be used as a success.
Bad *input* (a file, a value out of range) is not a failed result: it raises
:class:`~prismstation.errors.InputError`; a cancelled operation raises
:class:`~prismstation.errors.Cancelled` (:mod:`prismstation.ops.progress`). A judgement on a
result that did compute — the χ² verdict of an orientation's patches, a DSM's fill below the
minimum — is a field of the result (``verdict``, ``low_fill``), not a failure.

Fitted transforms
-----------------

After scikit-image's geometric transforms (``from_estimate`` returning the transform or a
falsy failure), with the statistics a photogrammetrist reads added:

- ``T.fit(src, dst, …)`` (class method; options: the model or kind, the σ of each ``dst``
  point) → the fitted, immutable transform, or a :class:`FailedFit` (falsy) carrying the
  typed error and its reason — a GUI calls it on every click and never needs a ``try``; the
  ``fit_…`` functions raise instead. Implemented by ``Affine2D``, ``BiasFit``,
  ``FittedTransform`` (rectification) and ``ShiftField``;
- ``t(xy)`` forward, ``t.inverse(xy)`` backward, points ``(n, 2)`` → ``(n, 2)`` (``(n, k)``
  shifts for a ``ShiftField``);
- ``t.residuals(src, dst)`` observed − computed ``dst − t(src)``, shaped like ``dst``;
- ``t.params`` in the transform's published form, ``t.cov`` their covariance (of
  ``params.ravel()``, a-posteriori ``σ0²·N⁻¹`` when there is redundancy), ``t.sigma0`` the
  a-posteriori σ of unit weight (None or NaN without redundancy), ``t.dof`` the redundancy
  ``r = (number of observations) − (number of parameters)``.

Degenerate geometry
-------------------
A fit whose design matrix, written in normalised coordinates (centred, one isotropic scale),
has a condition number ``κ = s_max / s_min`` above :data:`MAX_CONDITION` raises
:class:`~prismstation.errors.DegenerateGeometry` naming κ. For a model with an affine part, κ
of ``[1, u, v]`` is about the length of the strip holding the points divided by its width
(measured: 10 points spread uniformly over a square κ ≈ 1.1–2; in a strip 1/10 of its length
wide κ ≈ 7–16; 30 m wide across 30 km κ ≈ 650–1800; 2 m across 30 km κ ≈ 10⁴–2.5·10⁴). Noise
across the strip is amplified ~κ times into the model within the points' own extent. κ = 1000
means a strip 10 px wide across a 10⁴ px image — within a few measurement σ (0.5–3 px) of a
line, so the direction across it is set by the noise, not by the points.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Protocol, runtime_checkable

import numpy as np

from prismstation.errors import DegenerateGeometry, ModelError

#: largest condition number of a normalised design matrix accepted (see the module docstring)
MAX_CONDITION = 1e3
#: condition number from which a design counts as exactly singular (rounding errors only)
SINGULAR = 1e10


@dataclass(frozen=True)
class FailedFit:
    """A fit that did not succeed: falsy; ``reason`` says why, ``error`` is the typed error
    (:class:`~prismstation.errors.DegenerateGeometry` for too few, coincident or nearly
    collinear points) that :meth:`unwrap` raises; ``condition`` is κ when it was measured."""

    error: ModelError

    def __bool__(self) -> bool:
        return False

    def __str__(self) -> str:
        return self.reason

    @property
    def reason(self) -> str:
        return str(self.error)

    @property
    def degenerate(self) -> bool:
        return isinstance(self.error, DegenerateGeometry)

    @property
    def condition(self) -> float | None:
        return getattr(self.error, "condition", None)

    def unwrap(self):
        raise self.error


@runtime_checkable
class Estimator(Protocol):
    """What every fitted transform offers (see the module docstring)."""

    params: np.ndarray
    cov: np.ndarray

    @property
    def sigma0(self): ...

    @property
    def dof(self) -> int: ...

    def __call__(self, xy) -> np.ndarray: ...

    def inverse(self, xy) -> np.ndarray: ...

    def residuals(self, src, dst) -> np.ndarray: ...


def failure_or(fit: Callable, *args, **kwargs):
    """``fit(*args, **kwargs)``, or a :class:`FailedFit` when it raises :class:`ModelError`
    (the body of every estimator's ``fit`` class method)."""
    try:
        return fit(*args, **kwargs)
    except ModelError as exc:
        return FailedFit(exc)


def degenerate(message: str, condition: float | None = None) -> DegenerateGeometry:
    """A :class:`DegenerateGeometry` whose ``condition`` attribute holds κ (or None)."""
    exc = DegenerateGeometry(message)
    exc.condition = condition
    return exc


@dataclass(frozen=True)
class Normaliser:
    """Isotropic centring and scaling ``u = (p − centre) / scale`` (mean distance √2 from the
    centre; scale 1 for coincident points)."""

    centre: np.ndarray
    scale: float

    @classmethod
    def of(cls, pts) -> "Normaliser":
        pts = np.asarray(pts, float).reshape(-1, 2)
        c = pts.mean(axis=0)
        d = np.sqrt(((pts - c) ** 2).sum(axis=1)).mean()
        return cls(c, float(d / np.sqrt(2.0)) if d > 0 else 1.0)

    def fwd(self, p):
        return (np.asarray(p, float) - self.centre) / self.scale

    def back(self, u):
        return np.asarray(u, float) * self.scale + self.centre


def condition_number(A) -> float:
    """``s_max / s_min`` of ``A`` (inf when rank-deficient or empty)."""
    s = np.linalg.svd(np.asarray(A, float), compute_uv=False)
    return float(s[0] / s[-1]) if s.size and s[-1] > 0 else float("inf")


def check_points(n: int, need: int, what: str, noun: str = "points") -> None:
    """Raise :class:`DegenerateGeometry` when ``n`` < ``need`` points."""
    if n < need:
        raise degenerate(f"{what} needs at least {need} {noun}, have {n}")


def check_spread(u: np.ndarray, what: str, noun: str = "points",
                 max_condition: float = MAX_CONDITION) -> float:
    """κ of ``[1, u, v]`` for normalised points ``u`` ``(n, 2)``; raise
    :class:`DegenerateGeometry` when the points coincide, lie on a line, or nearly so."""
    k = condition_number(np.column_stack([np.ones(len(u)), u]))
    if not k < SINGULAR or np.abs(u).max(initial=0.0) == 0:
        raise degenerate(f"{what}: the {noun} are collinear or coincident (condition number {k:.3g})", k)
    if k > max_condition:
        raise degenerate(f"{what}: the {noun} lie nearly on one line (condition number {k:.3g} > "
                         f"{max_condition:.0f}); they must be spread in two directions", k)
    return k


def published_cov(publish: Callable[[np.ndarray], np.ndarray], p: np.ndarray,
                  cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Parameters and covariance after an affine reparametrisation ``publish`` (e.g. from
    normalised to published coordinates): ``(publish(p), J·cov·Jᵀ)``, J exact by columns."""
    f0 = publish(np.zeros_like(p))
    J = np.column_stack([publish(e) - f0 for e in np.eye(p.size)])
    return J @ p + f0, J @ cov @ J.T
