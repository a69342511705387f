"""Predictions and their ellipses: formal covariance against the empirical scatter of
predictions over repeated noisy measurements (Monte Carlo on the model's own geometry)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from prismstation.core.models.solution import PointObs, solve
from prismstation.ops.predict import (CHI2_95_2D, DEFAULT_DEM_SIGMA_M, PointInput, dem_sigma,
                                      height_spread, predict_point)
from prismstation.sim.model_triplet import make_points, make_scene

NOISE_PX = 0.3


def _monte_carlo(case, runs=150, seed=0):
    """Errors (predicted − true, px) and formal covariances of one prediction case."""
    scene = make_scene()
    truth = make_points(scene, n_gcp=9, n_icp=4, noise_px=0.0, seed=1)
    gcps = [p for p in truth if p.kind == "GCP"]
    t = [p for p in truth if p.kind == "ICP"][0]
    rng = np.random.default_rng(seed)

    def noisy(xy):
        return tuple(np.add(xy, rng.normal(0, NOISE_PX, 2)))

    errs, covs, sources = [], [], set()
    for _ in range(runs):
        sol = solve(scene, [PointObs(p.id, p.kind, p.ground, {v: noisy(xy) for v, xy in p.image.items()})
                            for p in gcps])
        kw = {}
        if case == "NF":      # measured in N and F: intersection, predicted in B
            point, view = PointInput("t", "TIE", {v: (*noisy(t.image[v]), None) for v in "NF"}), "B"
        elif case == "dem":   # measured in N, a DEM with 10 m errors: predicted in F
            point, view = PointInput("t", "TIE", {"N": (*noisy(t.image["N"]), None)}), "F"
            h = t.ground[2] + rng.normal(0, 10.0)
            kw = dict(height_of=lambda en: np.full(len(en), h), sigma_dem=10.0)
        else:                 # an ICP by its known ground, not measured
            point, view = PointInput("t", "ICP", {}, t.ground), "F"
        pr = predict_point(sol, point, **kw)[view]
        sources.add(pr.source)
        errs.append(np.subtract(pr.xy, t.image[view]))
        covs.append(pr.cov)
    return np.array(errs), np.array(covs), sources


@pytest.mark.parametrize("case,source", [("NF", "intersection"), ("dem", "reference"), ("icp", "ground")])
def test_ellipse_matches_the_scatter_of_predictions(case, source):
    e, C, sources = _monte_carlo(case)
    assert sources == {source}
    empirical = np.sqrt(np.mean(e ** 2, axis=0))          # per axis, about the truth
    formal = np.sqrt(np.mean(C[:, [0, 1], [0, 1]], axis=0))
    ratio = empirical / formal
    assert np.all((ratio > 0.8) & (ratio < 1.25)), (empirical, formal)
    d2 = np.einsum("ni,nij,nj->n", e, np.linalg.inv(C), e)
    inside = float(np.mean(d2 < CHI2_95_2D))               # the drawn 95 % ellipse holds truth
    assert 0.88 <= inside <= 0.99, inside


def test_best_height_order_and_its_effect():
    """Two views beat the DEM, the DEM beats the mean: the ellipse in the third view shrinks."""
    scene = make_scene()
    truth = make_points(scene, n_gcp=9, n_icp=1, noise_px=0.2, seed=2)
    sol = solve(scene, [p for p in truth if p.kind == "GCP"])
    t = truth[-1]
    one = {"N": (*t.image["N"], None)}
    mean = predict_point(sol, PointInput("t", "TIE", one), sigma_mean=400.0)["F"]
    dem = predict_point(sol, PointInput("t", "TIE", one), height_of=lambda en: np.full(len(en), t.ground[2]),
                        sigma_dem=10.0, sigma_mean=400.0)["F"]
    two = predict_point(sol, PointInput("t", "TIE", {**one, "B": (*t.image["B"], None)}))["F"]
    assert (mean.source, dem.source, two.source) == ("mean", "reference", "intersection")
    assert mean.ellipse()[0] > 10 * dem.ellipse()[0] > 10 * two.ellipse()[0] / 2
    assert math.hypot(*np.subtract(dem.xy, t.image["F"])) < 2.0
    assert math.hypot(*np.subtract(two.xy, t.image["F"])) < 1.0
    assert abs(two.height - t.ground[2]) < 3 * two.sigma_h + 1.0
    # the long axis of the mean-height ellipse lies along the parallax (image y here)
    a, b, ang = mean.ellipse()
    assert a > 20 * b and abs(abs(math.sin(ang)) - 1) < 0.05


def test_sigma_of_dem_and_of_the_mean_height_from_the_project():
    ground = {f"P{i}": (1000.0 * i, 0.0, 100.0 + 10 * i) for i in range(5)}
    assert dem_sigma(lambda en: en[:, 0] / 100.0 + 100.0 + 3.0, ground) == pytest.approx(3.0)
    assert dem_sigma(None, ground) == DEFAULT_DEM_SIGMA_M
    assert height_spread(g[2] for g in ground.values()) == pytest.approx(np.std([100, 110, 120, 130, 140], ddof=1))


def test_vectorised_known_ground_predictions_equal_the_single_ones():
    from prismstation.ops.predict import predict_all
    scene = make_scene()
    truth = make_points(scene, n_gcp=9, n_icp=30, noise_px=0.2, seed=3)
    sol = solve(scene, truth[:9])
    pts = [PointInput(p.id, p.kind, {"N": (*p.image["N"], None)} if i % 2 else {}, p.ground, (0.5, 1.0))
           for i, p in enumerate(truth[9:])]
    allp = predict_all(sol, pts)
    for p in pts:
        one = predict_point(sol, p)
        assert set(allp[p.id]) == set(one) == ({"F", "B"} if p.measured else {"N", "F", "B"})
        for v, pr in one.items():
            assert np.allclose(allp[p.id][v].xy, pr.xy) and np.allclose(allp[p.id][v].cov, pr.cov)
            assert allp[p.id][v].source == "ground"


@pytest.mark.parametrize("view", ["F", "B"])
def test_a_point_measured_in_one_oblique_view_meets_a_steep_reference(view):
    """Measured only in F (or B), placed by the reference DEM: on a 60° slope along track the
    ray meets the surface where the old fixed five steps stopped metres short."""
    from prismstation.core.models import prism
    from prismstation.ops.predict import ground_estimate
    scene = make_scene()
    truth = make_points(scene, n_gcp=9, n_icp=1, noise_px=0.0, seed=1)
    sol = solve(scene, [PointObs(p.id, p.kind, p.ground, dict(p.image)) for p in truth if p.kind == "GCP"])
    icp = next(p for p in truth if p.kind == "ICP")
    en0 = np.array(icp.ground[:2], float)
    t = prism.along_track_unit(scene, en0)
    s = math.tan(math.radians(60.0))
    h0 = sol.mean_height + 400.0              # 400 m above the mean: the start is far off

    def plane(en):
        return h0 + s * ((np.asarray(en, float) - en0) @ t)
    xy = sol.ground_to_image(view, en0[None], np.array([h0]))[0]
    point = PointInput("p", "TIE", {view: (float(xy[0]), float(xy[1]), None)})
    g, _, source = ground_estimate(sol, point, height_of=plane, sigma_dem=0.01, sigma_mean=100.0)
    assert source == "reference"
    assert abs(g[2] - h0) < 0.05 and np.hypot(*(g[:2] - en0)) < 0.05
    # what five fixed-point steps from the mean height gave
    h = sol.mean_height
    for _ in range(5):
        h = float(plane(sol.image_to_ground(view, xy, h)[None])[0])
    assert abs(h - h0) > 5.0, h - h0
