"""A fit's every output against a slow, straightforward recomputation, point by point.

The fit is vectorised over points and its per-point results are assembled from plain lists for
speed; this recomputes each point on its own with the model's formulas (docs/model.md §2) and
the bias fit with a plain weighted least squares in pixel coordinates, on a set that holds
every case the assembly distinguishes: GCPs, ICPs, tie points, points measured in one or two
views only, a point measured nowhere, a blunder, per-view σ.
"""
import math

import numpy as np
import pytest

from prismstation.core.models import prism
from prismstation.core.models.results import PointColumns
from prismstation.core.models.solution import PointObs, Settings, normal_equivalent, solve, statistics

from prismstation.sim.model_triplet import make_points, make_scene

TOL_PX = 1e-7   # pixels: the point-by-point and vectorised paths round differently
TOL_M = 1e-6    # metres (the inverse relief iteration stops at 1e-9 m per step)


def _project():
    sc = make_scene(192.0, path_oriented=False)   # flight oblique to the image axes
    pts = make_points(sc, n_gcp=12, n_icp=30, noise_px=0.3, seed=5)
    bad = pts[4]                                  # a blunder of 6 px in N
    img = dict(bad.image); img["N"] = (img["N"][0] + 6.0, img["N"][1])
    pts[4] = PointObs(bad.id, bad.kind, bad.ground, img, {"N": 0.8, "F": 1.5})
    pts += [PointObs("T1", "TIE", None, pts[20].image),                          # tie, N F B
            PointObs("T2", "TIE", None, {"N": pts[21].image["N"]}),              # tie, N only
            PointObs("T3", "TIE", None, {v: pts[22].image[v] for v in "FB"}),    # tie, F B
            PointObs("T4", "TIE", None, {"B": pts[23].image["B"]}),              # tie, B only
            PointObs("I90", "ICP", pts[24].ground, {}),                          # measured nowhere
            PointObs("I91", "ICP", pts[25].ground, {"F": pts[25].image["F"]}),   # ICP, F only
            PointObs("G90", "GCP", pts[26].ground, {v: pts[26].image[v] for v in "NF"})]
    return sc, pts


def _bias_by_plain_lsq(xy0, xy, sigma):
    """Affine bias ``x = x0 + M·x0 + b`` by weighted least squares in pixels: published
    parameters (B1..B6) and their a-posteriori covariance."""
    n = len(xy0)
    A = np.zeros((2 * n, 6))
    A[0::2, 0], A[0::2, 1], A[0::2, 4] = xy0[:, 0], xy0[:, 1], 1
    A[1::2, 2], A[1::2, 3], A[1::2, 5] = xy0[:, 0], xy0[:, 1], 1
    w = 1 / np.repeat(sigma, 2) ** 2
    N = A.T @ (A * w[:, None])
    p = np.linalg.solve(N, A.T @ (w * (xy - xy0).ravel()))
    v = (xy - xy0).ravel() - A @ p
    s0 = float(v @ (w * v)) / (2 * n - 6)
    return p, s0 * np.linalg.inv(N)


def _expected_point(sc, sol, p):
    """One point's results computed on their own (no vectorisation over points)."""
    views, bias, par = sc.views, sol.bias, sol.model.parallax
    measured = {v: tuple(map(float, p.image[v])) for v in views if v in p.image}
    py = mid = None
    if "F" in measured and "B" in measured:
        py, mid = prism.fb_parallax(sc, [measured["F"]], [measured["B"]])
        py, mid = float(py[0]), mid[0]
    source = "parallax" if py is not None and par is not None else "mean"
    h = float(par.height(py, mid)) if source == "parallax" else sol.mean_height
    used = ["N"] if "N" in measured else list(measured)
    en = (np.mean([prism.ancillary_to_ground(sc, views[v], bias[v].invert(np.array(measured[v])), h)
                   for v in used], axis=0) if used else None)
    ground = np.array(p.ground) if p.ground is not None else None
    at = ground if ground is not None else (None if en is None else np.array([*en, h]))
    predicted = ({v: bias[v].apply(prism.ground_to_ancillary(sc, views[v], at[:2], at[2])) for v in views}
                 if at is not None else {})
    residual = ({v: np.subtract(measured[v], predicted[v]) for v in measured}
                if ground is not None else {})
    across = {}
    if "N" in measured:
        xn = np.array(measured["N"])
        t = prism.along_track_unit(sc, prism.image_to_map(views["N"])(xn))
        for v in ("F", "B"):
            if v in measured:
                d = prism.to_nadir_space(sc, views[v])(np.array(measured[v])) - xn
                across[v] = float(d @ np.array([t[1], -t[0]]))
    est = None if en is None else (*en, h)
    return dict(measured=measured, predicted=predicted, residual_px=residual, parallax_px=py,
                across_px=across, ground_est=est, height_source=source if est else None,
                ground_residual=(np.subtract(est, ground) if est and ground is not None else None),
                note=("not measured in any view" if not measured else
                      "height not from parallax: measure the point in F and B"
                      if source != "parallax" else ""))


def _close(got, want, tol):
    if want is None:
        return got is None
    if isinstance(want, dict):
        return got.keys() == want.keys() and all(_close(got[k], want[k], tol) for k in want)
    return np.allclose(got, want, rtol=0, atol=tol)


def test_every_point_result_matches_a_point_by_point_recomputation():
    sc, pts = _project()
    sol = solve(sc, pts, Settings("affine", "line"))
    assert [r.id for r in sol.points] == [p.id for p in pts]
    for p, r in zip(pts, sol.points):
        want = _expected_point(sc, sol, p)
        assert r.kind == p.kind and r.note == want["note"], p.id
        assert r.height_source == want["height_source"], p.id
        for key in ("measured", "predicted", "residual_px", "parallax_px", "across_px"):
            assert _close(getattr(r, key), want[key], TOL_PX), (p.id, key)
        for key in ("ground_est", "ground_residual"):
            assert _close(getattr(r, key), want[key], TOL_M), (p.id, key)
        for d in (r.measured, r.predicted, r.residual_px):
            assert all(type(c) is float for xy in d.values() for c in xy), p.id
    # the cases the set was made for did occur
    by_id = {r.id: r for r in sol.points}
    assert by_id["I90"].ground_est is None and by_id["I91"].height_source == "mean"
    assert by_id["T3"].across_px == {} and set(by_id["T1"].across_px) == {"F", "B"}


def test_bias_parallax_and_adjustment_match_plain_least_squares():
    sc, pts = _project()
    sol = solve(sc, pts, Settings("affine", "line"))
    gcps = [p for p in pts if p.kind == "GCP" and "N" in p.image]
    xy0 = prism.ground_to_ancillary(sc, sc.views["N"], [p.ground[:2] for p in gcps],
                                    [p.ground[2] for p in gcps])
    xy = np.array([p.image["N"] for p in gcps])
    sig = np.array([p.sigma_px.get("N", 1.0) for p in gcps])
    params, cov = _bias_by_plain_lsq(xy0, xy, sig)
    fit = sol.bias["N"]
    assert fit.params == pytest.approx(params, rel=1e-8, abs=1e-12)
    scale = np.sqrt(np.outer(np.diag(cov), np.diag(cov)))   # compared as correlations
    assert np.all(np.abs(fit.cov - cov) <= 1e-8 * scale)
    assert fit.std == pytest.approx(np.sqrt(np.diag(cov)), rel=1e-7)
    # parallax line: h = c0 + c1·py over the GCPs seen in F and B
    fb = [p for p in pts if p.kind == "GCP" and "F" in p.image and "B" in p.image]
    py = prism.fb_parallax(sc, [p.image["F"] for p in fb], [p.image["B"] for p in fb])[0]
    c1, c0 = np.polyfit(py, [p.ground[2] for p in fb], 1)
    assert (sol.model.parallax.c0, sol.model.parallax.c1) == pytest.approx((c0, c1), rel=1e-9)
    # each GCP's largest standardised residual over its N x, N y and parallax observations
    std = {}
    for fit_, ids, per in ((fit.lsq, [p.id for p in gcps], 2), (sol.model.parallax.lsq, [p.id for p in fb], 1)):
        w = normal_equivalent(fit_.std_residuals, fit_.dof)
        for i, pid in enumerate(ids):
            std.setdefault(pid, []).extend(w[per * i:per * i + per])
    for r in sol.points:
        if r.kind != "GCP" or r.id not in std:
            assert r.std_residual is None and not r.blunder, r.id
            continue
        assert r.std_residual == pytest.approx(np.nanmax(std[r.id]), rel=1e-12), r.id
        assert r.blunder == (r.std_residual > 3.29), r.id
    assert [r.id for r in sol.points if r.blunder] == [pts[4].id]


def _plain_stats(values):
    v = np.array([x for x in values if math.isfinite(x)], float)
    if v.size == 0:
        return (0,) + (math.nan,) * 5
    return (v.size, v.min(), v.max(), v.mean(), math.sqrt(np.mean(v * v)),
            v.std(ddof=1) if v.size > 1 else math.nan)


def _as_tuple(c):
    return (c.n, c.min, c.max, c.mean, c.rms, c.std)


def test_statistics_match_numpy_over_the_point_results():
    sc, pts = _project()
    sol = solve(sc, pts, Settings("affine", "line"))
    st, res = sol.stats, sol.points
    other = PointColumns.of(res, sc.views)          # the results as the other models give them
    assert repr(statistics(sc, other)) == repr(st)  # from those = from the fit's own arrays
    assert set(st.image["N"]) == {"GCP", "ICP"}    # a tie point has no image residual here
    for v, view in sc.views.items():
        for kind in ("GCP", "ICP"):
            rows = [r.residual_px[v] for r in res if r.kind == kind and v in r.residual_px]
            for k, comp in enumerate(("x", "y")):
                want = _plain_stats([xy[k] for xy in rows])
                np.testing.assert_allclose(_as_tuple(getattr(st.image[v][kind].px, comp)), want, rtol=1e-12)
                np.testing.assert_allclose(_as_tuple(getattr(st.image[v][kind].m, comp)),
                                           np.array(want) * (1, *(view.pixel_size_m,) * 5), rtol=1e-12)
    for kind in ("GCP", "ICP"):
        g = [r.ground_residual for r in res if r.kind == kind and r.ground_residual is not None]
        for k, comp in enumerate(("x", "y")):
            np.testing.assert_allclose(_as_tuple(getattr(st.ground[kind], comp)),
                                       _plain_stats([d[k] for d in g]), rtol=1e-12)
        hs = [r.ground_residual[2] for r in res
              if r.kind == kind and r.ground_residual is not None and r.height_source == "parallax"]
        np.testing.assert_allclose(_as_tuple(st.height[kind]), _plain_stats(hs), rtol=1e-12)
    for v in ("F", "B"):
        np.testing.assert_allclose(_as_tuple(st.across[v]),
                                   _plain_stats([r.across_px[v] for r in res if v in r.across_px]), rtol=1e-12)
