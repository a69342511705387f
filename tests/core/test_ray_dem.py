"""Rays meeting a height surface: converged on steep relief seen off nadir, where a fixed
three or five steps are not enough, and a ray that cannot meet it reported, not placed."""
import math

import numpy as np
import pytest

from prismstation.core.models.ray_dem import ray_meets_surface

TAN_FB = math.tan(math.radians(26.0))      # F and B of PRISM, as the demo's geometry has them


def _ray(e0, tan_theta=TAN_FB):
    """A ray through (e0, 0) at height 0 leaning east: its footprint moves tan θ per metre up."""
    e0 = np.atleast_1d(np.asarray(e0, float))
    return lambda h: np.column_stack([e0 + tan_theta * h, np.zeros_like(e0)])


def _slope(deg, base=1000.0):
    """A plane rising east at ``deg`` degrees, ``base`` m at E = 0."""
    s = math.tan(math.radians(deg))
    return lambda en: base + s * np.asarray(en)[:, 0]


def _exact(e0, deg, base=1000.0, tan_theta=TAN_FB):
    s = math.tan(math.radians(deg))
    return (base + s * np.asarray(e0, float)) / (1.0 - s * tan_theta)


def _fixed(ground_at, surface, h0, steps):
    """The old way: a fixed number of fixed-point steps, no test."""
    h = np.atleast_1d(np.asarray(h0, float))
    for _ in range(steps):
        h = surface(ground_at(h))
    return h


@pytest.mark.parametrize("deg", [5.0, 30.0, 45.0, 60.0])
def test_steep_slopes_seen_at_26_degrees_converge(deg):
    e0 = np.array([-300.0, 0.0, 250.0])
    hits = ray_meets_surface(_ray(e0), _slope(deg), 0.0)
    assert hits and hits.converged.all() and not hits.reason
    np.testing.assert_allclose(hits.h, _exact(e0, deg), atol=0.02)
    # the point found lies on the ray and on the surface
    np.testing.assert_allclose(hits.en, _ray(e0)(hits.h), atol=1e-9)
    np.testing.assert_allclose(_slope(deg)(hits.en), hits.h, atol=0.011)


@pytest.mark.parametrize("deg, steps", [(45.0, 3), (60.0, 3), (60.0, 5)])
def test_a_fixed_count_of_steps_is_not_enough_there(deg, steps):
    """What the four copies did (3–5 fixed-point steps from the mean height): metres to
    hundreds of metres off on these slopes; the convergence test gets it to 1 cm."""
    e0 = np.array([0.0])
    old = _fixed(_ray(e0), _slope(deg), 0.0, steps)
    err_old = abs(old[0] - _exact(e0, deg)[0])
    assert err_old > 5.0, err_old
    hits = ray_meets_surface(_ray(e0), _slope(deg), 0.0)
    assert hits and abs(hits.h[0] - _exact(e0, deg)[0]) < 0.02


def test_beyond_the_fixed_points_reach_the_secant_converges():
    """70° at 26° off nadir: slope·tan θ = 1.34, the fixed point diverges."""
    e0 = np.array([0.0, 100.0])
    diverged = _fixed(_ray(e0), _slope(70.0), 0.0, 10)
    assert np.all(np.abs(diverged - _exact(e0, 70.0)) > 1e3)
    hits = ray_meets_surface(_ray(e0), _slope(70.0), 0.0)
    assert hits
    np.testing.assert_allclose(hits.h, _exact(e0, 70.0), atol=0.02)


def test_a_ray_off_the_surface_or_not_converging_is_reported_not_placed():
    def surface(en):
        h = _slope(30.0)(en)
        return np.where(en[:, 0] > 5000.0, np.nan, h)      # the DEM ends at E = 5 km
    e0 = np.array([0.0, 4900.0])
    hits = ray_meets_surface(_ray(e0), surface, 0.0)
    assert not hits and "left the surface" in hits.reason
    assert hits.converged.tolist() == [True, False]
    assert np.isfinite(hits.h[0]) and np.isnan(hits.h[1]) and np.isnan(hits.en[1]).all()

    # a surface that jumps every metre: no point within 1 mm of it in 4 steps
    def stairs(en):
        return 1000.0 + 37.0 * np.floor(np.asarray(en)[:, 0]) % 500.0
    hits = ray_meets_surface(_ray(np.array([0.3])), stairs, 0.0, tol_m=0.001, max_iterations=4)
    assert not hits and "did not meet the surface" in hits.reason and np.isnan(hits.h).all()
