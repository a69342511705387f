"""The RPC model, its bias, intersection and the bias-compensated adjustment (arrays only;
the RPCs are the real Pléiades triplet's, read through the io layer)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from prismstation.core.models.rpc_adjust import adjust
from prismstation.core.models.rpc_bias import BiasedRpc, bias_design, intersect, metres_per_degree
from prismstation.errors import DegenerateGeometry, ModelError
from prismstation.io.rpc import read_rpc


@pytest.fixture(scope="module")
def triplet(shared_data):
    return [read_rpc(shared_data / "pleiades_triplet" / f"img_0{i}.tif") for i in (1, 2, 3)]


def ground_points(rpc, n, seed, h=(200.0, 600.0)):
    rng = np.random.default_rng(seed)
    x, y, hh = rng.uniform(0, 1024, n), rng.uniform(0, 1024, n), rng.uniform(*h, n)
    lon, lat = rpc.localize(x, y, hh)
    return lon, lat, hh


def observe(models, lon, lat, h, sigma, seed):
    rng = np.random.default_rng(seed)
    n = len(lon)
    P, I, XY = [], [], []
    for k, m in enumerate(models):
        x, y = m.project(lon, lat, h)
        P += list(range(n))
        I += [k] * n
        XY += list(zip(x, y))
    return np.array(P), np.array(I), np.array(XY) + rng.normal(0, sigma, (len(P), 2))


def test_partials_match_finite_differences(triplet):
    rpc = triplet[1]
    lon, lat, h = ground_points(rpc, 50, 0)
    _, _, J = rpc.project_with_partials(lon, lat, h)
    for k, e in enumerate((1e-7, 1e-7, 1e-3)):
        d = np.zeros(3)
        d[k] = e
        a = np.array(rpc.project(lon + d[0], lat + d[1], h + d[2]))
        b = np.array(rpc.project(lon - d[0], lat - d[1], h - d[2]))
        fd = ((a - b) / (2 * e)).T
        assert np.allclose(fd, J[:, :, k], rtol=1e-6, atol=1e-6 * np.abs(J[:, :, k]).max())
    # with a bias: J = (I − ∂Δ/∂xy)⁻¹ J_rpc, also against differences
    m = BiasedRpc(rpc, "affine", [2.0, 3.0, -1.0, -4.0, 0.5, 2.0], 512, 512)
    _, _, Jb = m.project_with_partials(lon, lat, h)
    a = np.array(m.project(lon, lat, h + 1e-3))
    b = np.array(m.project(lon, lat, h - 1e-3))
    assert np.allclose(((a - b) / 2e-3).T, Jb[:, :, 2], rtol=1e-6)


def test_localize_inverts_project_and_reports_failure(triplet):
    rpc = triplet[0]
    lon, lat, h = ground_points(rpc, 200, 1)
    x, y = rpc.project(lon, lat, h)
    lo, la = rpc.localize(x, y, h)
    bx, by = rpc.project(lo, la, h)
    assert np.abs(bx - x).max() < 1e-6 and np.abs(by - y).max() < 1e-6
    # the pixel convention: the RPC's (SAMP_OFF, LINE_OFF) is a pixel centre
    cx, cy = rpc.project(rpc.lon_off, rpc.lat_off, rpc.h_off)
    n = rpc.samp_num[0] / rpc.samp_den[0] * rpc.samp_scale + rpc.samp_off
    assert cx == pytest.approx(n + 0.5)
    with pytest.raises(ModelError, match="did not converge"):
        rpc.localize(np.array([1e12, 10.0]), np.array([1e12, 10.0]), 300.0, max_iter=5)
    lo, la, ok = rpc.localize_masked(np.array([1e12, 10.0]), np.array([1e12, 10.0]), 300.0, max_iter=5)
    assert ok.tolist() == [False, True] and np.isnan(lo[0]) and np.isfinite(lo[1])


def test_bias_models_and_biased_projection(triplet):
    D = bias_design("shift_drift", np.array([100.0, 2100.0]), np.array([500.0, 3500.0]), 100, 500)
    # Δx = a0, Δy = b0 + b2·(y − y0)/1000
    assert D[1].tolist() == [[1, 0, 0], [0, 1, 3.0]] and D[0].tolist() == [[1, 0, 0], [0, 1, 0]]
    m = BiasedRpc(triplet[0], "affine", [2.0, 3.0, -1.0, -4.0, 0.5, 2.0], 512, 512)
    lon, lat, h = ground_points(triplet[0], 20, 2)
    x, y = m.project(lon, lat, h)
    xr, yr = triplet[0].project(lon, lat, h)
    d = m.bias_at(x, y)       # the bias at the (biased) image point reproduces it exactly
    assert np.allclose(x - d[:, 0], xr, atol=1e-9) and np.allclose(y - d[:, 1], yr, atol=1e-9)
    lo, la = m.localize(x, y, h)
    assert np.allclose(lo, lon, atol=1e-10) and np.allclose(la, lat, atol=1e-10)
    with pytest.raises(ModelError, match="takes 2 parameters"):
        BiasedRpc(triplet[0], "shift", [1.0])


def test_intersection_and_its_covariance(triplet):
    """Three rays with 0.3 px noise: the spread of the intersected points over many draws
    matches the stated covariance."""
    lon, lat, h = ground_points(triplet[0], 1, 3)
    errs, covs = [], []
    rng = np.random.default_rng(4)
    for _ in range(300):
        xy = np.array([m.project(lon, lat, h) for m in triplet])[:, :, 0]
        r = intersect(triplet, xy + rng.normal(0, 0.3, xy.shape), 0.3)
        ke, kn = metres_per_degree(lat, h)
        errs.append([(r.lon[0] - lon[0]) * ke[0], (r.lat[0] - lat[0]) * kn[0], r.h[0] - h[0]])
        covs.append(r.cov[0])
    errs = np.array(errs)
    ratio = errs.std(0) / np.sqrt(np.diag(np.mean(covs, 0)))
    assert np.all((ratio > 0.85) & (ratio < 1.15)), ratio
    with pytest.raises(ModelError, match="fewer than 2 images"):
        intersect(triplet[:1], xy[:1], 0.3)


def brute_force(rpcs, kinds, fixed, P, I, XY, sigma, gcp, gcp_llh, gcp_sig, hp, hv, hs, start):
    """The same problem written plainly and solved by scipy's least_squares."""
    ni, n = len(rpcs), int(P.max()) + 1
    npar = [0 if k in fixed else {"shift": 2, "shift_drift": 3, "affine": 6}[kinds[k]]
            for k in range(ni)]
    cs = np.cumsum([0] + npar)

    def res(z):
        b, g = z[:cs[-1]], z[cs[-1]:].reshape(n, 3)
        out = []
        for k in range(ni):
            sel = I == k
            m = BiasedRpc(rpcs[k], "none" if k in fixed else kinds[k],
                          None if k in fixed else b[cs[k]:cs[k + 1]], 512, 512)
            d = m.bias_at(XY[sel, 0], XY[sel, 1])
            x, y = rpcs[k].project(g[P[sel], 0], g[P[sel], 1], g[P[sel], 2])
            out += [(XY[sel, 0] - d[:, 0] - x) / sigma, (XY[sel, 1] - d[:, 1] - y) / sigma]
        ke, kn = metres_per_degree(g[gcp, 1], g[gcp, 2])
        out += [(gcp_llh[:, 0] - g[gcp, 0]) * ke / gcp_sig, (gcp_llh[:, 1] - g[gcp, 1]) * kn / gcp_sig,
                (gcp_llh[:, 2] - g[gcp, 2]) / gcp_sig, (hv - g[hp, 2]) / hs]
        return np.concatenate(out)

    z = least_squares(res, np.concatenate([np.zeros(cs[-1]), start.ravel()]), x_scale="jac",
                      xtol=1e-15, ftol=1e-15, gtol=1e-15, method="lm").x
    return [z[cs[k]:cs[k + 1]] for k in range(ni)], z[cs[-1]:].reshape(n, 3)


@pytest.mark.parametrize("kinds, fixed, n_gcp", [(["shift", "shift_drift", "affine"], (), 6),
                                                  (["none", "affine", "shift"], (0,), 0)])
def test_adjustment_equals_brute_force_least_squares(triplet, kinds, fixed, n_gcp):
    lon, lat, h = ground_points(triplet[0], 25, 5)
    true = [BiasedRpc(triplet[0], "shift", [1.5, -2.0], 512, 512),
            BiasedRpc(triplet[1], "affine", [3.0, 0.5, -0.3, -20.0, 0.2, 0.4], 512, 512),
            BiasedRpc(triplet[2], "shift", [-7.0, 12.0], 512, 512)]
    P, I, XY = observe(true, lon, lat, h, 0.3, 6)
    gcp = np.arange(n_gcp)
    gcp_llh = np.column_stack([lon, lat, h])[gcp]
    hp = np.arange(10, 25)                  # a reference DEM's heights, 3 m off
    hv = h[hp] + np.random.default_rng(7).normal(0, 3.0, hp.size)
    res = adjust(triplet, P, I, XY, 0.3, bias=kinds, fixed=fixed, gcp_point=gcp, gcp_llh=gcp_llh,
                 gcp_sigma=0.2, height_point=hp, height=hv, height_sigma=3.0,
                 centres=[(512, 512)] * 3)
    start = np.column_stack([lon, lat, h]) + 1e-5
    b, g = brute_force(triplet, kinds, fixed, P, I, XY, 0.3, gcp, gcp_llh, 0.2, hp, hv, 3.0, start)
    for k in range(3):
        assert np.allclose(res.models[k].params, b[k], atol=1e-5), (k, res.models[k].params, b[k])
    ke, kn = metres_per_degree(g[:, 1], g[:, 2])
    assert np.abs((res.lon - g[:, 0]) * ke).max() < 1e-4
    assert np.abs((res.lat - g[:, 1]) * kn).max() < 1e-4 and np.abs(res.h - g[:, 2]).max() < 1e-4
    assert res.dof == 2 * len(P) + 3 * n_gcp + hp.size - 3 * 25 - sum(
        0 if k in fixed else {"none": 0, "shift": 2, "shift_drift": 3, "affine": 6}[kinds[k]]
        for k in range(3))
    assert 0.6 < res.sigma0 < 1.4


def test_known_biases_recovered_with_honest_sigma(triplet):
    """Simulated triplet, affine biases on all three images, 8 GCPs (surveyed to 0.05 m) among
    60 tie points at 0.3 px: over 40 noise draws each bias parameter's error is consistent with
    its formal σ (RMS of the standardised errors within [0.75, 1.3])."""
    lon, lat, h = ground_points(triplet[0], 60, 8)
    tb = [[1.0, -0.2, 0.3, 2.0, 0.1, -0.1], [3.0, 0.5, -0.3, -20.0, 0.2, 0.4],
          [-7.0, 0.0, 0.1, 12.0, -0.3, 0.0]]
    true = [BiasedRpc(triplet[k], "affine", tb[k], 512, 512) for k in range(3)]
    g = np.arange(8)
    z = []
    for seed in range(40):
        P, I, XY = observe(true, lon, lat, h, 0.3, 100 + seed)
        rng = np.random.default_rng(500 + seed)
        ke, kn = metres_per_degree(lat[g], h[g])
        survey = np.column_stack([lon[g] + rng.normal(0, 0.05, 8) / ke,
                                  lat[g] + rng.normal(0, 0.05, 8) / kn, h[g] + rng.normal(0, 0.05, 8)])
        res = adjust(triplet, P, I, XY, 0.3, bias="affine", gcp_point=g, gcp_llh=survey,
                     gcp_sigma=0.05,
                     centres=[(512, 512)] * 3)
        z.append(np.concatenate([(res.models[k].params - tb[k]) / res.bias_std(k) for k in range(3)]))
        assert res.redundancy.sum() <= res.dof + 1e-9
    rms = np.sqrt(np.mean(np.square(z), axis=0))
    print("RMS of (recovered − true) / σ per bias parameter:", np.round(rms, 2))
    assert np.all((rms > 0.75) & (rms < 1.3)), rms


def test_blunder_stands_out_and_datum_defect_is_refused(triplet):
    lon, lat, h = ground_points(triplet[0], 30, 9)
    P, I, XY = observe(triplet, lon, lat, h, 0.3, 10)
    # a 13 σ blunder across the epipolar direction (x: the triplet is along-track stereo, so
    # along it, y, the heights absorb part of a blunder and the third ray shares it)
    XY[5, 0] += 4.0
    res = adjust(triplet, P, I, XY, 0.3, bias="shift")
    assert res.fixed == (0,)
    assert np.nanargmax(np.abs(res.std_residuals).max(1)) == 5
    assert np.abs(res.std_residuals[5, 0]) > 5
    with pytest.raises(DegenerateGeometry, match="not determined"):
        adjust(triplet, P, I, XY, 0.3, bias="affine", fixed=())


def test_longitudes_across_the_antimeridian(triplet):
    """An image across ±180°: its RPC's LONG_OFF at 179.95°, ground points given between
    −180° and −179.9° (as any CRS transformation returns them). The same RPC with LONG_OFF
    at −180.05° sees those points without wrapping: both must give the same pixels, and image
    → ground must come back within −180…180° and re-project."""
    from dataclasses import replace
    east = replace(triplet[0], lon_off=179.95, lon_scale=0.12)
    west = replace(east, lon_off=179.95 - 360.0)
    rng = np.random.default_rng(5)
    lon = rng.uniform(-179.99, -179.9, 200)
    lat = east.lat_off + rng.uniform(-0.5, 0.5, 200) * east.lat_scale
    h = east.h_off + rng.uniform(-0.5, 0.5, 200) * east.h_scale
    np.testing.assert_allclose(np.column_stack(east.project(lon, lat, h)),
                               np.column_stack(west.project(lon, lat, h)), atol=1e-6, rtol=0)
    x, y, J = east.project_with_partials(lon, lat, h)
    np.testing.assert_allclose(J, west.project_with_partials(lon, lat, h)[2], rtol=1e-9)
    back_lon, back_lat = east.localize(x, y, h)
    assert np.all(back_lon <= 180.0) and np.all(back_lon >= -180.0)
    np.testing.assert_allclose(back_lon, lon, atol=1e-9)
    on_the_east = rng.uniform(179.9, 180.0, 50)     # the image's other half: no turn
    np.testing.assert_allclose(np.column_stack(east.project(on_the_east, lat[:50], h[:50])),
                               np.column_stack(west.project(on_the_east - 360.0, lat[:50], h[:50])),
                               atol=1e-6, rtol=0)
