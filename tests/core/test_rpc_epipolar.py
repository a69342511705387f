"""Local epipolar rectification of an RPC pair and triangulation through the RPCs, checked
against the exact correspondences and the multi-ray intersection of the same RPCs."""
from __future__ import annotations

import numpy as np
import pytest

from prismstation.core.models.rpc_bias import BiasedRpc, intersect_points
from prismstation.core.surfaces.rpc_epipolar import (apply_affine, correspondences, grid_heights,
                                            ray_lattice, rectify_pair, triangulate)
from prismstation.errors import ModelError
from prismstation.io.rpc_scene import to_map, utm_crs
from tests.ops.rpc_synth import make_rpc

LON0, LAT0 = 5.27, 44.17


@pytest.fixture(scope="module")
def pair():
    # forward and backward views, B/H 0.3, cubic RPCs with a non-constant denominator
    return (make_rpc(LON0, LAT0, gsd=2.0, size=500, tan_along=0.15, seed=1),
            make_rpc(LON0, LAT0, gsd=2.0, size=500, tan_along=-0.15, tan_across=0.08, seed=2))


@pytest.mark.parametrize("window", [(0, 0, 256, 256), (200, 120, 300, 200)])
def test_rectified_rows_agree(pair, window):
    a, b = pair
    rect = rectify_pair(a, b, window, (200.0, 700.0))
    # exact RPC correspondences at heights inside and outside the three the fit used
    pa, pb, h = correspondences(a, b, window, (250.0, 430.0, 610.0), n=9)
    xa, ya = apply_affine(rect.left, pa[:, 0], pa[:, 1])
    xb, yb = apply_affine(rect.right, pb[:, 0], pb[:, 1])
    assert np.abs(ya - yb).max() <= rect.epipolar_error_px + 0.01
    assert rect.epipolar_error_px < 0.1
    d = xa - xb
    # disparity grows with height, at the stated rate, inside the stated range
    slope = np.polyfit(h, d, 1)[0]
    assert slope > 0 and slope == pytest.approx(rect.px_per_m, rel=0.05)
    assert rect.disparity[0] < d.min() and d.max() < rect.disparity[1]
    lo, n = rect.search
    assert lo <= rect.disparity[0] - 1 and lo + n >= rect.disparity[1] + 2 and n % 16 == 0
    # the rectified grid holds the whole window (corners inside)
    cx, cy = apply_affine(rect.left, np.array([window[0], window[0] + window[2]]),
                          np.array([window[1], window[1] + window[3]]))
    assert (cx >= 0).all() and (cy >= 0).all() and (cx <= rect.shape[1]).all() and (cy <= rect.shape[0]).all()


def test_triangulation_is_the_rpc_intersection(pair):
    """Heights and ground of disparities through the lattice agree with the rigorous
    two-ray intersection of the same biased RPCs to millimetres."""
    a = BiasedRpc(pair[0], "shift", np.array([0.4, -1.3]), 250.0, 250.0)
    b = BiasedRpc(pair[1], "affine", np.array([-0.7, 0.2, 0.1, 2.1, -0.3, 0.05]), 250.0, 250.0)
    rect = rectify_pair(a, b, (100, 100, 300, 300), (250.0, 650.0))
    crs = utm_crs(LON0, LAT0)
    fw = to_map(crs)
    lattice = ray_lattice(a, b, rect, fw)
    rng = np.random.default_rng(0)
    disparity = np.full(rect.shape, np.nan, np.float32)
    ii = rng.integers(40, rect.shape[1] - 40, 200)
    jj = rng.integers(10, rect.shape[0] - 10, 200)
    # disparities of true ground points at random heights (beyond the range's ends too)
    xa, ya = apply_affine(rect.inverse("left"), ii + 0.5, jj + 0.5)
    htrue = rng.uniform(200.0, 700.0, 200)
    lon, lat = a.localize(xa, ya, htrue)
    xb, yb = b.project(lon, lat, htrue)
    xbr, _ = apply_affine(rect.right, xb, yb)
    disparity[jj, ii] = (ii + 0.5 - xbr).astype(np.float32)
    tri = triangulate(rect, lattice, disparity)
    h = tri.h[jj, ii]
    assert np.isfinite(h).all()
    # float32 disparities of ~100 px carry ~1e-5 px: millimetres of height
    assert np.abs(h - htrue).max() < 0.01
    # the rigorous intersection of the two image points
    xbi, ybi = apply_affine(rect.inverse("right"), ii + 0.5 - disparity[jj, ii], jj + 0.5)
    k = len(ii)
    obs = np.empty((2 * k, 2))
    obs[0::2] = np.column_stack([xa, ya])
    obs[1::2] = np.column_stack([xbi, ybi])
    inter = intersect_points([a, b], np.repeat(np.arange(k), 2), np.tile([0, 1], k), obs, 0.3, k)
    assert np.abs(h - inter.h).max() < 0.01
    # ground: on the left ray at the height (to a centimetre); the two-ray intersection
    # parts the across-epipolar residual between both rays (≤ the rectification's error)
    e, n = fw(lon, lat)
    assert np.hypot(tri.e[jj, ii] - e, tri.n[jj, ii] - n).max() < 0.01
    e, n = fw(inter.lon, inter.lat)
    assert np.hypot(tri.e[jj, ii] - e, tri.n[jj, ii] - n).max() < 2.0 * rect.epipolar_error_px + 0.01
    # σ of the height per pixel of disparity: 1 / the pair's parallax rate
    assert np.nanmedian(tri.m_per_px) == pytest.approx(1.0 / rect.px_per_m, rel=0.05)


def test_no_stereo_is_refused(pair):
    with pytest.raises(ModelError, match="stereo"):
        rectify_pair(pair[0], pair[0], (0, 0, 200, 200), (200.0, 700.0))
    with pytest.raises(ModelError, match="empty"):
        rectify_pair(pair[0], pair[1], (0, 0, 200, 200), (500.0, 500.0))


def test_grid_heights_bins_means():
    e = np.array([0.5, 0.7, 1.5, 2.5, np.nan, 9.0])
    n = np.array([-0.5, -0.2, -0.5, -1.5, -0.5, -0.5])
    h = np.array([10.0, 12.0, 20.0, 30.0, 5.0, 7.0])
    mean, cnt, extra = grid_heights(e, n, h, (1.0, 0.0, 0.0, 0.0, -1.0, 0.0), (2, 3), extra=2 * h)
    assert cnt.tolist() == [[2, 1, 0], [0, 0, 1]]
    assert mean[0, 0] == 11.0 and mean[0, 1] == 20.0 and mean[1, 2] == 30.0 and np.isnan(mean[1, 0])
    assert extra[0, 0] == 22.0


def test_grid_heights_spreads_points_over_their_neighbourhood():
    """Points about as dense as the cells (a lattice of one cell turned by 30°, jittered, as
    relief scatters an image's pixels on the ground) leave cells empty when each counts in its
    own; spread with a Gaussian of half a cell, every
    inner cell holds a height, the mean of its neighbourhood's (a constant stays exact), and
    a cell no point comes within a cell of stays empty."""
    rng = np.random.default_rng(0)
    i, j = np.mgrid[-60:120, -60:120].astype(float)
    c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
    e = (c * i - s * j + rng.uniform(-0.3, 0.3, i.shape)).ravel()
    n = -(s * i + c * j + rng.uniform(-0.3, 0.3, i.shape)).ravel()
    h = np.full(e.size, 42.0)
    t = (1.0, 0.0, 0.0, 0.0, -1.0, 0.0)
    plain, cnt0, _ = grid_heights(e, n, h, t, (60, 60))
    spread, cnt, _ = grid_heights(e, n, h, t, (60, 60), sigma_cells=0.5)
    inner = (slice(2, -2), slice(2, -2))
    assert np.isnan(plain[inner]).mean() > 0.05
    assert np.isfinite(spread[inner]).all() and np.allclose(spread[inner], 42.0)
    assert cnt[inner].min() >= 1.0 and cnt[inner].mean() > 2 * cnt0[inner].mean()
    far, _, _ = grid_heights(np.array([0.5]), np.array([-0.5]), np.array([1.0]), t, (4, 4), sigma_cells=0.5)
    assert np.isfinite(far).tolist()[:2] == [[True, True, False, False], [True, False, False, False]]
    assert np.isnan(far[2:]).all()
