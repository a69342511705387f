"""Geometry properties (hypothesis): the model's forward and inverse agree, fits do not depend
on point order, and every transform round-trips.

Scenes are sim/model_triplet.py's: path-oriented (1B2-R) or north-up (1B2-G) affines, any
heading, a 14,000 px image at 2.5 m, the ground track 3 km beside the image centre.
"""
from __future__ import annotations

import numpy as np
from hypothesis import assume, example, given
from hypothesis import strategies as st

from prismstation.core.models import prism
from prismstation.core.adjustment.affine import Affine2D
from prismstation.core.models.prism import BIAS_MODELS, BiasFit, fit_bias
from prismstation.core.models.rectify import fit_transform
from prismstation.core.models.solution import Settings, solve
from prismstation.sim.model_triplet import make_points, make_scene
from tests.robustness.fuzzlib import fuzz_settings

SIZE = 14000
headings = st.floats(0.0, 360.0, exclude_max=True)
heights = st.floats(-100.0, 9000.0)
pixels = st.floats(0.0, float(SIZE))
views = st.sampled_from(["N", "F", "B"])


def _scene(heading, path_oriented):
    return make_scene(heading, path_oriented, size=SIZE)


# ------------------------------------------------------------------ model forward / inverse
@fuzz_settings(300)
@given(heading=headings, path_oriented=st.booleans(), view=views, h=heights, x=pixels, y=pixels)
@example(heading=0.0, path_oriented=False, view="N", h=7713.0, x=0.0, y=0.0)  # 1.0e-6 px with 4 iterations
def test_inverse_then_forward_is_identity(heading, path_oriented, view, h, x, y):
    """Image x0' → ground at h → image: back to the same pixel within 1e-6 px."""
    sc = _scene(heading, path_oriented)
    v = sc.views[view]
    xy0 = np.array([x, y])
    en = prism.ancillary_to_ground(sc, v, xy0, h)
    back = prism.ground_to_ancillary(sc, v, en, h)
    assert np.max(np.abs(back - xy0)) < 1e-6, (back - xy0)


@fuzz_settings(300)
@given(heading=headings, path_oriented=st.booleans(), view=views, h=heights, x=pixels, y=pixels)
def test_forward_then_inverse_is_identity(heading, path_oriented, view, h, x, y):
    """A ground point anywhere under the image → image → ground: within 1e-6 px on the ground."""
    sc = _scene(heading, path_oriented)
    v = sc.views[view]
    en = sc.views["N"].map_to_image.inverse()(np.array([x, y]))
    xy0 = prism.ground_to_ancillary(sc, v, en, h)
    en_back = prism.ancillary_to_ground(sc, v, xy0, h)
    assert np.max(np.abs(en_back - en)) < 1e-6 * v.pixel_size_m, (en_back - en)


@fuzz_settings(60)
@given(heading=headings, path_oriented=st.booleans(), view=views, h=heights)
def test_forward_inverse_vectorised(heading, path_oriented, view, h):
    """Arrays of points (n, 2) with per-point heights give what single points give."""
    sc = _scene(heading, path_oriented)
    v = sc.views[view]
    rng = np.random.default_rng(int(heading * 1000))
    xy0 = rng.uniform(0, SIZE, (25, 2))
    hs = np.full(25, h) + rng.uniform(-50, 50, 25)
    en = prism.ancillary_to_ground(sc, v, xy0, hs)
    single = np.array([prism.ancillary_to_ground(sc, v, xy0[i], hs[i]) for i in range(25)])
    assert np.allclose(en, single, rtol=0, atol=1e-9)
    assert np.max(np.abs(prism.ground_to_ancillary(sc, v, en, hs) - xy0)) < 1e-6


# ------------------------------------------------------------------ bias and affines
small = st.floats(-2e-3, 2e-3)
shifts = st.floats(-200.0, 200.0)


@fuzz_settings(200)
@given(m=st.lists(small, min_size=4, max_size=4), b=st.lists(shifts, min_size=2, max_size=2),
       pts=st.lists(st.tuples(pixels, pixels), min_size=1, max_size=20))
def test_bias_apply_invert_round_trip(m, b, pts):
    fit = BiasFit("affine", np.array(m).reshape(2, 2), np.array(b), np.zeros(6), np.zeros(6), ())
    xy = np.array(pts, float)
    assert np.max(np.abs(fit.invert(fit.apply(xy)) - xy)) < 1e-8
    assert np.max(np.abs(fit.apply(fit.invert(xy)) - xy)) < 1e-8


@fuzz_settings(100)
@given(model=st.sampled_from(list(BIAS_MODELS)), m=st.lists(small, min_size=4, max_size=4),
       b=st.lists(shifts, min_size=2, max_size=2), seed=st.integers(0, 2**32 - 1))
def test_fitted_bias_round_trip_and_recovery(model, m, b, seed):
    """A bias fitted to exact data of its own form is recovered; apply/invert round-trip."""
    rng = np.random.default_rng(seed)
    M = np.array(m).reshape(2, 2)
    if model == "shift":
        M = np.zeros((2, 2))
    elif model == "similarity":
        M = np.array([[M[0, 0], -M[1, 0]], [M[1, 0], M[0, 0]]])
    xy0 = rng.uniform(0, SIZE, (8, 2))
    xy = xy0 + xy0 @ M.T + np.array(b)
    fit = fit_bias(xy0, xy, model)
    assert np.max(np.abs(fit.apply(xy0) - xy)) < 1e-6
    assert np.max(np.abs(fit.invert(xy) - xy0)) < 1e-6


def _affine(draw_vals):
    a, b_, c, d, e, f = draw_vals
    return Affine2D([[a, b_, c], [d, e, f]])


well_conditioned = st.tuples(st.floats(0.2, 5.0), st.floats(-np.pi, np.pi), st.floats(0.2, 5.0),
                             st.floats(-0.5, 0.5), st.floats(-1e6, 1e6), st.floats(-1e7, 1e7),
                             st.booleans())


def _make_affine(params) -> Affine2D:
    sx, rot, sy, shear, tx, ty, flip = params
    R = np.array([[np.cos(rot), -np.sin(rot)], [np.sin(rot), np.cos(rot)]])
    L = R @ np.array([[sx, shear], [0.0, sy * (-1 if flip else 1)]])
    return Affine2D(np.column_stack([L, [tx, ty]]))


@fuzz_settings(200)
@given(pa=well_conditioned, pb=well_conditioned,
       pts=st.lists(st.tuples(st.floats(-1e4, 2e4), st.floats(-1e4, 2e4)), min_size=1, max_size=10))
def test_affine_compose_inverse_round_trip(pa, pb, pts):
    A, B = _make_affine(pa), _make_affine(pb)
    p = np.array(pts, float)
    scale = 1.0 + np.abs(A(B(p))).max()
    assert np.allclose((A @ B)(p), A(B(p)), rtol=0, atol=1e-9 * scale)
    for T in (A, B, A @ B):
        q = T(p)
        assert np.allclose(T.inverse()(q), p, rtol=0, atol=1e-9 * (1 + np.abs(q).max()))
        ident = (T @ T.inverse()).matrix
        assert np.allclose(ident[:, :2], np.eye(2), atol=1e-12)
        assert np.allclose(Affine2D.from_coeffs(*T.coeffs()).matrix, T.matrix, rtol=0, atol=0)
    assert np.allclose(((A @ B).inverse() @ A @ B).matrix[:, :2], np.eye(2), atol=1e-9)


# ------------------------------------------------------------------ fit independent of point order
def _fit_signature(sol):
    out = {}
    for v, fit in sol.bias.items():
        out[f"bias {v}"] = (np.asarray(fit.params, float), np.asarray(fit.std, float))
    par = sol.model.parallax
    out["parallax"] = (np.array([par.c0, par.c1]), np.array([par.std_c0 or 0.0, par.std_c1 or 0.0]))
    for p in sol.points:
        if p.ground_est is not None:
            out[f"est {p.id}"] = (np.array(p.ground_est), np.ones(3))
        for v, r in p.residual_px.items():
            out[f"res {p.id} {v}"] = (np.asarray(r, float), np.ones(2))
    return out


@fuzz_settings(40)
@given(heading=headings, path_oriented=st.booleans(), seed=st.integers(0, 2**32 - 1),
       n_gcp=st.integers(3, 12), bias=st.sampled_from(list(BIAS_MODELS)),
       parallax=st.sampled_from(list(prism.PARALLAX_MODELS)), data=st.data())
def test_solution_does_not_depend_on_point_order(heading, path_oriented, seed, n_gcp, bias, parallax, data):
    sc = _scene(heading, path_oriented)
    pts = make_points(sc, n_gcp=n_gcp, n_icp=8, noise_px=0.4, seed=seed % 100000)
    settings = Settings(bias_model=bias, parallax_model=parallax)
    ref = solve(sc, pts, settings)
    assume(ref.ok)
    order = data.draw(st.permutations(range(len(pts))))
    sol = solve(sc, [pts[i] for i in order], settings)
    a, b = _fit_signature(ref), _fit_signature(sol)
    assert a.keys() == b.keys()
    for k in a:
        (va, sa), (vb, _) = a[k], b[k]
        # 1e-9 relative to the value, or to its standard deviation where the value is ~0
        tol = 1e-9 * np.maximum(np.abs(va), np.abs(sa)) + 1e-12
        assert np.all(np.abs(va - vb) <= tol), (k, va, vb)
    assert ref.messages == sol.messages


# ------------------------------------------------------------------ rectification transforms
@fuzz_settings(120)
@given(kind=st.sampled_from(["affine", "projective", "poly1", "poly2", "poly3"]),
       base=well_conditioned, nonlin=st.lists(st.floats(-1e-9, 1e-9), min_size=4, max_size=4),
       seed=st.integers(0, 2**32 - 1))
def test_rectify_transform_round_trip(kind, base, nonlin, seed):
    """Fit a transform to image → map points of a known mapping, then map → image → map and
    image → map → image over the fitted area: the same points within 1e-6 px / 1e-6 m·scale."""
    rng = np.random.default_rng(seed)
    A = _make_affine(base)
    n = {"affine": 8, "projective": 10, "poly1": 8, "poly2": 15, "poly3": 25}[kind]
    src = rng.uniform(0, SIZE, (n, 2))
    q = src / SIZE
    # mild non-linearity the polynomials and the projective can absorb (metres)
    bend = np.column_stack([nonlin[0] * src[:, 0] ** 2 + nonlin[1] * src[:, 0] * src[:, 1],
                            nonlin[2] * src[:, 1] ** 2 + nonlin[3] * src[:, 0] * src[:, 1]])
    dst = A(src) + (bend if kind.startswith("poly") and kind != "poly1" else 0) + rng.normal(0, 0.5, (n, 2)) * q
    t = fit_transform(kind, src, dst)
    test = rng.uniform(0.05 * SIZE, 0.95 * SIZE, (30, 2))
    fwd = t(test)
    back = t.inverse(fwd)
    assert np.all(np.isfinite(back)), kind
    assert np.max(np.abs(back - test)) < 1e-6, (kind, np.max(np.abs(back - test)))
    # and map → image → map
    assert np.max(np.abs(t(back) - fwd)) < 1e-6 * max(1.0, A.scale())
