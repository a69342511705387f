"""The shortcuts taken for speed in the core give what the plain formulas give."""
import math

import numpy as np
import pytest

from prismstation.core.models.scene import GroundTrack
from prismstation.core.models.solution import critical_value
from prismstation.core.adjustment.stats import ComponentStats, VectorStats


def _nearest_on_polyline(points, q):
    """Plain-Python reference: the closest point of the polyline, first and last segments
    extended without end."""
    best, best_d2 = None, math.inf
    for i in range(len(points) - 1):
        (ax, ay), (bx, by) = points[i], points[i + 1]
        dx, dy = bx - ax, by - ay
        s = ((q[0] - ax) * dx + (q[1] - ay) * dy) / (dx * dx + dy * dy)
        if i > 0:
            s = max(s, 0.0)
        if i < len(points) - 2:
            s = min(s, 1.0)
        p = (ax + s * dx, ay + s * dy)
        d2 = (p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2
        if d2 < best_d2:
            best, best_d2 = p, d2
    return np.array(best)


@pytest.mark.parametrize("track", [
    [[500000.0, 4600000.0], [506000.0, 4566000.0]],                       # one segment
    [[500000.0, 4600000.0], [503000.0, 4583000.0], [506000.0, 4566000.0]],  # same line, two
    [[500000.0, 4600000.0], [504000.0, 4583000.0], [506000.0, 4566000.0]],  # bent
])
def test_foot_is_the_nearest_track_point(track):
    tr = GroundTrack(np.array(track))
    rng = np.random.default_rng(3)
    q = rng.uniform([480000, 4540000], [530000, 4620000], (6, 2))
    f, t = tr.foot(q)
    assert f.shape == t.shape == (6, 2)
    for qi, fi, ti in zip(q, f, t):
        assert np.allclose(fi, _nearest_on_polyline(track, qi), rtol=0, atol=1e-6)
        assert math.isclose(np.hypot(*ti), 1.0, rel_tol=1e-12)
    f1, t1 = tr.foot(q[0])  # a single point keeps its shape
    assert f1.shape == (2,) and np.array_equal(f1, f[0]) and np.array_equal(t1, t[0])


def test_foot_of_one_segment_equals_the_same_line_cut_in_two():
    one = GroundTrack(np.array([[500000.0, 4600000.0], [506000.0, 4566000.0]]))
    two = GroundTrack(np.array([[500000.0, 4600000.0], [503000.0, 4583000.0], [506000.0, 4566000.0]]))
    q = np.random.default_rng(5).uniform([480000, 4540000], [530000, 4620000], (50, 2))
    f1, t1 = one.foot(q)
    f2, t2 = two.foot(q)
    assert np.allclose(f1, f2, atol=1e-6) and np.allclose(t1, t2, atol=1e-12)


@pytest.mark.parametrize("n", [0, 1, 2, 7, 180, 1000])
def test_component_stats_are_numpys_to_the_last_bit(n):
    v = np.random.default_rng(n).normal(3.0, 2.0, n)
    if n > 3:
        v[[1, 2]] = [np.nan, np.inf]
    s = ComponentStats.of(v)
    w = v[np.isfinite(v)]
    assert s.n == w.size
    if w.size == 0:
        assert all(math.isnan(x) for x in (s.min, s.max, s.mean, s.rms, s.std))
        return
    assert (s.min, s.max, s.mean) == (w.min(), w.max(), w.mean())
    assert s.rms == np.sqrt(np.mean(w ** 2))
    assert s.std == w.std(ddof=1) if w.size > 1 else math.isnan(s.std)


def test_vector_stats_drop_rows_with_any_non_finite_value():
    xy = np.array([[1.0, 2.0], [np.nan, 5.0], [3.0, np.inf], [5.0, 8.0]])
    s = VectorStats.of(xy)
    assert s.n == 2 and (s.x.mean, s.y.mean) == (3.0, 5.0)


def test_critical_value_is_students_t_at_the_normal_alpha():
    stats = pytest.importorskip("scipy.stats")
    for threshold in (1.96, 3.29, 4.0, 40.0):
        for dof in (1, 2, 3, 10, 100):
            alpha = 2 * stats.norm.sf(threshold)
            assert critical_value(threshold, dof) == float(stats.t.isf(alpha / 2, max(dof - 1, 1)))
    assert critical_value(3.29, 10**6) == pytest.approx(3.29, abs=1e-3)
