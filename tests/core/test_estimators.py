"""Every fitted transform of core through the one estimator protocol (core/adjustment/estimate.py):
fit on noisy synthetic pairs, forward∘inverse, residuals, σ0 and the parameter covariance
against the scatter of the parameters over 200 noise draws; then the degenerate geometries."""
from dataclasses import dataclass
from typing import Callable

import numpy as np
import pytest

from prismstation.core.models import prism
from prismstation.core.adjustment.affine import Affine2D
from prismstation.core.adjustment.estimate import MAX_CONDITION, SINGULAR, Estimator, FailedFit
from prismstation.core.models.prism import BiasFit
from prismstation.core.models.rectify import FittedTransform, compare_transforms, fit_transform
from prismstation.core.models.resection import FrameCamera, resect
from prismstation.core.orientation.shift_field import ShiftField
from prismstation.core.models.solution import PointObs, Settings, solve
from prismstation.errors import DegenerateGeometry, ModelError

from prismstation.sim.model_triplet import make_scene

DRAWS = 200
E0, N0 = 512000.0, 4601000.0


@dataclass(frozen=True)
class Case:
    """An estimator, how to fit it, an exact map from src to dst and the noise on dst."""

    name: str
    fit: Callable                 # (src, dst, sigma or None) -> estimator or FailedFit
    truth: Callable               # src (n, 2) -> dst (n, k)
    noise: float                  # σ of each dst coordinate
    pass_sigma: bool              # σ given to the fit: σ0 is then unitless (≈ 1)
    extent: float = 10000.0       # src points uniform in [0, extent]²
    n: int = 25


def _poly(degree):
    exps = [(d - j, j) for d in range(degree + 1) for j in range(d + 1)]
    rng = np.random.default_rng(degree)
    A = rng.normal(0, 1, (2, len(exps))) * np.array([1000.0 ** -(i + j - 1) for i, j in exps]) * 2e-3
    A[0, 1], A[1, 2] = 2.5, -2.5
    A[:, 0] = E0, N0
    return lambda s: np.stack([s[:, 0] ** i * s[:, 1] ** j for i, j in exps], axis=1) @ A.T


def _homography(s):
    H = np.array([[2.4, 0.3, E0], [0.2, -2.6, N0], [2e-6, -1e-6, 1.0]])
    h = np.column_stack([s, np.ones(len(s))]) @ H.T
    return h[:, :2] / h[:, 2:]


AFFINE = Affine2D([[2.5, 0.1, E0], [0.05, -2.45, N0]])
BIAS = np.array([[7.3e-5, 4.8e-5], [-5.51e-4, 5.2e-5]]), np.array([-7.4, -27.7])
SIMILAR = np.array([[2e-4, -3e-4], [3e-4, 2e-4]])
FIELD = np.array([[12.0, 1e-3, -2e-3], [-40.0, 5e-4, 1e-3]])


def _bias(M, b):
    return lambda s: s + s @ M.T + b


CASES = [
    Case("Affine2D", Affine2D.fit, AFFINE, 1.0, True),
    Case("BiasFit shift", lambda s, d, g: BiasFit.fit(s, d, "shift", g),
         _bias(np.zeros((2, 2)), BIAS[1]), 0.5, True, 14000, 9),
    Case("BiasFit similarity", lambda s, d, g: BiasFit.fit(s, d, "similarity", g),
         _bias(SIMILAR, BIAS[1]), 0.5, True, 14000, 9),
    Case("BiasFit affine", lambda s, d, g: BiasFit.fit(s, d, "affine", g), _bias(*BIAS), 0.5, True, 14000, 9),
    *[Case(f"FittedTransform {k}", lambda s, d, g, k=k: FittedTransform.fit(s, d, k), t, 1.5, False)
      for k, t in (("affine", AFFINE), ("poly1", AFFINE), ("projective", _homography),
                   ("poly2", _poly(2)), ("poly3", _poly(3)))],
    Case("ShiftField", lambda s, d, g: ShiftField.fit(s, d, None if g is None else np.full(d.shape, g)),
         lambda s: FIELD[:, 0] + s @ FIELD[:, 1:].T, 0.5, True, 8000, 30),
]


def _scatter_disagrees(P, C, p_exact) -> list[str]:
    """Which claims of the formal covariance ``C`` the draws ``P`` (draws, u) contradict
    (at 3 standard errors; seeds are fixed, so the outcome is deterministic)."""
    draws, u = P.shape
    std = np.sqrt(np.diag(C))
    bad = []
    # unbiased: the mean of the draws is the exact fit
    if np.any(np.abs(P.mean(axis=0) - p_exact) > 4 * std / np.sqrt(draws) + 1e-12 * np.abs(p_exact)):
        bad.append("mean")
    # each σ matches the scatter (sd of a sample sd over 200 draws ≈ 5 %)
    ratio = P.std(axis=0, ddof=1) / std
    if np.any((ratio < 0.85) | (ratio > 1.15)):
        bad.append("std")
    # and the correlations: the mean Mahalanobis distance² of the draws is u (χ²)
    z = (P - p_exact) / std
    m = np.einsum("ij,ij->i", z, np.linalg.solve(C / np.outer(std, std), z.T).T)
    if abs(m.mean() / u - 1) > 3 * np.sqrt(2 / (u * draws)):
        bad.append("mahalanobis")
    return bad


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.name)
def test_estimator_protocol(case):
    rng = np.random.default_rng(7)
    src = rng.uniform(0, case.extent, (case.n, 2))
    exact = case.truth(src)
    sigma = case.noise if case.pass_sigma else None
    est = case.fit(src, exact + rng.normal(0, case.noise, exact.shape), sigma)
    assert est and isinstance(est, Estimator), est
    # forward ∘ inverse and inverse ∘ forward are the identity over the points' extent
    q = rng.uniform(0, case.extent, (50, 2))
    assert np.abs(est.inverse(est(q)) - q).max() < 1e-6 * case.extent
    fq = est(q)
    assert np.abs(est(est.inverse(fq)) - fq).max() < 1e-6 * (1 + np.abs(fq).max())
    # residuals: observed − computed, one row per point, and σ0² = Σ(v/σ)² / dof
    dst = exact + rng.normal(0, case.noise, exact.shape)
    est = case.fit(src, dst, sigma)
    v = est.residuals(src, dst)
    assert v.shape == dst.shape and np.allclose(v, dst - est(src))
    assert est.dof == dst.size - est.params.size
    w = v / (case.noise if case.pass_sigma else 1.0)
    s0 = np.atleast_1d(est.sigma0)
    per = (w ** 2).sum(axis=0) if s0.size > 1 else (w ** 2).sum()
    assert np.allclose(s0 ** 2 * (est.dof if s0.size == 1 else len(src) - 3), per, rtol=1e-6)
    assert est.cov.shape == (est.params.size,) * 2

    # a σ is a claim: 200 noise draws on the same points
    p_exact = case.fit(src, exact, sigma).params.ravel()
    params, covs, s02 = [], [], []
    for _ in range(DRAWS):
        e = case.fit(src, exact + rng.normal(0, case.noise, exact.shape), sigma)
        params.append(e.params.ravel())
        covs.append(e.cov)
        s02.append(np.atleast_1d(e.sigma0) ** 2)
    P, C = np.array(params), np.mean(covs, axis=0)
    assert _scatter_disagrees(P, C, p_exact) == []
    # the check has the power to see a σ 22 % too large or 23 % too small
    assert _scatter_disagrees(P, 1.5 * C, p_exact) and _scatter_disagrees(P, 0.6 * C, p_exact)
    # σ0² is an unbiased estimate of the noise variance (1 when the σ was given)
    expect = 1.0 if case.pass_sigma else case.noise ** 2
    dof_c = est.dof if np.ndim(est.sigma0) == 0 else len(src) - 3
    assert np.all(np.abs(np.mean(s02, axis=0) / expect - 1) < 4 * np.sqrt(2 / (dof_c * DRAWS)))


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.name)
def test_too_few_points_is_a_failure_value_not_an_exception(case):
    src = np.array([[10.0, 20.0]])
    res = case.fit(src, case.truth(src), case.noise if case.pass_sigma else None)
    if case.name == "BiasFit shift":   # one GCP is enough for a shift
        assert res
        return
    assert not res and isinstance(res, FailedFit) and res.degenerate
    assert "at least" in res.reason and str(res) == res.reason
    with pytest.raises(DegenerateGeometry):
        res.unwrap()


def _strip(n, offset, rng, length=30000.0):
    """``n`` points along a line ``length`` long (units of the caller: metres or pixels) at
    random distances up to ``offset`` from it; ``offset = length`` gives a spread set."""
    d, perp = np.array([0.8, 0.6]), np.array([-0.6, 0.8])
    t = np.linspace(0, length, n)
    o = rng.uniform(-offset, offset, n) if offset < length else rng.uniform(0, length, n)
    return np.array([1000.0, 2000.0]) + np.outer(t, d) + np.outer(o, perp)


# estimators that need points spread in two directions
SPREAD = [c for c in CASES if c.name not in ("BiasFit shift", "BiasFit similarity")]


@pytest.mark.parametrize("case", SPREAD, ids=lambda c: c.name)
@pytest.mark.parametrize("offset, verdict", [(0.0, "collinear"), (1.0, "nearly"), (30000.0, "ok")])
def test_collinear_nearly_collinear_and_spread(case, offset, verdict):
    """1 m off a line across 30 km (κ ≈ 2·10⁴) is degenerate, and says so with κ."""
    src = _strip(12, offset, np.random.default_rng(5))
    res = case.fit(src, case.truth(src), case.noise if case.pass_sigma else None)
    if verdict == "ok":
        assert res, res
        return
    assert not res and res.degenerate and res.condition > MAX_CONDITION
    assert "condition number" in res.reason
    if verdict == "collinear":
        assert res.condition >= SINGULAR
    else:
        assert res.condition < SINGULAR and "nearly on one line" in res.reason


def test_shift_and_similarity_fit_collinear_points_but_not_coincident_ones():
    line = _strip(6, 0.0, np.random.default_rng(1))
    for model in ("shift", "similarity"):
        assert BiasFit.fit(line, _bias(SIMILAR, BIAS[1])(line), model)
    same = np.repeat([[500.0, 700.0]], 4, axis=0)
    assert BiasFit.fit(same, same + 3, "shift")
    res = BiasFit.fit(same, same + 3, "similarity")
    assert not res and res.degenerate and "coincide" in res.reason
    with pytest.raises(DegenerateGeometry, match="coincide"):
        prism.fit_bias(same, same, "affine")


def test_threshold_sits_between_a_thin_strip_and_a_near_line():
    """A GCP strip a tenth of its length wide still fits (κ ≈ 10); 10 m across 30 km does not."""
    rng = np.random.default_rng(2)
    wide, thin = _strip(10, 1500.0, rng), _strip(10, 5.0, rng)
    assert fit_transform("affine", wide, AFFINE(wide))
    with pytest.raises(DegenerateGeometry, match="nearly on one line"):
        fit_transform("affine", thin, AFFINE(thin))


def test_solve_reports_nearly_collinear_gcps_with_the_condition_number():
    """The model's own fit: GCPs 1 m off a line across 30 km fitted silently before."""
    sc = make_scene()
    rng = np.random.default_rng(4)
    en = _strip(8, 1.0, rng) + np.array([540000.0 - 13000, 4560000.0 - 10000])
    pts = []
    for i, e in enumerate(en):
        img = {v: tuple(prism.ground_to_ancillary(sc, view, e, 500.0) + BIAS[1] + rng.normal(0, 0.5, 2))
               for v, view in sc.views.items()}
        pts.append(PointObs(f"G{i}", "GCP", (e[0], e[1], 500.0), img))
    sol = solve(sc, pts, Settings("affine"))
    assert not sol.ok
    msg = " ".join(sol.messages)
    assert "nearly on one line" in msg and "condition number" in msg
    fail = sol.failures["N"]
    assert fail.degenerate and MAX_CONDITION < fail.condition < SINGULAR
    assert solve(sc, pts, Settings("similarity")).ok     # similarity needs no 2-D spread


def test_compare_transforms_and_resection_name_the_degenerate_geometry():
    rng = np.random.default_rng(3)
    src = _strip(12, 1.0, rng)
    reports = compare_transforms(src, AFFINE(src))
    assert all(not r.ok and "nearly on one line" in r.error for r in reports)
    xyz = np.column_stack([src, np.full(len(src), 100.0)])
    with pytest.raises(DegenerateGeometry, match="condition number"):
        resect(FrameCamera(0.153, 1e-5, 0, 0), src, xyz)


def test_failures_are_model_errors_and_legacy_names_still_work():
    assert issubclass(DegenerateGeometry, ModelError) and issubclass(DegenerateGeometry, ValueError)
    res = FittedTransform.fit([[0, 0], [1, 1]], [[0, 0], [1, 1]], "spline")
    assert not res and not res.degenerate and "unknown" in res.reason
    a = AFFINE
    assert isinstance(a.inverse(), Affine2D)                 # without points: the inverse affine
    q = np.array([[3.0, 4.0]])
    assert np.allclose(a.inverse()(a(q)), q) and np.allclose(a.inverse(a(q)), q)
    tri = q.repeat(3, 0) + [[0, 0], [100, 0], [0, 100]]
    fit = BiasFit.fit(tri, tri + 3, "affine")
    assert np.allclose(fit.apply(q), fit(q)) and np.allclose(fit.invert(q), fit.inverse(q))
