"""Where a point should be in the views it is not measured in, and how sure that is.

A prediction takes the best ground position available for the point:

``ground``
    a GCP or ICP: its known coordinates, with its own σ (``sigma_xy_m``, ``sigma_h_m``; none
    given: exact);
``intersection``
    measured in two or more views: the least-squares intersection of those image rays through
    the fitted sensor model, with the reference DEM's height (or the mean height) as
    one more observation with its σ — where the pixels are coarse and the DEM good, the DEM
    may know the height better than the rays;
``reference``
    measured in one view, the reference DEM under it: that view's ray at the DEM height, the
    height taken as an observation with the DEM's σ (:func:`dem_sigma`);
``mean``
    measured in one view, no DEM there: the ray at the solution's mean height with the spread
    of the project's known heights as σ (:func:`height_spread`).

Uncertainty (the error ellipse): the covariance of the predicted image position (px², x
column, y row) propagates, to first order,

* the bias-fit parameter covariance of the predicted view (a-posteriori; the sensor model's
  ``bias_cov``, :mod:`prismstation.core.models.sensor`);
* the covariance of the ground position, from the measurements used (each with its σ — its own
  ``sigma_px`` or the settings' a-priori σ — scaled by the a-posteriori σ0 of that view's bias
  fit, plus that view's bias-parameter covariance) and the height's σ.

It is the uncertainty of the predicted *true* position; a measurement there adds its own σ.
The fits of different views are taken as independent; the slope of the DEM within the ray's
uncertainty is ignored. ``tests/ops/test_predict.py`` checks the ellipses against the
empirical scatter of predictions over repeated noisy measurements (Monte Carlo).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from prismstation.core.models.ray_dem import ray_meets_surface
from prismstation.core.models.sensor import STEP_M
from prismstation.core.models.solution import Solution
from prismstation.ops.fit import ellipsoidal_heights

CHI2_95_2D = 5.991464547107979
"""χ² with 2 degrees of freedom at 95 %: the 95 % ellipse has semi-axes ``sqrt(5.99·λ)``."""
DEFAULT_DEM_SIGMA_M = 10.0
"""σ of a reference DEM's heights when the project cannot measure it (an SRTM-class DEM:
16 m LE90 absolute, i.e. about 10 m σ)."""
DEFAULT_HEIGHT_SPREAD_M = 500.0
"""σ of an unknown height when the project holds fewer than two known heights (metres)."""


@dataclass(frozen=True)
class PointInput:
    """One point as the predictor sees it. ``measured``: view → ``(x, y, σ px or None)``;
    ``ground``: ``(E, N, h ellipsoidal)`` or None; ``sigma_ground``: ``(σ plan, σ h)`` metres."""

    id: str
    kind: str
    measured: dict
    ground: tuple | None = None
    sigma_ground: tuple = (0.0, 0.0)


@dataclass(frozen=True, eq=False)
class Prediction:
    """The predicted image position ``xy`` of a point in ``view`` (pixels) and its covariance
    ``cov`` (2×2, px²); ``source`` names the ground used, ``height`` and ``sigma_h`` (metres)
    its height."""

    view: str
    xy: tuple
    cov: np.ndarray
    source: str
    height: float
    sigma_h: float

    def ellipse(self, chi2: float = CHI2_95_2D) -> tuple[float, float, float]:
        """``(a, b, angle)``: semi-axes (pixels, a ≥ b) of the ellipse holding the true position
        with the probability of ``chi2`` (default 95 %), and the direction of ``a`` (radians
        from the image x axis towards +y)."""
        w, v = np.linalg.eigh(self.cov)
        w = np.clip(w, 0.0, None)
        return (math.sqrt(chi2 * w[1]), math.sqrt(chi2 * w[0]), math.atan2(v[1, 1], v[0, 1]))


# ---------------------------------------------------------------------- heights and their σ
def height_spread(heights) -> float:
    """σ of a height nothing else tells: the standard deviation of the project's known
    heights (metres), :data:`DEFAULT_HEIGHT_SPREAD_M` with fewer than two."""
    h = np.asarray(list(heights), float)
    h = h[np.isfinite(h)]
    return float(np.std(h, ddof=1)) if len(h) >= 2 else DEFAULT_HEIGHT_SPREAD_M


def dem_sigma(height_of, ground: dict) -> float:
    """σ of the reference DEM's heights, measured on the project: the RMS of DEM − known height
    over the points with ground coordinates (at least 3 inside the DEM), else
    :data:`DEFAULT_DEM_SIGMA_M`. ``ground``: id → ``(E, N, h)``."""
    if height_of is None or len(ground) < 3:
        return DEFAULT_DEM_SIGMA_M
    g = np.array(list(ground.values()), float).reshape(-1, 3)
    d = np.asarray(height_of(g[:, :2]), float) - g[:, 2]
    d = d[np.isfinite(d)]
    return float(np.sqrt(np.mean(d ** 2))) if len(d) >= 3 else DEFAULT_DEM_SIGMA_M


# ---------------------------------------------------------------------- model derivatives
def bias_cov(sol: Solution, view: str, xy) -> np.ndarray:
    """``(..., 2, 2)`` px²: what the bias fit's parameter covariance adds at image ``xy``
    (the sensor model's :meth:`~prismstation.core.models.sensor.SensorModel.bias_cov`)."""
    return sol.model.bias_cov(view, xy)


def ground_jacobian(sol: Solution, view: str, g) -> tuple[np.ndarray, np.ndarray]:
    """``(xy, J)``: image position of ground ``g = (E, N, h)`` in ``view`` and ``J`` ``(2, 3)``,
    its derivative in pixels per metre (the sensor model's
    :meth:`~prismstation.core.models.sensor.SensorModel.partials`)."""
    g = np.asarray(g, float)
    xy, J = sol.model.partials(view, g[None, :2], g[None, 2])
    return xy[0], J[0]


def measurement_sigma(sol: Solution, view: str, sigma_px) -> float:
    """σ (px) of one measurement: its own σ (or the settings' a-priori σ) times the
    a-posteriori σ0 of that view's bias fit, when the fit has redundancy."""
    s = sol.settings.sigma_px if sigma_px is None else float(sigma_px)
    s0 = sol.bias[view].sigma0
    return s * s0 if s0 is not None and math.isfinite(s0) and s0 > 0 else s


# ---------------------------------------------------------------------- the ground estimate
def ground_estimate(sol: Solution, point: PointInput, *, height_of=None, sigma_dem: float,
                    sigma_mean: float) -> tuple[np.ndarray, np.ndarray, str] | None:
    """``(g, C, source)``: ground ``(E, N, h)`` of ``point`` and its covariance ``(3, 3)``
    (metres²), or None when nothing places it (see the module doc for the sources)."""
    if point.ground is not None and all(map(math.isfinite, point.ground)):
        sxy, sh = point.sigma_ground
        return np.array(point.ground, float), np.diag([sxy ** 2, sxy ** 2, sh ** 2]), "ground"
    obs = {v: m for v, m in point.measured.items() if v in sol.scene.views}
    if not obs:
        return None
    # observations: each measured view (σ² I + its bias covariance), and a height prior
    first = next(iter(obs))
    h0, sigma_h, source = float(sol.mean_height), sigma_mean, "mean"
    xy_first = np.array(obs[first][:2], float)
    if height_of is not None:       # the ray meets the DEM (else the mean height)
        hit = ray_meets_surface(lambda h: sol.image_to_ground(first, xy_first, h[0])[None],
                                lambda en: np.asarray(height_of(en), float), h0)
        if hit:
            h0, sigma_h, source = float(hit.h[0]), sigma_dem, "reference"
    if len(obs) >= 2:  # the DEM, when there, still weighs in (coarse pixels: it may be better)
        source = "intersection"
    g = np.array([*sol.image_to_ground(first, xy_first, h0), h0], float)
    for _ in range(6):  # Gauss–Newton on (E, N, h)
        rows, res, W = [], [], []
        for v, (x, y, s) in obs.items():
            xy, J = ground_jacobian(sol, v, g)
            R = measurement_sigma(sol, v, s) ** 2 * np.eye(2) + bias_cov(sol, v, xy)
            rows.append(J)
            res.append(np.array([x, y]) - xy)
            W.append(np.linalg.inv(R))
        rows.append(np.array([[0.0, 0.0, 1.0]]))
        res.append(np.array([h0 - g[2]]))
        W.append(np.array([[1.0 / sigma_h ** 2]]))
        A = np.vstack(rows)
        Wb = _block_diag(W)
        N = A.T @ Wb @ A
        C = np.linalg.inv(N)
        dg = C @ A.T @ Wb @ np.concatenate(res)
        g = g + dg
        if np.all(np.abs(dg) < 1e-4):
            break
    return g, C, source


def _block_diag(blocks) -> np.ndarray:
    n = sum(b.shape[0] for b in blocks)
    out = np.zeros((n, n))
    i = 0
    for b in blocks:
        k = b.shape[0]
        out[i:i + k, i:i + k] = b
        i += k
    return out


def predict_point(sol: Solution, point: PointInput, views=None, *, height_of=None,
                  sigma_dem: float = DEFAULT_DEM_SIGMA_M,
                  sigma_mean: float = DEFAULT_HEIGHT_SPREAD_M) -> dict[str, Prediction]:
    """Predictions of ``point`` in ``views`` (default: every view it is not measured in)."""
    views = [v for v in sol.scene.views if v not in point.measured] if views is None else views
    if not views:
        return {}
    est = ground_estimate(sol, point, height_of=height_of, sigma_dem=sigma_dem, sigma_mean=sigma_mean)
    if est is None:
        return {}
    g, C, source = est
    out = {}
    for v in views:
        xy, J = ground_jacobian(sol, v, g)
        if not np.all(np.isfinite(xy)):
            continue
        cov = J @ C @ J.T + bias_cov(sol, v, xy)
        out[v] = Prediction(v, (float(xy[0]), float(xy[1])), cov, source, float(g[2]),
                            float(math.sqrt(max(C[2, 2], 0.0))))
    return out


def _known_ground_predictions(sol: Solution, points) -> dict:
    """:func:`predict_point` for points placed by their known ground, vectorised over points
    (a project may hold hundreds of GCPs and ICPs not yet measured)."""
    if not points:
        return {}
    g = np.array([p.ground for p in points], float)
    C = np.zeros((len(points), 3, 3))
    sig = np.array([p.sigma_ground for p in points], float)
    C[:, 0, 0] = C[:, 1, 1] = sig[:, 0] ** 2
    C[:, 2, 2] = sig[:, 1] ** 2
    out: dict = {}
    for v in sol.scene.views:
        want = np.array([v not in p.measured for p in points])
        if not want.any():
            continue
        gv, Cv = g[want], C[want]
        xy = sol.ground_to_image(v, gv[:, :2], gv[:, 2])
        J = np.empty((len(gv), 2, 3))
        for k in range(3):  # (central differences point by point, as partials: the same numbers)
            step = np.zeros(3)
            step[k] = STEP_M
            hi, lo = gv + step, gv - step
            J[:, :, k] = (sol.ground_to_image(v, hi[:, :2], hi[:, 2]) -
                          sol.ground_to_image(v, lo[:, :2], lo[:, 2])) / (2 * STEP_M)
        cov = J @ Cv @ J.transpose(0, 2, 1)
        fit = sol.bias[v]
        if fit.cov is not None and fit.cov.size:
            cov = cov + bias_cov(sol, v, xy)
        ok = np.isfinite(xy).all(axis=1)
        for i, p in enumerate(q for q, w in zip(points, want) if w):
            if ok[i]:
                out.setdefault(p.id, {})[v] = Prediction(
                    v, (float(xy[i, 0]), float(xy[i, 1])), cov[i], "ground", float(gv[i, 2]),
                    float(math.sqrt(Cv[i, 2, 2])))
    return out


def predict_all(sol: Solution, points, *, height_of=None, ground: dict | None = None) -> dict:
    """``{id: {view: Prediction}}`` for every point of ``points`` (:class:`PointInput`) in the
    views it is not measured in. ``ground``: id → ``(E, N, h)`` of the points with known ground
    (for the σ of the DEM and of the mean height)."""
    ground = ground or {}
    names = set(sol.scene.views)
    todo = [p for p in points if not names <= set(p.measured)]
    known = [p for p in todo if p.ground is not None and all(map(math.isfinite, p.ground))]
    out = _known_ground_predictions(sol, known)
    rest = [p for p in todo if p.measured and not (p.ground is not None and all(map(math.isfinite, p.ground)))]
    if not rest:
        return out
    s_dem = dem_sigma(height_of, ground)
    s_mean = height_spread(g[2] for g in ground.values())
    for p in rest:
        try:
            pr = predict_point(sol, p, height_of=height_of, sigma_dem=s_dem, sigma_mean=s_mean)
        except (np.linalg.LinAlgError, ValueError):
            continue
        if pr:
            out[p.id] = pr
    return out


def project_inputs(project, ground: dict) -> list[PointInput]:
    """The project's points with a view to predict in, as :class:`PointInput` (``ground``: id →
    ``(E, N, h ellipsoidal)`` of the GCPs and ICPs, e.g. :func:`known_ground`)."""
    n_views = len(project.scene.views)
    out = []
    for pid, p in project.points.items():
        ms = project.measurements_of(pid)
        if len(ms) >= n_views:
            continue  # measured everywhere: nothing to predict
        seen = {m.view: (m.x, m.y, m.sigma_px) for m in ms}
        g = ground.get(pid) if p.kind != "TIE" else None
        out.append(PointInput(pid, p.kind, seen, g, (p.sigma_xy_m or 0.0, p.sigma_h_m or 0.0)))
    return out


def known_ground(project) -> dict:
    """id → ``(E, N, h ellipsoidal)`` of the project's points with ground coordinates."""
    h = ellipsoidal_heights(project)
    return {pid: (project.points[pid].E, project.points[pid].N, hv) for pid, hv in h.items()}
