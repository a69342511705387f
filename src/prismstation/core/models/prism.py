"""The empirical PRISM 1B2 model of Gonçalves (2008) (docs/model.md §2): relief, bias, parallax.

Map points ``en`` are ``(..., 2)`` metres, heights ``h`` ellipsoidal metres (broadcastable to
``en[..., 0]``), image points ``xy`` ``(..., 2)`` pixels (x = column, y = row).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from prismstation.core.adjustment import lsq
from prismstation.core.adjustment.affine import Affine2D
from prismstation.core.adjustment.estimate import (MAX_CONDITION, SINGULAR, Normaliser, check_points, condition_number,
                                        degenerate, failure_or, published_cov)
from prismstation.core.models.scene import Scene, View
from prismstation.errors import ModelError

#: bias models and their parameter counts (= 2 × minimum GCPs)
BIAS_MODELS = {"shift": 2, "similarity": 4, "affine": 6}
PARALLAX_MODELS = ("line", "offset", "theoretical")


# ---------------------------------------------------------------- relief displacement
def relief_shift(scene: Scene, view: View, en, h) -> np.ndarray:
    """Map displacement ``(..., 2)`` of a point at height ``h`` in a 1B2 image of ``view``.

    Across track ``h·tanβ·u`` with ``tanβ = d / Hs`` — i.e. ``(h / Hs)·(P − foot)`` — and
    along track ``± h·tanθ·t`` for the forward (+) and backward (−) views.
    """
    en = np.asarray(en, dtype=float)
    h = np.asarray(h, dtype=float)[..., None]
    foot, t = scene.track.foot(en)
    shift = (h / scene.satellite_altitude_m) * (en - foot)
    if view.look_sign:
        shift = shift + view.look_sign * view.tan_theta * h * t
    return shift


def ground_to_ancillary(scene: Scene, view: View, en, h) -> np.ndarray:
    """Image position ``x0'`` (eq. 1 + 2): ``map_to_image(P + relief_shift)`` before bias."""
    en = np.asarray(en, dtype=float)
    return view.map_to_image(en + relief_shift(scene, view, en, h))


def ancillary_to_ground(scene: Scene, view: View, xy0, h, iterations: int = 10,
                        tol_m: float = 1e-9) -> np.ndarray:
    """Invert :func:`ground_to_ancillary` at known height ``h``: image ``x0'`` → map ``(E, N)``.

    The relief shift depends on the point's own position (β), hence the fixed-point
    iteration; it contracts by ~h/Hs (≈ 0.013 at 9 km), so it stops after the step falls below
    ``tol_m`` metres (5–6 iterations: forward and inverse then agree to 1e-6 px) or after
    ``iterations``.
    """
    apparent = image_to_map(view)(xy0)
    en = apparent
    for _ in range(iterations):
        new = apparent - relief_shift(scene, view, en, h)
        step = np.abs(new - en)
        en = new
        if not np.any(step >= tol_m):
            break
    return en


def to_nadir_space(scene: Scene, view: View) -> Affine2D:
    """Affine carrying ``view`` image coordinates into N image space through the map (§3.1)."""
    return _composed(scene.views["N"].map_to_image, image_to_map(view))


def image_to_map(view: View) -> Affine2D:
    """``view.map_to_image.inverse()``: image pixels → map metres at the ellipsoid (cached)."""
    return _inverse(view.map_to_image)


# A fit inverts and composes the same few affines many times; Affine2D is immutable and
# hashed by identity, so the results can be kept (the cache holds the affines alive).
@functools.lru_cache(maxsize=64)
def _inverse(affine: Affine2D) -> Affine2D:
    return affine.inverse()


@functools.lru_cache(maxsize=64)
def _composed(a: Affine2D, b: Affine2D) -> Affine2D:
    return a @ b


def along_track_unit(scene: Scene, en) -> np.ndarray:
    """Unit vector ``(..., 2)`` of the flight direction in N image space at map points ``en``."""
    _, t = scene.track.foot(en)
    s = scene.views["N"].map_to_image.apply_linear(t)
    return s / np.linalg.norm(s, axis=-1, keepdims=True)


def scene_track_dir(scene: Scene, en) -> np.ndarray:
    """Unit flight direction ``(..., 2)`` in map coordinates at map points ``en``."""
    return scene.track.foot(en)[1]


def theoretical_c1(scene: Scene) -> float:
    """``p / (tanθF + tanθB)``: metres of height per pixel of F−B parallax (eq. 4)."""
    v = scene.views
    return v["N"].pixel_size_m / (v["F"].tan_theta + v["B"].tan_theta)


# ---------------------------------------------------------------- bias compensation (eq. 3)
_BIAS_NAMES = {
    "none": (),
    "shift": ("b1", "b2"),
    "similarity": ("a", "c", "b1", "b2"),
    "affine": ("B1", "B2", "B3", "B4", "B5", "B6"),
}


def _bias_design(model: str, q: np.ndarray) -> np.ndarray:
    """Rows for ``Δ = M·q + b`` (x rows then y rows interleaved) in normalised coordinates."""
    n = len(q)
    A = np.zeros((2 * n, BIAS_MODELS[model]))
    qx, qy = q[:, 0], q[:, 1]
    if model == "shift":
        A[0::2, 0] = 1; A[1::2, 1] = 1
    elif model == "similarity":  # M = [[a, -c], [c, a]]
        A[0::2, 0], A[0::2, 1], A[0::2, 2] = qx, -qy, 1
        A[1::2, 0], A[1::2, 1], A[1::2, 3] = qy, qx, 1
    else:  # affine, the paper's B1..B6
        A[0::2, 0], A[0::2, 1], A[0::2, 4] = qx, qy, 1
        A[1::2, 2], A[1::2, 3], A[1::2, 5] = qx, qy, 1
    return A


def _bias_matrix(model: str, p) -> tuple[np.ndarray, np.ndarray]:
    """``(M, b)`` from parameters in the model's order."""
    if model == "shift":
        return np.zeros((2, 2)), np.array(p[:2], float)
    if model == "similarity":
        a, c, b1, b2 = p
        return np.array([[a, -c], [c, a]], float), np.array([b1, b2], float)
    B1, B2, B3, B4, B5, B6 = p
    return np.array([[B1, B2], [B3, B4]], float), np.array([B5, B6], float)


@dataclass(frozen=True, eq=False)
class BiasFit:
    """Bias compensation in image space: ``x = x0' + M·x0' + b`` (pixels; eq. 3).

    An estimator (:mod:`prismstation.core.adjustment.estimate`) from ancillary positions ``x0'`` to
    measured ``x``: ``fit(xy0, xy, model, sigma)``, ``t(xy0)``, ``t.inverse(xy)``,
    ``t.residuals(xy0, xy)``. ``params`` and ``std`` are in the published (un-normalised)
    form named by ``names``, ``cov`` their covariance (None when not fitted). ``lsq`` holds the
    adjustment (residuals ordered x0, y0, x1, y1, …) or None.
    """

    model: str
    M: np.ndarray
    b: np.ndarray
    params: np.ndarray
    std: np.ndarray
    names: tuple[str, ...]
    lsq: lsq.LsqResult | None = None
    cov: np.ndarray | None = None

    @classmethod
    def identity(cls) -> "BiasFit":
        return cls("none", np.zeros((2, 2)), np.zeros(2), np.zeros(0), np.zeros(0), (),
                   None, np.zeros((0, 0)))

    @classmethod
    def fit(cls, xy0, xy, model: str = "affine", sigma=None, *, what: str = "bias"):
        """:func:`fit_bias`, returning a falsy :class:`~prismstation.core.adjustment.estimate.FailedFit`
        with the reason instead of raising."""
        return failure_or(fit_bias, xy0, xy, model, sigma, what=what)

    def apply(self, xy0) -> np.ndarray:
        """Ancillary positions ``(..., 2)`` → bias-corrected image positions (pixels)."""
        xy0 = np.asarray(xy0, dtype=float)
        return xy0 + xy0 @ self.M.T + self.b

    __call__ = apply

    def invert(self, xy) -> np.ndarray:
        """Image positions ``(..., 2)`` → ancillary positions (pixels)."""
        xy = np.asarray(xy, dtype=float)
        return (xy - self.b) @ np.linalg.inv(np.eye(2) + self.M).T

    inverse = invert

    def residuals(self, xy0, xy) -> np.ndarray:
        """``(n, 2)`` observed − computed ``xy − self(xy0)`` (pixels)."""
        return np.asarray(xy, float) - self.apply(xy0)

    @property
    def sigma0(self) -> float | None:
        return None if self.lsq is None else self.lsq.sigma0

    @property
    def dof(self) -> int:
        """Redundancy ``2n − u`` of the fit (0 when not fitted)."""
        return 0 if self.lsq is None else self.lsq.dof


_MODEL_NEEDS = {"shift": "one GCP", "similarity": "two distinct GCPs",
                "affine": "GCPs spread in two directions"}


def fit_bias(xy0, xy, model: str, sigma=None, *, what: str = "bias") -> BiasFit:
    """Fit the bias model from ancillary positions ``xy0`` ``(n, 2)`` to measured ``xy`` ``(n, 2)``.

    ``sigma`` (n,) or scalar: a-priori σ of each measurement in pixels (default 1; σ0 is then
    in pixels, else unitless). Coordinates are
    centred and scaled before solving; parameters and covariance are returned published.
    Raises :class:`~prismstation.errors.DegenerateGeometry` when there are too few points,
    they coincide or (affine) lie on or nearly on one line — condition number of the
    normalised design above :data:`~prismstation.core.adjustment.estimate.MAX_CONDITION` — and
    :class:`ModelError` for an unknown model.
    """
    if model not in BIAS_MODELS:
        raise ModelError(f"unknown bias model {model!r}; choose one of {', '.join(BIAS_MODELS)}")
    xy0 = np.asarray(xy0, dtype=float).reshape(-1, 2)
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    u = BIAS_MODELS[model]
    need = u // 2
    check_points(len(xy0), need, f"{what}: the {model} model",
                 f"GCP{'s' * (need > 1)} measured in this view")
    norm = Normaliser.of(xy0)
    A = _bias_design(model, norm.fwd(xy0))
    k = condition_number(A)
    if k > MAX_CONDITION:
        lie = ("coincide" if model != "affine" or np.all(xy0 == xy0[0]) else
               "lie on one line" if not k < SINGULAR else "lie nearly on one line")
        raise degenerate(f"{what}: the GCPs {lie} (condition number {k:.3g} > {MAX_CONDITION:.0f}); "
                         f"the {model} model needs {_MODEL_NEEDS[model]}", k)
    sig = None if sigma is None else np.repeat(np.broadcast_to(np.asarray(sigma, float), len(xy0)), 2)
    res = lsq.solve(A, (xy - xy0).ravel(), sig, what=f"{what} ({model})")
    c, s = norm.centre, norm.scale

    def published(pn):
        Mn, bn = _bias_matrix(model, pn)
        M = Mn / s
        b = bn - M @ c
        if model == "shift":
            return b
        if model == "similarity":
            return np.array([M[0, 0], M[1, 0], b[0], b[1]])
        return np.array([M[0, 0], M[0, 1], M[1, 0], M[1, 1], b[0], b[1]])

    p, cov = published_cov(published, res.params, res.cov)
    M, b = _bias_matrix(model, p)
    return BiasFit(model, M, b, p, np.sqrt(np.diag(cov)), _BIAS_NAMES[model], res, cov)


# ---------------------------------------------------------------- parallax line (eq. 4)
def fb_parallax(scene: Scene, xy_f, xy_b):
    """F−B parallax of F and B image coordinates ``(n, 2)``: ``(py (n,), mid (n, 2))``, py in
    N pixels along track, ``mid`` the F–B midpoint in N space (where the parallax is)."""
    f = to_nadir_space(scene, scene.views["F"])(np.asarray(xy_f, float))
    b = to_nadir_space(scene, scene.views["B"])(np.asarray(xy_b, float))
    mid = (f + b) / 2
    return np.einsum("ij,ij->i", f - b, along_track_unit(scene, image_to_map(scene.views["N"])(mid))), mid


@dataclass(frozen=True, eq=False)
class ParallaxLine:
    """``h = c0 + c1·py`` (metres from pixels). ``used`` says what was fitted:
    ``line`` (c0, c1), ``offset`` (c0; c1 theoretical) or ``theoretical`` (nothing).

    ``tilt`` (metres per N-image pixel, x and y): ``c0`` varying over the scene as
    ``c0 + tilt·xy`` at N-image position ``xy`` (the F–B midpoint in N space). Zero for a
    GCP fit (the paper's line); a reference-DEM orientation sets it from its patches' height
    field, which varies by metres across a 14,000 px scene (attitude drift)."""

    requested: str
    used: str
    c0: float
    c1: float
    c1_theory: float
    std_c0: float | None = None
    std_c1: float | None = None
    lsq: lsq.LsqResult | None = None
    note: str = ""
    tilt: tuple = (0.0, 0.0)

    def height(self, py, xy=None) -> np.ndarray:
        """Heights (m) of parallaxes ``py`` (px, shape (...)) at N-image positions ``xy``
        (..., 2), which a tilted line needs."""
        h = self.c0 + self.c1 * np.asarray(py, dtype=float)
        if self.tilt[0] or self.tilt[1]:
            if xy is None:
                raise ValueError("a tilted parallax line needs the N-image positions")
            xy = np.asarray(xy, dtype=float)
            h = h + self.tilt[0] * xy[..., 0] + self.tilt[1] * xy[..., 1]
        return h

    @property
    def sigma0(self) -> float | None:
        return None if self.lsq is None else self.lsq.sigma0



class FixedPrism(NamedTuple):
    """The PRISM model as an orientation made elsewhere fixes it (the ``part`` of a
    :class:`~prismstation.core.models.solution.Control`): ``bias`` view → :class:`BiasFit` and the
    ``parallax`` line; the fit then only evaluates the points."""

    bias: dict
    parallax: ParallaxLine | None

def fit_parallax(py, h, mode: str, c1_theory: float) -> ParallaxLine:
    """Fit the height–parallax relation over GCPs (``py`` pixels, ``h`` metres, ``(n,)``).

    Degrades as docs/model.md says: ``line`` with one GCP fits only ``c0``; with none, the
    theoretical line through the origin. σ0 is in metres (unit weights).
    """
    if mode not in PARALLAX_MODELS:
        raise ModelError(f"unknown parallax model {mode!r}; choose one of {', '.join(PARALLAX_MODELS)}")
    py = np.asarray(py, dtype=float)
    h = np.asarray(h, dtype=float)
    n = len(py)
    used, note = mode, ""
    if used == "line" and (n < 2 or np.ptp(py) < 1.0):
        used, note = "offset", (f"{n} GCP with parallax: only the offset c0 is fitted, c1 is theoretical"
                                if n < 2 else "GCPs have no spread in parallax: c1 kept theoretical")
    if used == "offset" and n < 1:
        used, note = "theoretical", "no GCP measured in F and B: theoretical parallax line"
    if used == "theoretical":
        return ParallaxLine(mode, used, 0.0, c1_theory, c1_theory, note=note)
    if used == "offset":
        res = lsq.solve(np.ones((n, 1)), h - c1_theory * py, what="parallax offset")
        return ParallaxLine(mode, used, float(res.params[0]), c1_theory, c1_theory,
                            float(res.std[0]), None, res, note)
    pc, ps = py.mean(), max(float(np.ptp(py)), 1.0)
    A = np.column_stack([np.ones(n), (py - pc) / ps])
    res = lsq.solve(A, h, what="parallax line")
    J = np.array([[1.0, -pc / ps], [0.0, 1.0 / ps]])
    p, cov = J @ res.params, J @ res.cov @ J.T
    return ParallaxLine(mode, used, float(p[0]), float(p[1]), c1_theory,
                        float(np.sqrt(cov[0, 0])), float(np.sqrt(cov[1, 1])), res, note)
