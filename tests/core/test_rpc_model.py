"""The RPC model behind the sensor-model seam, and its fit (``solve`` on an RPC scene).

The scene is the real Pléiades triplet's (its RPCs from the GeoTIFF tags); the observations are
made by projecting ground points through those RPCs with known image-space biases and noise,
so that every fitted number has a known answer. The fit on the triplet's own matched tie points
is in ``tests/cli/test_rpc_project.py``.
"""
from __future__ import annotations

import numpy as np
import pytest

from prismstation.core.models.rpc_bias import BiasedRpc
from prismstation.core.models.rpc_model import RpcBias, RpcModel
from prismstation.core.models.sensor import SensorModel
from prismstation.core.models.solution import PointObs, Settings, solve
from prismstation.io.rpc_scene import write_scene_for_images
from prismstation.io.scene import read_scene

FILES = [f"pleiades_triplet/img_0{i}.tif" for i in (1, 2, 3)]
SIGMA = 0.2   # px, the simulated measurement noise
#: the biases put into the observations (shift: a0, b0 px), per view
TRUE = {"img_01": (0.8, -1.5), "img_02": (-2.0, 3.0), "img_03": (1.2, 25.0)}


@pytest.fixture(scope="module")
def scene(shared_data, tmp_path_factory):
    d = tmp_path_factory.mktemp("rpcscene")
    return read_scene(write_scene_for_images([shared_data / f for f in FILES], d / "scene.json"))


def terrain(en):
    """A smooth hill (ellipsoidal m) over the crops: the 'truth' and the reference DEM."""
    en = np.asarray(en, float).reshape(-1, 2)
    return 250.0 + 40.0 * np.sin(en[:, 0] / 150.0) * np.cos(en[:, 1] / 110.0)


def ground_grid(scene, n=8):
    """``n × n`` map points inside every view's footprint, at the terrain's height."""
    c = np.vstack([v.footprint() for v in scene.views.values()])
    lo, hi = c.min(0), c.max(0)
    lo, hi = lo + 0.3 * (hi - lo), hi - 0.3 * (hi - lo)
    E, N = np.meshgrid(np.linspace(lo[0], hi[0], n), np.linspace(lo[1], hi[1], n))
    en = np.column_stack([E.ravel(), N.ravel()])
    return en, terrain(en)


def observations(scene, en, h, gcp_idx=(), seed=0):
    """PointObs of the ground points seen in every view through the biased RPCs (+ noise);
    the points ``gcp_idx`` are GCPs with their true ground, the others tie points."""
    rng = np.random.default_rng(seed)
    model = RpcModel(scene, {v: RpcBias("shift", TRUE[v]) for v in scene.views})
    xy = {v: model.ground_to_image(v, en, h) + rng.normal(0, SIGMA, (len(en), 2)) for v in scene.views}
    pts = []
    for i in range(len(en)):
        g = i in gcp_idx
        pts.append(PointObs(f"P{i:02d}", "GCP" if g else "TIE", (en[i, 0], en[i, 1], h[i]) if g else None,
                            {v: tuple(xy[v][i]) for v in scene.views}, {}, (0.01, 0.01) if g else None))
    return pts


def test_model_is_the_rpc_through_the_map_projection(scene):
    model = RpcModel(scene)
    assert isinstance(model, SensorModel) and scene.sensor is RpcModel
    en, h = ground_grid(scene, 5)
    for name, view in scene.views.items():
        lon, lat = view.projection.to_lonlat(en[:, 0], en[:, 1])
        x, y = view.rpc.project(lon, lat, h)
        np.testing.assert_array_equal(model.ground_to_image(name, en, h), np.column_stack([x, y]))
        assert 0.45 < view.pixel_size_m < 0.55          # Pléiades panchromatic, ~0.5 m


def test_image_to_ground_inverts_ground_to_image_with_a_bias(scene):
    bias = {v: RpcBias("affine", [1.5, 0.3, -0.2, -4.0, 0.1, 0.5], None, 500.0, 500.0) for v in scene.views}
    model = RpcModel(scene, bias)
    en, h = ground_grid(scene, 5)
    for v in scene.views:
        xy = model.ground_to_image(v, en, h)
        back = model.ground_to_image(v, model.image_to_ground(v, xy, h), h)
        assert np.max(np.abs(back - xy)) < 1e-6
        # the biased model solves xy = rpc(ground) + Δ(xy)
        m = BiasedRpc(scene.views[v].rpc, "affine", bias[v].params, 500.0, 500.0)
        lon, lat = scene.views[v].projection.to_lonlat(en[:, 0], en[:, 1])
        x, y = scene.views[v].rpc.project(lon, lat, h)
        np.testing.assert_allclose(xy - m.bias_at(xy[:, 0], xy[:, 1]), np.column_stack([x, y]), atol=1e-6)


def test_partials_match_finite_differences(scene):
    model = RpcModel(scene, {v: RpcBias("shift_drift", [1.0, 2.0, 0.7]) for v in scene.views})
    en, h = ground_grid(scene, 3)
    for v in scene.views:
        xy, J = model.partials(v, en, h)
        np.testing.assert_allclose(xy, model.ground_to_image(v, en, h), atol=1e-9)
        s = 0.05
        for k in range(3):
            d = np.zeros(3)
            d[k] = s
            hi = model.ground_to_image(v, en + d[:2], h + d[2])
            lo = model.ground_to_image(v, en - d[:2], h - d[2])
            np.testing.assert_allclose(J[:, :, k], (hi - lo) / (2 * s), rtol=2e-4, atol=1e-6)
        # ~2 px per metre across a 0.5 m pixel; the height moves the point along the track
        assert 1.5 < np.abs(J[:, :, :2]).max() < 2.5


def test_bias_covariance_of_a_shift_is_its_parameter_covariance(scene):
    cov = np.array([[0.04, 0.01], [0.01, 0.09]])
    model = RpcModel(scene, {v: RpcBias("shift", [1.0, 2.0], cov) for v in scene.views})
    np.testing.assert_allclose(model.bias_cov("img_02", np.array([[10.0, 20.0], [900.0, 50.0]])),
                               np.broadcast_to(cov, (2, 2, 2)))


def test_gcps_fit_every_view_bias_within_its_sigma(scene):
    en, h = ground_grid(scene)
    pts = observations(scene, en, h, gcp_idx=(0, 7, 27, 56, 63))
    sol = solve(scene, pts, Settings(bias_model="shift", sigma_px=SIGMA))
    assert sol.ok and not sol.failures, sol.messages
    assert 0.7 < sol.bias["img_01"].sigma0 < 1.3
    for v, true in TRUE.items():
        b = sol.bias[v]
        assert not b.fixed
        err = (b.params - true) / b.std
        assert np.all(np.abs(err) < 4), (v, b.params, b.std)
        assert np.all(b.std < 0.2)
    # tie points: intersected, with their σ; residuals per view
    ties = [p for p in sol.points if p.kind == "TIE"]
    dh = np.array([p.ground_est[2] for p in ties]) - terrain([p.ground_est[:2] for p in ties])
    sh = np.array([p.ground_sigma[2] for p in ties])
    assert np.sqrt(np.mean((dh / sh) ** 2)) < 1.5
    assert all(p.height_source == "intersection" and set(p.residual_px) == set(TRUE) for p in ties)
    assert set(sol.stats.image["img_03"]) == {"GCP", "ICP", "TIE"}
    assert sol.stats.image["img_03"]["TIE"].px.x.rms < 2 * SIGMA


def test_fixed_view_and_reference_heights_find_the_relative_line_bias(scene):
    """No GCP: img_01 held fixed, tie points held to the reference DEM's heights; the others'
    biases come out relative to img_01's (plus what the DEM's datum gives a line bias)."""
    en, h = ground_grid(scene)
    pts = observations(scene, en, h, seed=1)
    sol = solve(scene, pts, Settings(bias_model="shift", sigma_px=SIGMA, fixed_view="img_01"),
                height_of=terrain, height_sigma_m=0.5)
    assert sol.ok, sol.messages
    assert sol.bias["img_01"].fixed and sol.bias["img_01"].params.size == 0
    assert any("held to the reference DEM" in m for m in sol.messages)
    # img_03's bias comes out relative to img_01's: (1.2, 25) − (0.8, −1.5) px, to within 4 σ
    # and a tenth of a pixel (holding img_01 at zero moves the ground by its 0.8 m shift,
    # which img_03 sees through a slightly different scale)
    ref = sol.bias["img_03"]
    rel = np.array(TRUE["img_03"]) - np.array(TRUE["img_01"])
    assert np.all(np.abs(ref.params - rel) < 4 * ref.std + 0.1), (ref.params, ref.std, rel)
    assert ref.std[1] < 0.5


def test_tie_points_alone_leave_the_line_bias_to_its_prior(scene):
    en, h = ground_grid(scene)
    pts = [p for p in observations(scene, en, h, seed=2) if True]
    pair = type(scene)(scene.crs, None, None, {v: scene.views[v] for v in ("img_01", "img_03")}, None, {},
                       RpcModel)
    pts = [PointObs(p.id, p.kind, p.ground, {v: p.image[v] for v in pair.views}) for p in pts]
    sol = solve(pair, pts, Settings(bias_model="shift", sigma_px=SIGMA))
    assert sol.ok
    assert any("not determined by the data" in m and "img_03" in m for m in sol.messages), sol.messages
    b = sol.bias["img_03"]
    assert abs(b.params[1]) < 3 * b.std[1] and b.std[1] > 2.0   # no confident wrong answer


def test_a_blunder_is_flagged(scene):
    en, h = ground_grid(scene)
    pts = observations(scene, en, h, gcp_idx=(0, 7, 56, 63), seed=3)
    p = pts[30]
    bad = dict(p.image)
    bad["img_02"] = (bad["img_02"][0] + 6 * SIGMA * 3, bad["img_02"][1])
    pts[30] = PointObs(p.id, p.kind, p.ground, bad)
    sol = solve(scene, pts, Settings(bias_model="shift", sigma_px=SIGMA))
    flagged = [r.id for r in sol.points if r.blunder]
    assert flagged == [p.id]


def test_check_points_are_intersected_and_compared(scene):
    en, h = ground_grid(scene)
    pts = observations(scene, en, h, gcp_idx=(0, 7, 56, 63), seed=4)
    pts = [PointObs(p.id, "ICP", (en[i, 0], en[i, 1], h[i]), p.image) if i in (20, 35, 44) else p
           for i, p in enumerate(pts)]
    sol = solve(scene, pts, Settings(bias_model="shift", sigma_px=SIGMA))
    icp = [r for r in sol.points if r.kind == "ICP"]
    assert len(icp) == 3
    for r in icp:
        assert r.height_source == "intersection"
        assert np.all(np.abs(r.ground_residual) < 4 * np.array(r.ground_sigma) + 0.05), (r.ground_residual, r.ground_sigma)
    assert sol.stats.height["ICP"].n == 3 and sol.stats.ground["ICP"].x.n == 3


def test_single_view_point_meets_the_reference_dem(scene):
    en, h = ground_grid(scene)
    pts = observations(scene, en, h, gcp_idx=(0, 7, 56, 63), seed=5)
    p = pts[10]
    pts[10] = PointObs(p.id, "TIE", None, {"img_02": p.image["img_02"]})
    sol = solve(scene, pts, Settings(bias_model="shift", sigma_px=SIGMA), height_of=terrain, height_sigma_m=1.0)
    r = next(r for r in sol.points if r.id == p.id)
    assert r.height_source == "reference"
    assert abs(r.ground_est[2] - terrain(r.ground_est[:2])[0]) < 0.05
    assert np.hypot(*(np.array(r.ground_est[:2]) - en[10])) < 1.0
    assert "one image" in r.note


def test_unknown_settings_are_model_errors(scene):
    from prismstation.errors import ModelError
    with pytest.raises(ModelError, match="bias model"):
        solve(scene, [], Settings(bias_model="similarity"))
    with pytest.raises(ModelError, match="held fixed"):
        solve(scene, [], Settings(bias_model="shift", fixed_view="N"))
    sol = solve(scene, [], Settings(bias_model="shift"))
    assert not sol.ok and "nothing to fit" in sol.messages[0]


def test_reference_heights_without_their_sigma_are_not_used_for_tie_points(scene):
    en, h = ground_grid(scene)
    pts = observations(scene, en, h, seed=6)
    sol = solve(scene, pts, Settings(bias_model="shift", sigma_px=SIGMA, fixed_view="img_01"), height_of=terrain)
    assert sol.ok and any("without their σ" in m for m in sol.messages)
    assert not any("held to the reference DEM" in m for m in sol.messages)
