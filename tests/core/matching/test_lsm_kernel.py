"""The compiled loops of least-squares matching: outside points and NaN positions are refused,
never read past the window, and the types compile_kernels prepares are the ones matching uses."""
import numpy as np
import pytest
from scipy import ndimage

from prismstation.core.matching import lsm_kernel as K
from prismstation.core.matching.lsm import refine
from prismstation.core.matching.lsm_fit import Fit
from prismstation.core.matching.lsm_sampled import POINT_SAMPLED
from prismstation.core.matching.lsm_spline import Spline


def _spline():
    rng = np.random.default_rng(5)
    return Spline(ndimage.gaussian_filter(rng.normal(100, 30, (30, 40)), 1.0), c0=10, r0=20)


def test_points_outside_the_window_or_nan_give_nan():
    sp = _spline()
    x = np.array([30.0, sp.lo[0] - 0.01, sp.hi[0] + 0.01, np.nan, 30.0, 1e300])
    y = np.array([35.0, 35.0, 35.0, 35.0, np.nan, 35.0])
    s, sx, sy = sp.sample(x, y)
    assert np.isfinite([s[0], sx[0], sy[0]]).all()
    assert np.isnan(s[1:]).all() and np.isnan(sx[1:]).all() and np.isnan(sy[1:]).all()


def test_a_patch_with_a_nan_position_or_beyond_the_window_is_outside():
    sp = _spline()
    k = np.arange(-3, 4.0)
    v, u = np.meshgrid(k, k, indexing="ij")
    fit = Fit(np.ones((7, 7)) + u, u, v, sp, np.array([1.0, 0.0]), 3)
    fit.A = np.eye(2)
    for t in ([30.0, 35.0], [np.nan, 35.0], [30.0, np.inf], [sp.hi[0] - 1.0, 35.0]):
        fit.t, fit.smp = np.array(t), None
        assert (fit.sample() is None) == (t != [30.0, 35.0]), t


def test_the_prepared_types_are_the_ones_a_match_uses():
    # a match of point-sampled texture takes every path (the coarse pass, the bend, the taper,
    # the central part, the low-passed fit): none of them may compile another signature
    K.compile_kernels()
    kernels = (K.sample_points, K.sample_patch, K.design_rows, K.normals, K.solve_small, K.gauss_newton,
               K.block_moments, K.edge_sums, K.spline_coefficients, K.crossing_sigma)
    before = [len(f.signatures) for f in kernels]
    rng = np.random.default_rng(2)
    img = np.kron(rng.normal(100, 30, (60, 60)), np.ones((4, 4)))        # hard edges, no blur
    shifted = ndimage.shift(img, (0.3, 0.45), order=1)
    r = refine(img, 120.2, 119.7, shifted, [120.6, 120.1], np.eye(2), parallax=(1.0, 0.1), half=24)
    assert r.ok, r.reason
    assert r.extra["edges"] > POINT_SAMPLED and r.extra["smoothed"].any()
    assert [len(f.signatures) for f in kernels] == before


def test_the_edge_scatter_is_the_block_sums_of_the_weighted_design():
    # sampling_scatter against its definition: Σ over 8 × 8 blocks (the last ones partial) of
    # the design rows times gradient × σ, their outer products summed
    from prismstation.core.matching.lsm_sigma import sampling_scatter
    rng = np.random.default_rng(7)
    n, k, b = 29, 5, 8
    J, gx, gy = rng.normal(size=(n, n, k)), rng.normal(size=(n, n)), rng.normal(size=(n, n))
    ex, ey = rng.random((n, n)), rng.random((n, n))
    want = np.zeros((k, k))
    for i in range(0, n, b):
        for j in range(0, n, b):
            blk = (slice(i, i + b), slice(j, j + b))
            cx = (J[blk] * (gx * ex)[blk][..., None]).sum(axis=(0, 1))
            cy = (J[blk] * (gy * ey)[blk][..., None]).sum(axis=(0, 1))
            want += np.outer(cx, cx) + np.outer(cy, cy)
    assert np.allclose(sampling_scatter(J, gx, gy, ex, ey, b), want, rtol=1e-12, atol=1e-12)


def test_the_spline_coefficients_are_scipys():
    rng = np.random.default_rng(8)
    for shape in ((1, 1), (1, 6), (5, 1), (2, 2), (2, 9), (7, 3), (85, 87)):
        img = rng.normal(100, 30, shape)
        want = ndimage.spline_filter(img, order=3, mode="mirror")
        assert np.allclose(K.spline_coefficients(img), want, rtol=0, atol=1e-12 * np.abs(want).max())


def _sampling_px_by_arrays(a, noise):
    """sampling_px as array operations (its definition, written out once more)."""
    from prismstation.core.matching.lsm_sigma import _SAMPLING_PX, _SAMPLING_RATIO
    v = 2.0 * noise ** 2
    out = []
    for arr in (a, a.T):
        d = np.diff(arr, axis=1)
        d0 = d[:, 2:-2] ** 2
        side = np.maximum(d[:, :-4] ** 2 + d[:, 1:-3] ** 2 + d[:, 3:-1] ** 2 + d[:, 4:] ** 2 - 4 * v, 0.0)
        ratio = np.where(d0 > 4 * v, side / np.maximum(d0 - v, 1e-12), np.inf)
        e = np.zeros_like(d)
        e[:, 2:-2] = np.interp(ratio, _SAMPLING_RATIO, _SAMPLING_PX, right=0.0)
        px = np.zeros_like(arr)
        for k in range(-1, 3):
            lo, hi = max(k, 0), min(arr.shape[1] - 1 + k, arr.shape[1])
            px[:, lo:hi] = np.maximum(px[:, lo:hi], e[:, lo - k:hi - k])
        out.append(px)
    return out[0], out[1].T


def test_the_edges_sigma_is_its_definition():
    from prismstation.core.matching.lsm_sigma import sampling_px
    rng = np.random.default_rng(9)
    for trial in range(40):
        n = int(rng.integers(6, 50))
        blocks = np.kron(rng.normal(100, 30, (n // 4 + 2, n // 4 + 2)), np.ones((4, 4)))[:n, :n]
        a = [blocks, ndimage.gaussian_filter(rng.normal(100, 30, (n, n)), rng.uniform(0.2, 1.5)),
             rng.normal(100, 30, (n, n))][trial % 3] + rng.normal(0, 2, (n, n))
        noise = float(rng.uniform(0, 5))
        for got, want in zip(sampling_px(a, noise), _sampling_px_by_arrays(a, noise)):
            assert np.allclose(got, want, rtol=0, atol=1e-12)


def test_the_loops_are_prepared_once_and_the_collector_left_what_was_alive(monkeypatch):
    import gc
    monkeypatch.setattr(K, "_READY", False)
    gc.unfreeze()
    K.compile_kernels()
    frozen = gc.get_freeze_count()
    assert frozen > 10_000 and K._READY
    K.compile_kernels()                      # at once: nothing loaded or frozen again
    assert gc.get_freeze_count() == frozen


def test_the_small_solver_is_lapacks_and_says_when_a_matrix_is_singular():
    rng = np.random.default_rng(3)
    for k in (8, 11):
        J = rng.normal(size=(k, 200))
        N, b, x = J @ J.T, rng.normal(size=k), np.empty(k)
        assert K.solve_small(N, b, x)
        assert np.allclose(x, np.linalg.solve(N, b), rtol=1e-10, atol=1e-12)
    assert not K.solve_small(np.zeros((3, 3)), np.ones(3), np.empty(3))
    assert not K.solve_small(np.array([[1.0, 1.0], [0.0, 0.0]]), np.ones(2), np.empty(2))    # a zero row


@pytest.mark.parametrize("shape", [(61, 61), (60, 62), (1,), (2,), (4095,)])
def test_the_noise_median_is_numpys(shape):
    from prismstation.core.matching.lsm_sigma import _median
    a = np.abs(np.random.default_rng(sum(shape)).normal(size=shape))
    assert _median(a) == float(np.median(a))
