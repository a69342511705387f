import numpy as np
import pytest

from prismstation.core.models import prism
from prismstation.core.orientation.dem_orient import (PatchShift, affine_field, control_from_field, gcp_field_obs,
                                          grid_points, patch_windows, smooth_like_reference)
from prismstation.core.models.solution import PointObs, solve
from prismstation.core.orientation import view_offsets as vo
from prismstation.sim.model_triplet import make_scene


def _shift(x, y):  # an affine field of shifts (m) over the N image, like the ~50 m Gonçalves reports
    x, y = np.asarray(x, float), np.asarray(y, float)
    return np.stack([40 + 3e-3 * x, -30 + 1e-3 * y, 12 - 5e-4 * x], -1)


def test_control_from_field_recovers_truth():
    sc = make_scene()
    rng = np.random.default_rng(4)
    # images made by an orientation that is off by the field: each view shows a point where the
    # ancillary model puts (P - dEN) at height (h - dh)
    pts, truth = [], {}
    for i in range(30):
        xy = rng.uniform(500, 13500, 2)
        h_true = rng.uniform(100, 1300)
        s = _shift(*xy)
        h_rel = h_true - s[2]
        en_anc = prism.ancillary_to_ground(sc, sc.views["N"], xy, h_rel)
        img = {v: tuple(prism.ground_to_ancillary(sc, view, en_anc, h_rel)) for v, view in sc.views.items()}
        truth[f"P{i}"] = (*(en_anc + s[:2]), h_true)
        pts.append(PointObs(f"P{i}", "ICP", truth[f"P{i}"], img))
    ctl = control_from_field(sc, _shift, mean_height=700)
    sol = solve(sc, pts, control=ctl)
    g = np.array([p.ground_residual for p in sol.points])
    # the ±3.5 m tilt of dh over the image is in the parallax line's tilt, not in the heights
    # (through the relief term h·d/Hs, a few cm stay in planimetry)
    assert ctl.part.parallax.tilt[0] == pytest.approx(-5e-4, rel=1e-6) and abs(ctl.part.parallax.tilt[1]) < 1e-9
    assert np.abs(g[:, :2]).max() < 0.15 and np.abs(g[:, 2]).max() < 0.05, np.abs(g).max(0)


def test_grid_points_mean_per_cell():
    g = grid_points([5, 6, 7, 15], [-5, -6, -7, -5], [1.0, 2.0, 3.0, 9.0], (10, 0, 0, 0, -10, 0), (2, 2),
                    min_count=1)
    assert g[0, 0] == pytest.approx(2.0) and g[0, 1] == pytest.approx(9.0) and np.isnan(g[1, 1])


def test_patch_windows_cover_without_slivers():
    w = patch_windows((2000, 2100), 400, margin_px=50)
    assert len(w) == 25 and min(p[2] for p in w) >= 350
    assert w[0][:2] == (50, 50) and w[-1][0] + w[-1][2] == 2050


def test_affine_field_of_a_record_made_before_the_joint_adjustment():
    """Records saved before the joint adjustment hold patches only: their used patches' affine
    fit is the field (a constant for patches on a line), so such projects still open."""
    patches = [PatchShift(w, w[0] + w[2] / 2, w[1] + w[3] / 2, *_shift(w[0] + w[2] / 2, w[1] + w[3] / 2),
                          1, 1, 1, 100, 0.9) for w in patch_windows((6000, 6000), 1500)]
    field = affine_field(patches)
    assert field(100.0, 5000.0) == pytest.approx(_shift(100.0, 5000.0))
    line = [PatchShift((0, 0, 1, 1), 100.0 * i, 50.0, 1.0, 2.0, 3.0, 0.5, 0.5, 0.2, 100, 0.9) for i in range(4)]
    assert affine_field(line)(0.0, 0.0) == pytest.approx([1.0, 2.0, 3.0])


@pytest.mark.parametrize("with_gradients", [True, False])
def test_view_offsets_varying_over_n_reach_the_biases_and_the_parallax_line(with_gradients):
    """F and B see every point where the ancillary model puts it plus an offset that drifts
    over N (±1.5 px along track): given the offsets' gradients the control carries every
    point to its ground position; taken as constants, metres are left (what the 14,000 px
    scenes showed along track)."""
    sc = make_scene()
    rows, cols = sc.views["N"].shape
    centre = (cols / 2, rows / 2)
    offs = {"F": np.array([0.3, 0.8]), "B": np.array([-0.2, -0.5])}
    grads = {"F": np.array([[0.0, 1e-5], [0.0, 1.1e-4]]), "B": np.array([[2e-5, 0.0], [0.0, -2.1e-4]])}
    rng = np.random.default_rng(7)
    pts = []
    for i in range(40):
        xy = rng.uniform(500, 13500, 2)
        h = rng.uniform(100, 1300)
        en = prism.ancillary_to_ground(sc, sc.views["N"], xy, h)
        img = {"N": tuple(xy)}
        for v in "FB":
            view = sc.views[v]
            o = vo.offset_at(offs[v], grads[v], centre, xy)
            img[v] = tuple(prism.ground_to_ancillary(sc, view, en, h)
                           + prism.to_nadir_space(sc, view).inverse().apply_linear(o))
        pts.append(PointObs(f"P{i}", "ICP", (*en, h), img))
    ctl = control_from_field(sc, lambda x, y: np.zeros(np.shape(x) + (3,)), 700.0,
                             {v: list(o) for v, o in offs.items()},
                             offset_gradients=grads if with_gradients else None)
    g = np.array([p.ground_residual for p in solve(sc, pts, control=ctl).points])
    if with_gradients:
        assert np.abs(g).max() < 0.05, np.abs(g).max(0)
    else:
        assert np.abs(g).max() > 1.0


def test_gcps_observe_the_field_as_the_cells_do():
    """A ground point seen in F and B through an orientation off by the field ``_shift`` (and
    with view offsets from N): :func:`gcp_field_obs` gives the field at its N position."""
    sc = make_scene()
    tF, tB = sc.views["F"].tan_theta, sc.views["B"].tan_theta
    w = tF / (tF + tB)
    offs = {"F": np.array([0.4, -1.2]), "B": np.array([-0.3, 0.9])}
    rng = np.random.default_rng(2)
    xy = rng.uniform(1000, 13000, (6, 2))
    h_true = rng.uniform(200, 1200, 6)
    s = _shift(xy[:, 0], xy[:, 1])
    h_rel = h_true - s[:, 2]
    en_anc = prism.ancillary_to_ground(sc, sc.views["N"], xy, h_rel)
    img = {}
    for v in "FB":
        view = sc.views[v]
        img[v] = (prism.ground_to_ancillary(sc, view, en_anc, h_rel)
                  + prism.to_nadir_space(sc, view).inverse().apply_linear(offs[v]))
    ground = np.column_stack([en_anc + s[:, :2], h_true])
    obs = gcp_field_obs(sc, img["F"], img["B"], ground, np.ones((6, 3)), lambda v, p: offs[v] + 0 * p, w)
    np.testing.assert_allclose(obs.value.reshape(-1, 3), s, atol=0.05)
    np.testing.assert_allclose(np.column_stack([obs.x, obs.y])[::3], xy, atol=0.02)


def test_smooth_like_reference_is_the_box_and_tent_of_the_reference_cells():
    rng = np.random.default_rng(3)
    z = rng.normal(size=(40, 40))
    assert np.array_equal(smooth_like_reference(z, (1, 1)), z)
    s = smooth_like_reference(z, (3, 3))
    ker = np.convolve(np.ones(3), [1, 2, 3, 2, 1]) / 27          # box 3 ⊗ tent of half-width 3
    want = np.einsum("i,j,ij->", ker, ker, z[10:17, 10:17])
    assert s[13, 13] == pytest.approx(want)
    # the border: the outer taps weigh 1/27 each, so one row of them missing passes need = 0.95
    assert np.isnan(s[:2]).all() and np.isfinite(s[2, 3:-3]).all() and np.isfinite(s[3:-3, 3:-3]).all()
    z[20, 20] = np.nan                                   # one void: the cells whose kernel it hits
    s = smooth_like_reference(z, (3, 3), need=0.999)
    assert np.isnan(s[17:24, 17:24]).all() and np.isfinite(s[16, 20]) and np.isfinite(s[24, 20])
    assert np.isfinite(smooth_like_reference(z, (3, 3), need=0.9)[20, 20])


@pytest.mark.parametrize("cells", [(2, 2), (2.33, 3.08), (3, 3), (4, 1)])
def test_smooth_like_reference_does_not_move_the_surface(cells):
    """Any ratio of reference cells to grid cells — whole, even or not whole (3″ of longitude
    over 30 m at 45° N is 2.3) — leaves a tilted plane where it is: a kernel that is not centred
    would shift the relative DEM by half a cell (15 m at 30 m)."""
    y, x = np.mgrid[0:60, 0:60].astype(float)
    plane = 3.0 * x - 2.0 * y
    s = smooth_like_reference(plane, cells)
    assert np.abs(s[10:-10, 10:-10] - plane[10:-10, 10:-10]).max() < 1e-9


def test_voids_that_follow_the_relief_do_not_move_the_smoothed_shift():
    """A 90 m reference (cell means, read bilinearly onto 30 m) and the true 30 m terrain with
    voids where the matcher typically fails — small crests facing one way: matched as it is, the
    terrain lands metres off; smoothed to the reference's resolution, within 0.5 m."""
    from scipy import ndimage
    from prismstation.core.matching.coarse import dem_offset
    rng = np.random.default_rng(0)
    n = 540                                                      # 10 m cells
    f = ndimage.gaussian_filter(rng.normal(size=(n, n)), 12)
    g = ndimage.gaussian_filter(rng.normal(size=(n, n)), 3)
    h10 = 400 * f / f.std() + 25 * g / g.std()
    h30 = h10.reshape(n // 3, 3, n // 3, 3).mean((1, 3))
    h90 = h10.reshape(n // 9, 9, n // 9, 9).mean((1, 3))
    c = (np.arange(n // 3) + 0.5) / 3 - 0.5                      # 30 m centres in 90 m cells
    rr, cc = np.meshgrid(c, c, indexing="ij")
    ref = ndimage.map_coordinates(h90, [rr, cc], order=1, mode="nearest")
    crest = h30 - ndimage.uniform_filter(h30, 5)
    void = ndimage.binary_dilation((crest > 0.5 * crest.std()) & (np.gradient(h30, axis=1) < 0)
                                   & (rng.random(h30.shape) < 0.3))
    rel = np.where(void, np.nan, h30)
    t, crop = (30.0, 0, 0, 0, -30.0, 0), (slice(8, -8), slice(8, -8))
    raw = dem_offset(ref[crop], rel[crop], t, 100.0)
    smooth = dem_offset(ref[crop], smooth_like_reference(rel, (3, 3))[crop], t, 100.0)
    assert abs(raw.dx) > 3.0                                     # the voids' bias, unsmoothed
    assert np.hypot(smooth.dx, smooth.dy) < 0.5 and abs(smooth.dz) < 1.5
