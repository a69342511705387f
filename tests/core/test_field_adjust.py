"""The joint adjustment of the DEM orientation's shift field (core/orientation/field_adjust.py), its σ and
the terrain's conditioning verdict (core/orientation/conditioning.py), on synthetic cells whose truth is known."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage
from scipy.optimize import least_squares

from prismstation.core.orientation import conditioning as cond
from prismstation.core.orientation.field_adjust import Cells, FieldObs, accumulate, adjust_field, signal_share
from prismstation.core.orientation.field_model import Basis, Distortion, Surface

POST = 30.0          # reference posting (m)
GSD = 2.5            # N pixel (m); N image 6000 px = 15 km, north-up, the map offset by ORIGIN
ORIGIN = 3000.0
SIZE = 6000
BASIS = Basis.over((SIZE, SIZE))
PRIOR = np.full(9, 50.0)


def terrain(seed=1, n=600, relief=300.0, kind="rough"):
    """A reference surface (n × n posts of POST m): Gaussian relief, a N–S ridge, or a plane."""
    rng = np.random.default_rng(seed)
    if kind == "rough":
        z = ndimage.gaussian_filter(rng.normal(size=(n, n)), 12)
        z = relief * z / z.std()
    elif kind == "ridge":          # heights vary with E only: a ridge running north–south
        e = (np.arange(n) + 0.5) * POST
        z = np.broadcast_to(relief * np.sin(2 * np.pi * e / 2400.0), (n, n)).copy()
    else:
        z = np.zeros((n, n))
    return Surface(z + 500.0, 0.0, n * POST, POST)


def make_cells(surf, theta, *, grid=3, side=24, noise=1.0, sigma_b=(0.0, 0.0, 0.0), offset=(0, 0, 0), seed=0):
    """Cells of ``grid × grid`` patches (``side × side`` reference cells each) over the N image:
    each at its true map position, observed where the ancillary model would put it (moved back
    by the field ``theta``, each patch also by its own random shift ``sigma_b``), its height the
    ground's — the reference is the ground moved by ``−offset`` (E, N) and lowered by its h, its
    own error — minus the field's dh, plus
    correlated noise of σ ``noise``. Returns (Cells, number of patches)."""
    rng = np.random.default_rng(seed)
    parts, P = [], 0
    step = (SIZE * GSD / POST) / grid
    for pr in range(grid):
        for pc in range(grid):
            r0, c0 = int(ORIGIN / POST + pr * step + (step - side) / 2), int(ORIGIN / POST + pc * step + (step - side) / 2)
            rr, cc = np.mgrid[r0:r0 + side, c0:c0 + side]
            E = (cc + 0.5) * POST
            Nn = surf.heights.shape[0] * POST - (rr + 0.5) * POST
            x, y = (E - ORIGIN) / GSD, (surf.heights.shape[0] * POST - ORIGIN - Nn) / GSD
            s = BASIS.predict(theta, x, y) + rng.normal(0, 1, 3) * np.asarray(sigma_b)
            h = surf.sample(E - offset[0], Nn - offset[1])[0] + offset[2]
            eps = ndimage.gaussian_filter(rng.normal(size=E.shape), 0.8)
            eps *= noise / eps.std()
            parts.append(dict(x=x.ravel(), y=y.ravel(), e=(E - s[..., 0]).ravel(), n=(Nn - s[..., 1]).ravel(),
                              h=(h - s[..., 2] + eps).ravel(), patch=P, row=rr.ravel(), col=cc.ravel()))
            P += 1
    return Cells.join(parts), P


THETA = np.array([12.0, 2.0, -1.5, -7.0, 0.5, 1.0, 3.0, -0.8, 0.4])


def test_joint_adjustment_agrees_with_a_brute_force_least_squares():
    """The adjustment (patch shifts eliminated with Σ_b, Gauss–Newton) against scipy's
    least_squares over the field AND every patch's shift at once, with the same weights, the same
    inlier cells, the patch shifts' prior N(0, Σ_b) and the field's prior: the same minimum, and
    the same covariance of the field."""
    surf = terrain()
    cells, P = make_cells(surf, THETA, sigma_b=(0.8, 0.8, 0.3))
    fit = adjust_field(cells, surf, BASIS, np.zeros(9), n_patches=P, prior_sigma=PRIOR)
    assert fit, fit.reason
    S = accumulate(cells, surf, BASIS, fit.theta, fit.offset, P, areas=fit.area)
    inl = S.inlier
    w = 1.0 / (fit.spread ** 2 * fit.area)
    sb = np.maximum(fit.sigma_b, 1e-6)

    def resid(q):
        th, b = q[:9], q[9:].reshape(P, 3)
        s = BASIS.predict(th, cells.x, cells.y) + b[cells.patch]
        r = surf.sample(cells.e + s[:, 0], cells.n + s[:, 1])[0] - cells.h - s[:, 2]
        return np.r_[(np.sqrt(w[cells.patch]) * r)[inl], (b / sb).ravel(), th / PRIOR]

    q0 = np.r_[fit.theta + 0.5, np.zeros(3 * P)]
    bf = least_squares(resid, q0, method="lm", xtol=1e-10, ftol=1e-10)
    J = bf.jac
    cov_bf = np.linalg.inv(J.T @ J)[:9, :9]
    sd = np.sqrt(np.diag(cov_bf))
    # the adjustment's Jacobian takes the reference's central-difference gradients, not the
    # exact derivative of its bilinear surface: the same minimum to a small part of its σ
    assert np.all(np.abs(bf.x[:9] - fit.theta) < 0.15 * sd), (bf.x[:9] - fit.theta) / sd
    assert np.sqrt(np.diag(fit.cov[:9, :9])) == pytest.approx(sd, rel=0.05)
    # and the truth is within the stated σ (a loose check: one draw)
    assert np.all(np.abs(fit.theta - THETA) < 4 * np.sqrt(np.diag(fit.cov[:9, :9])) + 0.05)


def _gcps(theta, xy, sigma, rng, offset=(0.0, 0.0, 0.0)):
    """Direct observations of the field at N positions ``xy`` (n, 2) with noise σ."""
    s = BASIS.predict(theta, xy[:, 0], xy[:, 1]) + rng.normal(0, sigma, (len(xy), 3))
    n = len(xy)
    return FieldObs(np.repeat(xy[:, 0], 3), np.repeat(xy[:, 1], 3), np.tile(np.arange(3), n), s.ravel(),
                    np.full(3 * n, sigma))


def test_gcps_and_dem_cells_together_beat_gcps_alone_at_the_edges():
    """Nine GCPs on an inner grid (the middle third of the scene), 1 m survey noise: alone, their
    error is extrapolated to the scene's edges as a tilt; with the reference DEM's cells in the
    same adjustment the field's shape comes from the cells and its frame from the GCPs — the
    reference's own offset (here 6, −4, 2 m) is estimated, not inherited."""
    surf = terrain(seed=3)
    ref_offset = (6.0, -4.0, 2.0)
    corners = np.array([[0, 0], [SIZE, 0], [0, SIZE], [SIZE, SIZE]], float)
    errs_alone, errs_joint = [], []
    for seed in range(3):
        rng = np.random.default_rng(seed)
        cells, P = make_cells(surf, THETA, grid=4, side=16, sigma_b=(0.5, 0.5, 0.2), offset=ref_offset, seed=seed)
        g = np.linspace(SIZE / 3, 2 * SIZE / 3, 3)
        xy = np.column_stack([np.tile(g, 3), np.repeat(g, 3)])
        obs = _gcps(THETA, xy, 1.0, rng)
        # GCPs alone: the affine field by least squares
        A = BASIS.phi(xy[:, 0], xy[:, 1])
        alone = np.linalg.lstsq(A, obs.value.reshape(-1, 3), rcond=None)[0].T.ravel()
        fit = adjust_field(cells, surf, BASIS, np.zeros(9), n_patches=P, prior_sigma=PRIOR, obs=obs)
        assert fit, fit.reason
        assert fit.offset == pytest.approx(ref_offset, abs=1.0)
        truth = BASIS.predict(THETA, corners[:, 0], corners[:, 1])
        errs_alone.append(BASIS.predict(alone, corners[:, 0], corners[:, 1]) - truth)
        errs_joint.append(fit.field(corners[:, 0], corners[:, 1]) - truth)
        # its stated σ at the corners covers its error there
        sig = fit.sigma(corners[:, 0], corners[:, 1])
        assert np.all(np.abs(errs_joint[-1]) < 4 * sig + 0.1)
    rms = lambda e: float(np.sqrt(np.mean(np.square(np.array(e)[..., :2]))))  # noqa: E731
    assert rms(errs_joint) < 0.5 * rms(errs_alone), (rms(errs_joint), rms(errs_alone))


def test_sigma_of_the_field_covers_its_error():
    """Across draws with each patch off by its own random shift (Σ_b unknown to the adjustment)
    and correlated cell noise, error / stated σ of the field at a lattice over the image has an
    RMS near 1 (0.6–1.6) and no draw beyond 3."""
    surf = terrain(seed=5)
    lx, ly = cond.lattice((SIZE, SIZE), 3)
    ratios = []
    for seed in range(8):
        rng = np.random.default_rng(100 + seed)
        theta = THETA + rng.normal(0, 2, 9)
        cells, P = make_cells(surf, theta, grid=4, side=16, noise=2.0, sigma_b=(1.5, 1.5, 0.5), seed=seed)
        fit = adjust_field(cells, surf, BASIS, np.zeros(9), n_patches=P, prior_sigma=PRIOR)
        assert fit, fit.reason
        err = fit.field(lx, ly) - BASIS.predict(theta, lx, ly)
        ratios.append(err / fit.sigma(lx, ly))
    r = np.array(ratios)
    rms = float(np.sqrt(np.mean(r ** 2)))
    assert 0.6 < rms < 1.6, rms
    assert np.abs(r).max() < 3.5, np.abs(r).max()


def _summary(fit, along=(0.0, 1.0)):
    lx, ly = cond.lattice((SIZE, SIZE))
    return cond.summarise(np.array([fit.cov_at(a, b) for a, b in zip(lx, ly)]), np.array(along))


def test_conditioning_on_a_plane_refuses_with_the_reason():
    """A plane fixes the height only: before the run (the reference's gradients) and after it
    (the adjustment), σ along and across track stays the a-priori σ, the verdict is too_smooth,
    the message says no horizontal shift is fixed, and says what would help."""
    surf = terrain(kind="plane")
    gx, gy = np.zeros(400), np.zeros(400)
    xy = np.random.default_rng(0).uniform(0, SIZE, (400, 2))
    info = cond.information(gx, gy, BASIS.phi(xy[:, 0], xy[:, 1]), 1.0)
    cov = cond.expected_cov(info, PRIOR)
    assert np.sqrt(cov[0, 0]) == pytest.approx(50.0, rel=1e-6) and np.sqrt(cov[6, 6]) < 0.2
    cells, P = make_cells(surf, THETA)
    fit = adjust_field(cells, surf, BASIS, np.zeros(9), n_patches=P, prior_sigma=PRIOR)
    s = _summary(fit)
    assert s.along > 40 and s.across > 40 and s.h < 1.0
    v = cond.judge(s, 5.0, P, 50.0)
    assert v.status == cond.TOO_SMOOTH and v.exit_status == 3
    assert "fixes no shift in both horizontal directions" in v.message and "GCPs" in v.advice
    assert abs(fit.theta[6] - THETA[6]) < 0.5        # the height it does fix


def test_conditioning_on_a_ridge_fixes_the_shift_across_it_only():
    """A ridge running north–south under a north-bound track: the shift across the ridge (east,
    across track) is fixed to decimetres, along it (north, along track) not at all — the
    verdict names that direction; the terrain under a rotated track is judged in its frame."""
    surf = terrain(kind="ridge")
    cells, P = make_cells(surf, THETA)
    fit = adjust_field(cells, surf, BASIS, np.zeros(9), n_patches=P, prior_sigma=PRIOR)
    s = _summary(fit, along=(0.0, 1.0))
    assert s.across < 1.0 and s.along > 40
    assert abs(s.worst_azimuth_deg % 180) < 5 or abs(s.worst_azimuth_deg % 180 - 180) < 5
    v = cond.judge(s, 5.0, P, 50.0)
    assert v.status == cond.TOO_SMOOTH and "along track" in v.message and "across" not in v.message.split(":")[1]
    assert abs(fit.theta[0] - THETA[0]) < 0.5        # dE across the ridge is found
    s2 = _summary(fit, along=(1.0, 0.0))             # an east-bound track: the ridge fixes along
    assert s2.along < 1.0 and s2.across > 40
    # rough terrain: trusted
    rough = terrain()
    cells, P = make_cells(rough, THETA)
    fit = adjust_field(cells, rough, BASIS, np.zeros(9), n_patches=P, prior_sigma=PRIOR)
    assert cond.judge(_summary(fit), 5.0, P, 50.0).ok


def test_the_default_target_is_one_pixel():
    """A field fixed to 4.1 m planimetric (a 10 km scene of 6 % hills: 4.0 m off at the check
    points) is not trusted by default — the target is one PRISM pixel, 2.5 m — and the message
    names the σ and the target; a user who asks for 5 m gets it trusted."""
    s = cond.SigmaSummary(E=2.9, N=2.9, h=1.1, along=3.0, across=2.8, worst=3.1, worst_azimuth_deg=10.0)
    assert cond.TARGET_M == 2.5
    v = cond.judge(s, cond.TARGET_M, 16, 50.0)
    assert v.status == cond.TOO_SMOOTH and v.exit_status == 3
    assert "too smooth in both horizontal directions" in v.message and "the target is 2.5 m" in v.message
    assert "a larger target σ where the use allows it" in v.advice
    assert cond.judge(s, 5.0, 16, 50.0).ok
    # each direction within the target, the two together not: the message still says where
    s2 = cond.SigmaSummary(E=2.0, N=2.0, h=1.1, along=2.0, across=2.0, worst=2.1, worst_azimuth_deg=10.0)
    v2 = cond.judge(s2, cond.TARGET_M, 16, 50.0)
    assert not v2.ok and "too smooth in both horizontal directions together" in v2.message


def test_height_distortion_along_the_track_is_not_taken_for_a_shift():
    """Gentle hills, nearly a plane over a patch, and relative DEMs bent along the track by a
    Legendre quadratic of 0.5 m (F's and B's offsets from N not linear in time): with the
    field's affine dh alone the bend moves the field by most of a metre; with the distortion's
    terms in the adjustment the field is found to a decimetre or two, within its σ, and the
    bend is found too (with the sign of a correction: the heights were raised by it)."""
    rng = np.random.default_rng(3)
    z = ndimage.gaussian_filter(rng.normal(size=(600, 600)), 50, mode="wrap")
    surf = Surface(500.0 + 200.0 * z / z.std(), 0.0, 600 * POST, POST)
    cells, P = make_cells(surf, THETA, grid=4, side=24, noise=0.05, seed=4)
    dist = Distortion((SIZE / 2, SIZE / 2), SIZE / 2, (0.0, 1.0))
    bend = 0.5 * dist.psi(cells.x, cells.y)[:, 0]
    bent = Cells(cells.x, cells.y, cells.e, cells.n, cells.h + bend, cells.patch, cells.row, cells.col)
    lx, ly = cond.lattice((SIZE, SIZE), 3)
    truth = BASIS.predict(THETA, lx, ly)[:, :2]
    old = adjust_field(bent, surf, BASIS, THETA, n_patches=P, prior_sigma=PRIOR)
    new = adjust_field(bent, surf, BASIS, THETA, n_patches=P, prior_sigma=PRIOR, distortion=dist, distortion_sigma=1.4)
    assert old and new, (old.reason, new.reason)
    e_old = np.abs(old.field(lx, ly)[:, :2] - truth)
    e_new = np.abs(new.field(lx, ly)[:, :2] - truth)
    assert e_new.max() < 0.25 and np.all(e_new < 2 * new.sigma(lx, ly)[:, :2]), (e_new.max(), new.sigma(lx, ly))
    assert e_old.max() > 3 * e_new.max(), (e_old.max(), e_new.max())
    assert new.delta[0] == pytest.approx(-0.5, abs=0.05) and abs(new.delta[1]) < 0.05


def test_signal_share_leaves_the_mean_gradient_out():
    """Reference gradients = a plane's slope + relief + the reference's noise, the cells' own =
    the same slope and relief + their noise: ρ is the relief's share of what varies, not of the
    whole gradient (the plane's slope, shared by both, made it near 1)."""
    rng = np.random.default_rng(0)
    n = 4000
    relief = rng.normal(0, 0.01, (n, 2))
    g = 0.05 + relief + rng.normal(0, 0.03, (n, 2))          # SRTM-like noise: 3 × the relief
    o = 0.05 + relief + rng.normal(0, 0.01, (n, 2))
    rho = signal_share(g[:, 0], g[:, 1], o[:, 0], o[:, 1])
    assert rho == pytest.approx(0.01 ** 2 / (0.01 ** 2 + 0.03 ** 2), abs=0.03)
