"""core/surfaces/ortho: the cells' image positions from the lattice hold the model to its tolerance
wherever the model bends (in plan and in height), and the kernels move nothing."""
import numpy as np
import pytest

from prismstation.core.surfaces import ortho

T = (2.5, 0.0, 500000.0, 0.0, -2.5, 4600000.0)


def _exact(g2i, transform, heights):
    rows, cols = heights.shape
    a, _, c, _, e, f = transform
    X, Y = np.meshgrid(c + a * (np.arange(cols) + 0.5), f + e * (np.arange(rows) + 0.5))
    return np.asarray(g2i(np.stack([X, Y], axis=-1), heights), float)


def _pushbroom(curv_h=0.0, curv_plan=0.0):
    """A smooth ground → image map: rotated, scaled, with a relief shift (tan 0.5 / 2.5 m) bent in
    height by ``curv_h`` (px per m³ about 800 m) and in plan by ``curv_plan`` (px per m²)."""
    def g2i(en, h):
        E = np.asarray(en, float)[..., 0] - 500000.0
        N = np.asarray(en, float)[..., 1] - 4600000.0
        h = np.asarray(h, float)
        x = 0.39 * E + 0.08 * N + 0.01 * h + curv_plan * E * E + 3.0
        y = 0.08 * E - 0.39 * N + 0.2 * h + curv_h * (h - 800.0) ** 3 + curv_plan * N * E
        return np.stack([x, y], axis=-1)
    return g2i


@pytest.mark.parametrize("curv_h, curv_plan", [(0.0, 0.0), (1e-8, 0.0), (0.0, 3e-5), (1e-8, 3e-5)])
def test_positions_hold_the_model_to_the_tolerance(curv_h, curv_plan):
    g2i = _pushbroom(curv_h, curv_plan)
    rng = np.random.default_rng(1)
    heights = rng.uniform(100.0, 1500.0, (300, 260)).astype(np.float32)
    lat = ortho.fit_lattice(g2i, T, heights.shape, float(heights.min()), float(heights.max()))
    assert lat.max_error_px <= ortho.TOLERANCE_PX
    mx, my = ortho.positions(lat, heights, origin=(-40.0, 20.0))
    exact = _exact(g2i, T, heights)
    # array indices of a window whose corner is image pixel (-40, 20): x = index + 0.5 + origin
    err = np.hypot(mx + 0.5 - 40.0 - exact[..., 0], my + 0.5 + 20.0 - exact[..., 1])
    assert err.max() <= ortho.TOLERANCE_PX + 2e-4          # float32 maps
    if curv_h:
        assert lat.levels > ortho.LEVELS                    # the height's bend needed more heights
    if curv_plan:
        assert lat.step < ortho.STEP                        # the plan's bend a finer lattice


def test_a_reduced_window_scales_the_positions():
    g2i = _pushbroom()
    heights = np.full((64, 64), 300.0, np.float32)
    lat = ortho.fit_lattice(g2i, T, heights.shape, 300.0, 300.0)
    mx, my = ortho.positions(lat, heights, origin=(10.0, -6.0), factor=2.0)
    exact = _exact(g2i, T, heights)
    # element [r, c] of a window reduced by 2 is centred at image (10 + 2(c + 0.5), −6 + 2(r + 0.5))
    assert np.abs(10.0 + 2 * (mx + 0.5) - exact[..., 0]).max() < 1e-3
    assert np.abs(-6.0 + 2 * (my + 0.5) - exact[..., 1]).max() < 1e-3


def test_nan_heights_give_nan_positions_and_values():
    g2i = _pushbroom()
    heights = np.full((40, 40), 200.0, np.float32)
    heights[10:15, 20:30] = np.nan
    lat = ortho.fit_lattice(g2i, T, heights.shape, 200.0, 200.0)
    mx, my = ortho.positions(lat, heights, origin=(-200.0, -200.0))
    img = np.ones((600, 600), np.float32)
    for kernel in ortho.RESAMPLINGS:
        v = ortho.resample(img, mx, my, kernel)
        assert np.isnan(v[10:15, 20:30]).all() and np.isfinite(v[:10]).all()


@pytest.mark.parametrize("kernel", ortho.RESAMPLINGS)
def test_kernels_reproduce_a_ramp_so_they_move_nothing(kernel):
    """Bilinear and cubic convolution (a = −0.5) give a linear image back at any position (cubic a
    parabola too): a resampled edge stays where the position says. OpenCV's own cubic (a = −0.75)
    moves a ramp by up to 0.05 px."""
    yy, xx = np.mgrid[0:80, 0:90].astype(np.float32)
    rng = np.random.default_rng(0)
    mx = rng.uniform(3, 85, (40, 40)).astype(np.float32)
    my = rng.uniform(3, 75, (40, 40)).astype(np.float32)
    v = ortho.resample(3.0 * xx - 2.0 * yy + 7.0, mx, my, kernel)
    assert np.abs(v - (3.0 * mx - 2.0 * my + 7.0)).max() < 2e-3   # float32 at ~250
    if kernel == "cubic":
        q = ortho.resample(0.05 * xx * xx - 0.03 * xx * yy, mx, my, kernel)
        assert np.abs(q - (0.05 * mx * mx - 0.03 * mx * my)).max() < 1e-3


def test_kernels_leave_no_value_where_they_reach_outside():
    img = np.ones((20, 20), np.float32)
    # array indices: pixel centres at integers, the last column's at 19
    mx = np.array([[-0.1, 0.2, 9.0, 18.4, 19.2]], np.float32)
    my = np.full_like(mx, 9.5)
    b = ortho.resample(img, mx, my, "bilinear")
    c = ortho.resample(img, mx, my, "cubic")
    assert np.isnan(b[0, [0, 4]]).all() and (b[0, 1:4] == 1).all()
    assert np.isnan(c[0, [0, 1, 3, 4]]).all() and c[0, 2] == pytest.approx(1.0)
    with pytest.raises(ValueError):
        ortho.resample(img, mx, my, "lanczos")
