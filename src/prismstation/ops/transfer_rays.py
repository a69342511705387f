"""The model's σ at a transferred point and the rays' test (:mod:`prismstation.ops.transfer`):
how far each view's fitted model may misplace a point (:func:`model_sigma_m` for the searches,
:func:`view_sigma_px` for a band guided by another view, :func:`view_cov_px` for the test), the
least-squares intersection of a point's rays (:func:`intersect`) and the test that they meet
(:func:`consistency`). Image pixels ``(x, y)`` = (column, row); ground ``(E, N, h)`` in map
metres and ellipsoidal metres (docs/model.md §1).
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy import special

from prismstation.core.models.solution import Solution
from prismstation.ops.coarse_offsets import SIGMA_APRIORI_M
from prismstation.ops.predict import bias_cov, ground_jacobian

#: σ (m, per component) of a view's geolocation once its bias is fitted: the check-point
#: accuracy of the empirical model without and with GCPs (Gonçalves 2008: under 5 m)
FITTED_SIGMA_M = 5.0
MODEL_SIGMA_PX = 0.5
"""σ (px) of a view's model where its bias fit gives none (the views' relative orientation
enters the rays' consistency test)."""
CONSISTENCY_P = 0.999
"""The rays of a transfer (two or three) are rejected beyond this χ² quantile."""


def model_sigma_m(sol: Solution) -> float:
    """σ (m) per view and component the searches assume for ``sol``: the ancillary model's
    a-priori σ until every view's bias is fitted (by GCPs or a reference DEM), then
    :data:`FITTED_SIGMA_M`."""
    fitted = all(sol.model.fitted(v) for v in sol.scene.views)
    return FITTED_SIGMA_M if fitted else SIGMA_APRIORI_M


def view_sigma_px(sol: Solution, view: str) -> float:
    """σ (px) of ``view``'s model where a search is guided by another view's match (its band's
    height σ, :func:`_confirm`): the a-priori geolocation σ (:func:`model_sigma_m`) while its
    bias is not fitted, else the a-posteriori σ of a measurement in its bias fit (a wide band:
    it includes the GCPs' own error), :data:`MODEL_SIGMA_PX` where the fit gives none."""
    if not sol.model.fitted(view):
        return model_sigma_m(sol) / sol.scene.views[view].pixel_size_m
    s0 = sol.bias[view].sigma0
    return float(s0 * sol.settings.sigma_px) if s0 is not None and math.isfinite(s0) and s0 > 0 else MODEL_SIGMA_PX


def view_cov_px(sol: Solution, view: str, xy) -> np.ndarray:
    """``(2, 2)`` px²: the covariance of ``view``'s model at image ``xy`` in the rays' test — what
    the error of its bias fit's parameters gives there (:func:`~prismstation.ops.predict.bias_cov`)
    plus the misfit its residuals show beyond the GCP measurements' a-priori σ (``(σ0² − 1)·σ²``
    where σ0 > 1): not the σ of a GCP measurement, whose own error a tie point does not carry.
    While the bias is not fitted, or where its fit states no covariance (a reference-DEM
    orientation), :func:`view_sigma_px` in both directions."""
    cov = np.asarray(bias_cov(sol, view, np.asarray(xy, float)), float) if sol.model.fitted(view) else None
    s0 = sol.bias[view].sigma0
    if cov is None or not np.all(np.isfinite(cov)) or s0 is None or not (math.isfinite(s0) and s0 > 0):
        return view_sigma_px(sol, view) ** 2 * np.eye(2)
    return cov + max(s0 * s0 - 1.0, 0.0) * sol.settings.sigma_px ** 2 * np.eye(2)


def intersect(sol: Solution, obs: dict, h0: float, en0=None) -> tuple[np.ndarray, dict, float, int]:
    """Least-squares ground point of image observations ``{view: ((x, y), cov 2×2 px²)}``
    through the model (Gauss–Newton on ``(E, N, h)`` from height ``h0``, the Jacobian of the
    start kept; ``en0``: the first view's point at ``h0`` on the ground, when known).

    Returns ``(g, residuals {view: (2,) px, observed − predicted}, χ², redundancy, covariance
    of g (3×3, m²))``."""
    first = next(iter(obs))
    en0 = sol.image_to_ground(first, np.asarray(obs[first][0], float), h0) if en0 is None else en0
    g = np.array([*en0, h0], float)
    W = {v: np.linalg.inv(c) for v, (_, c) in obs.items()}
    start = {v: ground_jacobian(sol, v, g) for v in obs}   # the model is near linear over metres:
    J = {v: j for v, (_, j) in start.items()}              # its Jacobian at the start serves
    N = sum(J[v].T @ W[v] @ J[v] for v in obs)
    pred = {v: q for v, (q, _) in start.items()}
    for _ in range(8):
        res = {v: np.asarray(xy, float) - pred[v] for v, (xy, _) in obs.items()}
        dg = np.linalg.solve(N, sum(J[v].T @ W[v] @ res[v] for v in obs))
        g = g + dg
        pred = {v: sol.ground_to_image(v, g[:2], g[2]) for v in obs}
        if np.all(np.abs(dg) < 1e-3):
            break
    res = {v: np.asarray(xy, float) - pred[v] for v, (xy, _) in obs.items()}
    chi2 = float(sum(res[v] @ W[v] @ res[v] for v in obs))
    return g, res, chi2, 2 * len(obs) - 3, np.linalg.inv(N)


def consistency(sol: Solution, source: str, xy, found: dict, h0: float | None = None,
                en0=None) -> dict:
    """The rays' test: the source point and its matches in the other views intersected
    (:func:`intersect` from height ``h0``, default the mean height; each view weighted by its
    match covariance plus its model's, :func:`view_cov_px`; ``en0``: the source point's ground
    at ``h0``, when known); a χ² beyond :data:`CONSISTENCY_P` marks every match ``inconsistent``
    with the residuals in its reason. With one match the two rays meet at any height: what they
    test is the match's place across its parallax (the epipolar line), which the model fixes
    to its σ; with two, the heights the matches imply as well."""
    ok = {v: t for v, t in found.items() if t.ok}
    obs = {source: (np.asarray(xy, float), view_cov_px(sol, source, xy))}
    for v, t in ok.items():
        obs[v] = ((t.x, t.y), t.match.cov + view_cov_px(sol, v, (t.x, t.y)))
    try:
        _, res, chi2, dof, _ = intersect(sol, obs, sol.mean_height if h0 is None else h0,
                                         en0=None if h0 is None else en0)
    except np.linalg.LinAlgError:
        return found
    limit = float(special.chdtri(dof, 1.0 - CONSISTENCY_P))      # the χ² quantile, as scipy.stats gives it
    if chi2 <= limit:
        return found
    words = ", ".join(f"{v} {np.hypot(*r):.2f} px" for v, r in res.items())
    out = dict(found)
    for v, t in ok.items():
        m = replace(t.match, status="inconsistent",
                    reason=f"the rays do not meet (χ² {chi2:.1f} > {limit:.1f}; residuals {words})")
        out[v] = replace(t, match=m)
    return out
