"""The simulator's rigorous geometry alone (numpy only: this file imports no rasterio)."""
import numpy as np
import pytest

from prismstation.sim import geometry as geo
from prismstation.sim.scenario import (ALTITUDE, CENTRE, build_scenario, product_affine)

HS = ALTITUDE


def _scenario(ascending=False, north_up=False, seed=1):
    return build_scenario(np.random.default_rng(seed), 2000, north_up, ascending)


def _track_distance(orbit, en):
    """Independent: distance from points to the straight ground track and the unit vector u
    from the track to the point (docs/model.md §2)."""
    p0 = np.asarray(orbit.track_origin)
    t = np.array([np.sin(orbit.heading), np.cos(orbit.heading)])
    rel = en - p0
    foot = p0 + (rel @ t)[:, None] * t
    v = en - foot
    d = np.linalg.norm(v, axis=1)
    return d, v / d[:, None], t


@pytest.mark.parametrize("ascending", [False, True])
@pytest.mark.parametrize("name", ["N", "F", "B"])
def test_ray_point_round_trip(name, ascending):
    sc = _scenario(ascending)
    view = sc.views[name]
    rng = np.random.default_rng(5)
    line = rng.uniform(-100, 2100, 200)
    col = rng.uniform(-100, 2100, 200)
    h = rng.uniform(0, 1500, 200)
    o, d = geo.true_ray(sc.orbit, view, line, col)
    p = geo.ray_at_height(o, d, h)
    line2, col2 = geo.true_raw(sc.orbit, view, np.column_stack([p, h]))
    assert np.max(np.abs(line2 - line)) < 1e-6
    assert np.max(np.abs(col2 - col)) < 1e-6


def test_true_ray_of_image_point_passes_through_point():
    sc = _scenario()
    rng = np.random.default_rng(2)
    enh = np.column_stack([CENTRE[0] + rng.uniform(-2000, 2000, 50),
                           CENTRE[1] + rng.uniform(-2000, 2000, 50), rng.uniform(0, 1400, 50)])
    for view in sc.views.values():
        xy = geo.image_coords(sc.orbit, view, enh)
        o, d = geo.pixel_rays(sc.orbit, view, xy)
        back = geo.ray_at_height(o, d, enh[:, 2])
        assert np.max(np.linalg.norm(back - enh[:, :2], axis=1)) < 1e-5


def test_nominal_projection_inverse_and_product_affine():
    sc = _scenario()
    for view in sc.views.values():
        line, col = np.array([0.0, 10.5, 1999.0]), np.array([3.0, 1000.0, 1500.25])
        g = geo.nominal_ground(sc.orbit, view, line, col)
        l2, c2 = geo.nominal_raw(sc.orbit, view, g)
        assert np.allclose(l2, line, atol=1e-8) and np.allclose(c2, col, atol=1e-8)
        xy = np.array([[0.0, 0.0], [123.4, 1876.5]])
        assert np.allclose(geo.map_to_image(view, geo.image_to_map(view, xy)), xy, atol=1e-8)


@pytest.mark.parametrize("ascending", [False, True])
@pytest.mark.parametrize("name", ["N", "F", "B"])
def test_relief_displacement_agrees_with_empirical_formula(name, ascending):
    """Without attitude errors the rigorous image position differs from docs/model.md's
    ``P + h·(d/Hs)·u ± h·tanθ·t`` only across track, by ``h·d·(1/(Hs−h) − 1/Hs)``."""
    sc = _scenario(ascending)
    orbit = sc.orbit
    view = sc.views[name].with_attitude(geo.Attitude())
    rng = np.random.default_rng(3)
    en = np.column_stack([CENTRE[0] + rng.uniform(-3000, 3000, 100),
                          CENTRE[1] + rng.uniform(-3000, 3000, 100)])
    h = rng.uniform(0, 1450, 100)
    d, u, t = _track_distance(orbit, en)
    sign = {"N": 0.0, "F": 1.0, "B": -1.0}[name]
    tan_theta = np.tan(np.radians({"N": 0.0, "F": 26.4, "B": 26.8}[name]))
    empirical = en + (h * d / HS)[:, None] * u + sign * (h * tan_theta)[:, None] * t
    line, col = geo.true_raw(orbit, view, np.column_stack([en, h]))
    rigorous = geo.nominal_ground(orbit, view, line, col)
    diff = rigorous - empirical
    predicted = h * d * (1 / (HS - h) - 1 / HS)
    assert np.max(np.abs(diff @ t)) < 1e-6
    assert np.max(np.abs(np.sum(diff * u, axis=1) - predicted)) < 1e-6
    assert predicted.max() > 0.01  # the approximation is not trivially exact


def test_attitude_biases_shift_tens_of_metres_and_yaw_rotates():
    sc = _scenario()
    p = np.array([[CENTRE[0], CENTRE[1], 500.0]])
    for name, view in sc.views.items():
        nominal = view.with_attitude(geo.Attitude())
        shift = geo.image_coords(sc.orbit, view, p) - geo.image_coords(sc.orbit, nominal, p)
        assert 1.0 < np.linalg.norm(shift) * 2.5 < 300.0
    # the yaw makes the along-track shift vary across the image (B3-like term of eq. 3)
    n = sc.views["N"]
    nominal = n.with_attitude(geo.Attitude())
    pts = np.array([[*geo.image_to_map(n, np.array([x, 1000.0])), 300.0] for x in (100.0, 1900.0)])
    dy = (geo.image_coords(sc.orbit, n, pts) - geo.image_coords(sc.orbit, nominal, pts))[:, 1]
    assert abs(dy[1] - dy[0]) == pytest.approx(abs(sc.platform.yaw) * 1800, rel=0.05)


def test_forward_sees_earlier_than_nadir_by_tens_of_seconds():
    sc = _scenario()
    p = np.array([[CENTRE[0], CENTRE[1], 200.0]])
    times = {k: geo.raw_time(sc.orbit, v, geo.true_raw(sc.orbit, v, p)[0])[0]
             for k, v in sc.views.items()}
    assert 40 < times["N"] - times["F"] < 55 and 40 < times["B"] - times["N"] < 55


def test_views_get_independent_geolocation_errors_within_the_bound():
    """No fixed Table 2 offsets: across many draws each view's (along, across) error fills
    the ±bound box uniformly and independently of the other views'."""
    from prismstation.sim.scenario import draw_geolocation_errors
    rng = np.random.default_rng(0)
    e = np.array([[draw_geolocation_errors(rng, 100.0)[v] for v in "NFB"] for _ in range(3000)])
    assert np.abs(e).max() <= 100.0 and np.abs(e).max() > 99.0
    assert np.allclose(e.reshape(-1, 6).std(axis=0), 100 / np.sqrt(3), rtol=0.06)
    c = np.corrcoef(e.reshape(-1, 6).T)
    assert np.abs(c[np.triu_indices(6, 1)]).max() < 0.06
    sc = build_scenario(np.random.default_rng(1), 2000, errors={"N": (0, 0), "F": (0, 40), "B": (0, 0)})
    from prismstation.sim.scenario import geolocation_error_at
    for v, want in (("N", (0, 0)), ("F", (0, 40))):
        got = geolocation_error_at(sc.orbit, sc.views[v], sc.published[v], np.array([1000.0, 1000.0]))
        assert np.allclose(got, want[0] * sc.orbit.t + want[1] * sc.orbit.a, atol=1e-6)
        # drift and yaw: a few metres at most across a 5 km scene, not zero
        corner = geolocation_error_at(sc.orbit, sc.views[v], sc.published[v], np.array([0.0, 0.0]))
        assert 0.01 < np.hypot(*(corner - got)) < 5.0


def _plane(a, b, c):
    return lambda e, n: a + b * (e - CENTRE[0]) + c * (n - CENTRE[1])


@pytest.mark.parametrize("slope", [0.0, 0.3, 1.5, 2.5])
def test_terrain_intersection_with_planes_is_exact(slope):
    """A sloping plane has a closed-form intersection; steep slopes (where the fixed point
    diverges for the 26.8° backward ray) must still converge."""
    sc = _scenario()
    view = sc.views["B"]
    xy = np.random.default_rng(1).uniform(0, 2000, (300, 2))
    o, d = geo.pixel_rays(sc.orbit, view, xy)
    t = sc.orbit.t
    sample = _plane(700.0, -slope * t[0], -slope * t[1])
    got = geo.intersect_terrain(o, d, sample, 0.0, 1455.0, tol=1e-6)
    # analytic: h = 700 + s·((P(h) − C)·(−t)), P(h) = O + (Hs − h)·d_xy
    k = -slope * ((o[:, :2] - CENTRE) @ t)
    kd = -slope * (d[:, :2] @ t)
    h = (700.0 + k + HS * kd) / (1 + kd)
    inside = (h > 0) & (h < 1455)
    assert inside.sum() > 50
    assert np.max(np.abs(got[inside, 2] - h[inside])) < 1e-5


def test_terrain_intersection_on_rough_terrain_lies_on_terrain():
    sc = _scenario()
    view = sc.views["F"]
    xy = np.random.default_rng(4).uniform(0, 2000, (2000, 2))
    o, d = geo.pixel_rays(sc.orbit, view, xy)

    def rough(e, n):
        return 700 + 600 * np.sin(e / 150.0) * np.cos(n / 90.0)

    got = geo.intersect_terrain(o, d, rough, 100.0, 1300.0, tol=1e-6)
    assert np.max(np.abs(rough(got[:, 0], got[:, 1]) - got[:, 2])) < 1e-5
    # and every intersection is on the ray
    back = geo.ray_at_height(o, d, got[:, 2])
    assert np.max(np.abs(back - got[:, :2])) < 1e-6


def test_product_grids_path_oriented_and_north_up():
    sc = _scenario(ascending=True)
    a1, a2, a3, a4, _, _ = product_affine(sc.orbit, 1000, north_up=False)
    # rows (y) increase along the flight direction: +y maps to +t
    m = np.linalg.inv([[a1, a2], [a3, a4]])
    assert np.allclose(m[:, 1] / 2.5, sc.orbit.t, atol=1e-12)
    assert product_affine(sc.orbit, 1000, north_up=True)[:4] == (0.4, 0.0, 0.0, -0.4)


def test_geometry_module_imports_no_rasterio():
    import ast
    import inspect
    tree = ast.parse(inspect.getsource(geo))
    names = {a.name.split(".")[0] for node in ast.walk(tree)
             if isinstance(node, (ast.Import, ast.ImportFrom)) for a in node.names}
    mods = {node.module.split(".")[0] for node in ast.walk(tree)
            if isinstance(node, ast.ImportFrom) and node.module}
    assert not ({"rasterio", "cv2", "pyproj"} & (names | mods))
