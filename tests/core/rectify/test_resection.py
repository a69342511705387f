"""Space resection on simulated frame cameras, and the B/H ratio of Subaryono et al. (docs/model.md §6)."""
import json
import math

import numpy as np
import pytest

from prismstation.cli import main
from prismstation.core.models.resection import (FrameCamera, angles_of, base_height, homography_start,
                                         project, resect, rotation_matrix, vertical_start)
from prismstation.errors import ModelError


def _aerial(rng, n=30, noise=0.5):
    cam = FrameCamera(0.153, 10e-6, 5000.0, 4000.0)
    eo = np.array([1000.0, 2000.0, 1800.0, math.radians(2), math.radians(-3), math.radians(30)])
    xyz = np.column_stack([rng.uniform(300, 1800, n), rng.uniform(1300, 2800, n),
                           rng.uniform(0, 200, n)])
    xy = project(cam, eo, xyz) + rng.normal(0, noise, (n, 2))
    return cam, eo, xyz, xy


def test_rotation_matrix_is_wolf_omega_phi_kappa():
    o, p, k = 0.1, -0.2, 0.3
    Rx = np.array([[1, 0, 0], [0, math.cos(o), math.sin(o)], [0, -math.sin(o), math.cos(o)]])
    Ry = np.array([[math.cos(p), 0, -math.sin(p)], [0, 1, 0], [math.sin(p), 0, math.cos(p)]])
    Rz = np.array([[math.cos(k), math.sin(k), 0], [-math.sin(k), math.cos(k), 0], [0, 0, 1]])
    assert np.allclose(rotation_matrix(o, p, k), Rz @ Ry @ Rx)


def test_projection_of_a_vertical_camera_by_hand():
    cam = FrameCamera(0.1, 1e-5, 500.0, 500.0)
    # 1000 m above the point, 100 m east and 50 m north of the nadir: scale f/H = 1e-4
    xy = project(cam, [0, 0, 1000, 0, 0, 0], [[100.0, 50.0, 0.0]])
    assert np.allclose(xy, [[500 + 100 * 1e-4 / 1e-5, 500 - 50 * 1e-4 / 1e-5]])


def test_resection_recovers_eo_within_sigma():
    rng = np.random.default_rng(0)
    cam, eo, xyz, xy = _aerial(rng)
    r = resect(cam, xy, xyz)
    assert r.converged
    assert np.all(np.abs(r.params - eo) < 3.5 * r.sigma), (r.params - eo) / r.sigma
    assert r.sigma0_px == pytest.approx(0.5, rel=0.3)
    # history: starts at the start, each row adds that iteration's correction
    assert np.allclose(r.history[0], r.start) and not np.allclose(r.start, r.params)
    assert np.allclose(r.history[0], r.start)
    assert np.allclose(np.diff(r.history, axis=0), r.corrections)
    assert np.allclose(r.history[-1][:3], r.params[:3])
    size = np.abs(r.corrections[:, 3:]).max(axis=1)
    assert size[-1] < 1e-8 < size[0]
    assert "pushbroom" in r.note


def test_vertical_and_homography_starts_reach_the_same_solution():
    rng = np.random.default_rng(4)
    cam, eo, xyz, xy = _aerial(rng)
    v = vertical_start(cam, xy, xyz)
    assert v[3] == 0 and v[4] == 0
    assert abs(v[5] - eo[5]) < 0.1 and abs(v[2] - eo[2]) < 300      # κ and height roughly right
    h = homography_start(cam, xy, xyz)
    assert np.all(np.abs(h[3:] - eo[3:]) < 0.05)
    a = resect(cam, xy, xyz, start=v)
    b = resect(cam, xy, xyz, start=h)
    assert a.converged and b.converged
    assert np.allclose(a.params, b.params, atol=1e-6)


def test_angles_of_inverts_rotation_matrix():
    for o, p, k in [(0.1, -0.2, 0.3), (-1.0, 0.5, 3.0), (0.0, 0.0, -2.5)]:
        assert np.allclose(angles_of(rotation_matrix(o, p, k)), (o, p, k))


@pytest.mark.parametrize("tilt_deg,kappa_deg", [(18.8, 0.0), (30.0, 90.0), (30.0, -150.0)])
def test_resection_of_tilted_satellite_views(tilt_deg, kappa_deg):
    """Off-nadir views (Subaryono et al.'s right image pointed 18.8°) converge from the homography start."""
    rng = np.random.default_rng(5)
    cam = FrameCamera(1.082, 7e-6, 5000.0, 5000.0)
    eo = np.array([202559.7, 3894686.0, 580710.5, math.radians(tilt_deg), math.radians(-2.0),
                   math.radians(kappa_deg)])
    M = rotation_matrix(*eo[3:])
    px = rng.uniform(0, 10000, (25, 2))
    d = np.column_stack([cam.to_photo(px), np.full(25, -cam.focal_m)]) @ M   # rays to the ground
    xyz = eo[:3] + ((400 - eo[2]) / d[:, 2])[:, None] * d
    xyz[:, 2] = rng.uniform(0, 900, 25)
    xy = project(cam, eo, xyz) + rng.normal(0, 0.5, (25, 2))
    r = resect(cam, xy, xyz, max_iterations=40)
    assert r.converged
    assert np.all(np.abs(r.params - eo) < 4 * r.sigma), (r.params - eo) / r.sigma


def test_resection_sigma_is_calibrated_over_trials():
    """Standardised errors (estimate − truth) / σ have an RMS near 1 for every parameter."""
    rng = np.random.default_rng(1)
    z = []
    for _ in range(40):
        cam, eo, xyz, xy = _aerial(rng, n=15, noise=1.0)
        r = resect(cam, xy, xyz)
        z.append((r.params - eo) / r.sigma)
    rms = np.sqrt(np.mean(np.square(z), axis=0))
    assert np.all((rms > 0.7) & (rms < 1.4)), rms


def test_resection_of_a_narrow_satellite_view_converges():
    """Subaryono et al.'s setting: f = 1082 mm, ~620 km altitude, tilted view, 10 iterations."""
    rng = np.random.default_rng(2)
    cam = FrameCamera(1.082, 7e-6, 5000.0, 5000.0)
    eo = np.array([366305.4, 3766906.0, 619052.4, math.radians(1.0), math.radians(-2.2),
                   math.radians(12.0)])
    xyz = np.column_stack([rng.uniform(-30e3, 30e3, 25) + eo[0], rng.uniform(-30e3, 30e3, 25) + eo[1],
                           rng.uniform(0, 900, 25)])
    xy = project(cam, eo, xyz)
    r = resect(cam, xy, xyz, max_iterations=10)
    assert r.converged and len(r.corrections) <= 10
    assert np.allclose(r.params[:3], eo[:3], atol=1e-3)
    assert np.allclose(r.params[3:], eo[3:], atol=1e-9)


def test_resection_bad_geometry_is_a_model_error():
    cam = FrameCamera(0.153, 1e-5, 0, 0)
    with pytest.raises(ModelError, match="at least 3"):
        resect(cam, [[0, 0], [1, 1]], [[0, 0, 0], [1, 1, 0]])
    t = np.linspace(0, 100, 6)
    with pytest.raises(ModelError, match="collinear"):
        resect(cam, np.column_stack([t, t]), np.column_stack([t, t, t * 0]))


def test_base_height_reproduces_seed_002():
    left = (366305.4, 3766906.0, 619052.4)
    right = (202559.7, 3894686.0, 580710.5)
    bh = base_height(left, right)
    b = math.sqrt((202559.7 - 366305.4) ** 2 + (3894686.0 - 3766906.0) ** 2
                  + (580710.5 - 619052.4) ** 2)
    assert bh.base_m == pytest.approx(b, abs=1e-6)
    assert round(bh.base_m, 1) == 211211.9          # paper
    assert bh.height_m == pytest.approx(599881.45, abs=1e-6)
    assert round(bh.b_over_h, 6) == 0.352089        # paper


def test_bh_command_prints_and_writes_json(tmp_path, capsys):
    out = tmp_path / "bh.json"
    rc = main(["bh", "--left", "366305.4", "3766906.0", "619052.4",
               "--right", "202559.7", "3894686.0", "580710.5", "--json", str(out)])
    assert rc == 0
    text = capsys.readouterr().out
    assert "211211.9" in text and "0.352089" in text
    d = json.loads(out.read_text())
    assert d["height_m"] == pytest.approx(599881.45)
    assert d["b_over_h"] == pytest.approx(0.352089, abs=5e-7)


def _write_points(tmp_path, xyz, xy, icp=()):
    pts = tmp_path / "points.csv"
    meas = tmp_path / "meas.csv"
    pts.write_text("id,E,N,H,kind\n" + "".join(
        f"P{i},{e:.4f},{n:.4f},{h:.4f},{'ICP' if i in icp else 'GCP'}\n"
        for i, (e, n, h) in enumerate(xyz)))
    meas.write_text("id,view,x,y\n" + "".join(f"P{i},L,{x:.5f},{y:.5f}\n" for i, (x, y) in enumerate(xy)))
    return pts, meas


def test_resection_command_and_bh_from_two_resections(tmp_path, capsys):
    rng = np.random.default_rng(3)
    cam, eo, xyz, xy = _aerial(rng, noise=0.3)
    pts, meas = _write_points(tmp_path, xyz, xy, icp=(0, 1))
    out = tmp_path / "left.json"
    rc = main(["resection", str(pts), "--measurements", str(meas), "--focal-mm", "153",
               "--pixel-um", "10", "--principal-point", "5000", "4000", "--json", str(out)])
    assert rc == 0
    text = capsys.readouterr().out
    assert "converged" in text and "pushbroom" in text
    d = json.loads(out.read_text())
    direct = resect(cam, xy[2:], xyz[2:])             # the command leaves ICPs out
    assert d["eo"]["X0"] == pytest.approx(direct.params[0], abs=0.01)
    assert d["eo"]["kappa_deg"] == pytest.approx(math.degrees(direct.params[5]), abs=1e-5)
    assert d["sigma"]["Z0"] == pytest.approx(direct.sigma[2], rel=1e-3)
    assert len(d["corrections"]) == len(d["history"]) - 1 >= 2
    rc = main(["bh", "--left-resection", str(out), "--right", "1500", "2000", "1800"])
    assert rc == 0
    b = math.dist(direct.params[:3], (1500, 2000, 1800))
    assert f"{b:.1f}" in capsys.readouterr().out


def test_resection_command_bad_input_exits_2_with_one_line(tmp_path, capsys):
    pts = tmp_path / "p.csv"
    pts.write_text("id,E,N,H,x,y\nA,1,2,3,4,5\nB,1,2,,4,5\nC,1,2,3,4\n")
    rc = main(["resection", str(pts), "--focal-mm", "153", "--pixel-um", "10",
               "--image-size", "100", "100"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1
    assert "p.csv" in err and "line 4" in err
    bad = tmp_path / "r.json"
    bad.write_text('{"eo": {"X0": 1}}')
    rc = main(["bh", "--left-resection", str(bad), "--right", "1", "2", "3"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "r.json" in err and len(err.splitlines()) == 1


def test_resection_agrees_with_opencv_solvepnp():
    """Both minimise the reprojection error in pixels: same optimum (cv2's camera frame is the
    photo frame with y and z flipped; its pixel centres sit at integers)."""
    import cv2

    rng = np.random.default_rng(6)
    cam, eo, xyz, xy = _aerial(rng, n=25, noise=0.7)
    ours = resect(cam, xy, xyz)
    centre = xyz.mean(axis=0)
    K = np.array([[cam.focal_m / cam.pixel_m, 0, cam.cx - 0.5],
                  [0, cam.focal_m / cam.pixel_m, cam.cy - 0.5], [0, 0, 1.0]])
    ok, rvec, tvec = cv2.solvePnP(xyz - centre, xy - 0.5, K, None, flags=cv2.SOLVEPNP_ITERATIVE)
    assert ok
    ok, rvec, tvec = cv2.solvePnP(xyz - centre, xy - 0.5, K, None, rvec, tvec, True,
                                  flags=cv2.SOLVEPNP_ITERATIVE)
    R_cv = cv2.Rodrigues(rvec)[0]
    M = np.diag([1.0, -1.0, -1.0]) @ R_cv
    C = -R_cv.T @ tvec.ravel() + centre
    assert np.allclose(ours.params[:3], C, atol=0.01)
    assert np.allclose(ours.params[3:], angles_of(M), atol=1e-6)
