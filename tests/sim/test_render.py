"""Rendering agrees with the point geometry; terrain statistics are believable."""
import numpy as np
import pytest

from prismstation.sim import geometry as geo
from prismstation.sim.render import render_rows
from prismstation.sim.scenario import CENTRE, GEOID, build_scenario
from prismstation.sim.terrain import Grid, hillshade, synthesize_relief


@pytest.mark.parametrize("north_up", [False, True])
def test_rendered_marker_lands_at_computed_image_coordinates(north_up):
    """A bright spot painted on the ground at a terrain point appears, in every view, where
    ``image_coords`` (Newton on the true ray) puts that point: within 0.1 px."""
    size = 512
    sc = build_scenario(np.random.default_rng(3), size, north_up=north_up)
    e0, n0 = CENTRE[0] - 1000.0, CENTRE[1] + 1000.0
    ortho = synthesize_relief((400, 400), 5.0, np.random.default_rng(8), relief=300.0)
    dem = Grid(ortho + GEOID, e0, n0, 5.0)
    for target in ([200.0, 230.0], [330.0, 300.0]):
        e, n = geo.image_to_map(sc.views["N"], np.array(target))
        h = float(dem.sample(np.array([e]), np.array([n]))[0])
        # texture: 1 m grid, Gaussian spot of σ = 4 m at (e, n)
        ee = e0 + (np.arange(2000) + 0.5)
        nn = n0 - (np.arange(2000) + 0.5)
        spot = 200.0 * np.exp(-((ee[None, :] - e) ** 2 + (nn[:, None] - n) ** 2) / 32.0)
        texture = Grid(spot.astype(np.float32), e0, n0, 1.0)
        for view in sc.views.values():
            x, y = geo.image_coords(sc.orbit, view, np.array([e, n, h]))
            r0, c0 = int(y) - 10, int(x) - 10
            img = render_rows(sc.orbit, view, size, r0, r0 + 21, dem, texture, GEOID - 1,
                              GEOID + 301, psf_sigma=0.0, rng=None)[:, c0:c0 + 21]
            w = img.astype(float)
            cy = (w.sum(axis=1) @ (np.arange(21) + 0.5 + r0)) / w.sum()
            cx = (w.sum(axis=0) @ (np.arange(21) + 0.5 + c0)) / w.sum()
            assert abs(cx - x) < 0.1 and abs(cy - y) < 0.1, (view.name, cx - x, cy - y)


def test_default_scale_relief_spans_sea_level_to_1400_m():
    shape, spacing = (1580, 1350), 5.0   # the grid of a default 2000 px scene
    h = synthesize_relief(shape, spacing, np.random.default_rng(0))
    assert h.min() == 0.0 and h.max() == pytest.approx(1400.0, abs=1.0)
    assert 200 < np.median(h) < 1000                  # mountains, not one spike
    assert 0.005 < np.mean(h == 0) < 0.1               # a little sea-level plain
    gy, gx = np.gradient(h, spacing)
    slope = np.hypot(gx, gy)
    assert 0.1 < np.median(slope) < 0.6 and np.quantile(slope, 0.99) < 2.5
    s = hillshade(h, spacing)
    assert s.min() >= 0.25 and 0.8 < np.median(s) < 1.2


def test_relief_is_deterministic_by_seed():
    a = synthesize_relief((200, 200), 5.0, np.random.default_rng(1))
    b = synthesize_relief((200, 200), 5.0, np.random.default_rng(1))
    c = synthesize_relief((200, 200), 5.0, np.random.default_rng(2))
    assert np.array_equal(a, b) and not np.array_equal(a, c)
