import math

import numpy as np
import pytest

from prismstation.core.models import prism
from prismstation.core.adjustment.affine import Affine2D
from prismstation.core.models.solution import PointObs, Settings, solve
from prismstation.errors import ModelError

from prismstation.sim.model_triplet import PAPER_B, PAPER_M, make_points, make_scene


def test_eq4_theoretical_parallax_scale():  # docs/model.md §6, Gonçalves 2008 eq. 4
    c1 = 2.5 / (math.tan(math.radians(26.8)) + math.tan(math.radians(26.4)))
    assert round(c1, 4) == 2.4962
    assert prism.theoretical_c1(make_scene()) == pytest.approx(c1)
    assert 455 * c1 == pytest.approx(1136, abs=1.0)  # 000 §3.1: 455 px, highest point 1137 m


def test_affine_roundtrip_and_coeff_order():
    a = Affine2D.from_coeffs(0.4, 0.01, -0.02, -0.4, 1000.0, 2000.0)
    assert a.coeffs() == pytest.approx([0.4, 0.01, -0.02, -0.4, 1000.0, 2000.0])
    p = np.array([[540000.0, 4560000.0], [1.0, 2.0]])
    assert np.allclose(a.inverse()(a(p)), p)
    assert np.allclose((a @ a.inverse())(p), p)


@pytest.mark.parametrize("heading,path", [(192, True), (192, False), (348, True), (348, False)])
def test_relief_inverse_forward(heading, path):
    sc = make_scene(heading, path)
    rng = np.random.default_rng(1)
    en = sc.views["N"].map_to_image.inverse()(rng.uniform(0, 14000, (20, 2)))
    h = rng.uniform(0, 1400, 20)
    for v in sc.views.values():
        xy0 = prism.ground_to_ancillary(sc, v, en, h)
        assert np.allclose(prism.ancillary_to_ground(sc, v, xy0, h), en, atol=1e-6)


def test_relief_direction_and_size():
    sc = make_scene()
    en = sc.track.points.mean(axis=0) + np.array([[5000.0, 0.0]])
    foot, t = sc.track.foot(en)
    d = np.hypot(*(en - foot)[0])
    s_n = prism.relief_shift(sc, sc.views["N"], en, 1000.0)
    assert np.hypot(*s_n[0]) == pytest.approx(1000 * d / 691650.0)
    s_f = prism.relief_shift(sc, sc.views["F"], en, 1000.0) - s_n
    assert s_f[0] @ t[0] == pytest.approx(1000 * math.tan(math.radians(26.4)))  # forward: ahead
    s_b = prism.relief_shift(sc, sc.views["B"], en, 1000.0) - s_n
    assert s_b[0] @ t[0] == pytest.approx(-1000 * math.tan(math.radians(26.8)))


@pytest.mark.parametrize("heading,path", [(192, True), (192, False), (348, True), (348, False)])
def test_exact_recovery_of_paper_coefficients(heading, path):  # docs/model.md §6, Gonçalves 2008 eq. 3
    sc = make_scene(heading, path)
    sol = solve(sc, make_points(sc), Settings("affine", "line"))
    fit = sol.bias["N"]
    assert np.allclose(fit.M, PAPER_M, atol=1e-9) and np.allclose(fit.b, PAPER_B, atol=1e-6)
    assert sol.model.parallax.c1 == pytest.approx(prism.theoretical_c1(sc), rel=1e-9)
    g = np.array([p.ground_residual for p in sol.points])
    assert np.abs(g).max() < 1e-4
    if path:  # image x is across track in a path-oriented image: F−N is the x difference
        fx = np.mean([q.image["F"][0] - q.image["N"][0] for q in make_points(sc)])
        assert sol.stats["F-N"].mean == pytest.approx(fx, abs=1e-6)


def test_statistics_at_noise_floor():
    sc = make_scene()
    sig = 0.3
    rms_icp = []
    for seed in range(40):
        sol = solve(sc, make_points(sc, noise_px=sig, seed=seed), Settings("affine", "line"))
        rms_icp.append(sol.stats["image"]["N"]["ICP"]["px"].x.rms)
        assert sol.stats["image"]["N"]["GCP"]["px"].n == 9
    # ICP per-axis RMS ≈ σ·sqrt(1 + u/n) with u/n = 3/9 for the affine model (per axis)
    assert np.sqrt(np.mean(np.square(rms_icp))) == pytest.approx(sig * math.sqrt(1 + 3 / 9), rel=0.1)


def test_bias_models_and_parameter_std():
    sc = make_scene()
    pts = make_points(sc, noise_px=0.3, seed=3, M=np.zeros((2, 2)))
    for model, u in (("shift", 2), ("similarity", 4), ("affine", 6)):
        fit = solve(sc, pts, Settings(model)).bias["N"]
        assert len(fit.params) == u and np.all(fit.std > 0) and fit.lsq.dof == 18 - u
        assert fit.b == pytest.approx(PAPER_B, abs=4 * fit.std[-2:].max() + 0.05)


def test_too_few_and_collinear_gcps_give_reasons():
    sc = make_scene()
    pts = make_points(sc, n_gcp=2, n_icp=5)
    sol = solve(sc, pts, Settings("affine"))
    assert not sol.ok and any("at least 3 GCPs" in m for m in sol.messages)
    line = [PointObs(f"C{i}", "GCP", (540000.0 + 100 * i, 4560000.0 + 100 * i, 100.0),
                     {"N": (1000.0 + i * 10, 1000.0 + i * 10)}) for i in range(5)]
    sol = solve(sc, line, Settings("affine"))
    assert not sol.ok and any("one line" in m for m in sol.messages)
    with pytest.raises(ModelError):
        prism.fit_bias(np.zeros((3, 2)), np.zeros((3, 2)), "affine")


def test_blunder_stands_out():
    sc = make_scene()
    pts = make_points(sc, n_gcp=12, noise_px=0.3, seed=5)
    bad = pts[4]
    img = dict(bad.image); img["N"] = (img["N"][0] + 5.0, img["N"][1])
    pts[4] = PointObs(bad.id, bad.kind, bad.ground, img)
    sol = solve(sc, pts)
    flagged = [p.id for p in sol.points if p.blunder]
    assert flagged == [bad.id]


def test_tie_point_and_single_view_points():
    sc = make_scene()
    pts = make_points(sc)
    tie = PointObs("T1", "TIE", None, pts[20].image)
    n_only = PointObs("T2", "TIE", None, {"N": pts[21].image["N"]})
    sol = solve(sc, pts + [tie, n_only])
    t1 = sol.point("T1")
    assert t1.height_source == "parallax"
    assert np.allclose(t1.ground_est, pts[20].ground, atol=1e-3)
    t2 = sol.point("T2")
    assert t2.height_source == "mean" and "F and B" in t2.note


def test_point_order_does_not_matter():
    sc = make_scene()
    pts = make_points(sc, noise_px=0.3, seed=9)
    a = solve(sc, pts).bias["N"].params
    b = solve(sc, pts[::-1]).bias["N"].params
    assert np.allclose(a, b, rtol=1e-10, atol=1e-12)


def test_transfer_between_views():
    sc = make_scene()
    pts = make_points(sc)
    sol = solve(sc, pts)
    p = pts[30]
    got = sol.transfer("N", p.image["N"], h=p.ground[2])
    for v in "NFB":
        assert np.allclose(got[v], p.image[v], atol=1e-6)
