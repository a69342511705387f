"""The compiled Gauss–Newton loop of a least-squares patch (``lsm_kernel.gauss_newton``, called
by ``Fit.run``) against its definition written out in Python, every way it ends; its normal
equations against numpy's products; the patch's two-pass sample against the spline's values
at the same points."""
import math

import numpy as np
import pytest
from scipy import ndimage

from prismstation.core.matching import lsm_fit as F
from prismstation.core.matching import lsm_kernel as K
from prismstation.core.matching.lsm_spline import Spline


def _run_by_python(fit, bend, max_iter, t0, max_move, A0inv, max_shape_change, need_rho=None, tol=F.STEP_TOL):
    """``Fit.run`` as array operations (how it read before its loop was compiled)."""
    nb = 3 if bend else 0
    wt = fit.weights()
    sw = F._NONE if wt is None else np.sqrt(wt)
    it = 0
    for it in range(1, max_iter + 1):
        smp = fit.sample()
        if smp is None:
            return F.OUTSIDE, "patch left the search image", it
        S, Sx, Sy = smp
        if need_rho is not None and it >= F.RIVAL_ITER:
            rho = F.correlation(fit.T, S)
            if rho < need_rho - F.RIVAL_MARGIN:
                return F.LOW_CORRELATION, f"correlation {rho:.2f} after {it - 1} iterations: no rival", it
        if fit.g1 is None:
            fit.g1 = fit.T.std() / max(S.std(), 1e-12)
            fit.g0 = fit.T.mean() - fit.g1 * S.mean()
        # the design on the mean of both images' gradients (ESM), rows and residuals × √weight
        J, r = np.empty((11 if bend else 8, S.size)), np.empty(S.size)
        a, b, c, d = fit.A.ravel()
        E = np.array([[d, -c], [-b, a]]) / (a * d - b * c)          # A⁻ᵀ
        K.design_rows(S, Sx, Sy, fit.T, fit.Tu, fit.Tv, fit.u, fit.v, fit.Q, fit.d, fit.g0, fit.g1, E, True, bend,
                      J, r, sw)
        dp = np.empty(J.shape[0])
        if not K.solve_small(J @ J.T, J @ r, dp):
            return F.TEXTURE, "singular normal matrix (no texture)", it
        fit.smp = None
        fit.t += dp[0:2]
        fit.A += dp[2:6].reshape(2, 2)
        if bend:
            fit.c += dp[6:9]
        fit.g0 += dp[6 + nb]
        fit.g1 += dp[7 + nb]
        if math.hypot(fit.t[0] - t0[0], fit.t[1] - t0[1]) > max_move:
            return F.MOVED, f"the patch moved more than {max_move:g} px from its start", it
        change = math.sqrt(float(np.square(A0inv @ fit.A - np.eye(2)).sum()))
        bent = bend and np.abs(fit.c).max() * fit.half > 2 * F.max_bend(fit.half)
        if change > 2 * max_shape_change or fit.g1 <= 0 or bent:
            return F.SHAPE, ("the patch's contrast inverted" if fit.g1 <= 0 else
                             f"the shape degenerated (changed by {change:.0%})"), it
        still = fit.w is not None or np.abs(dp[2:6 + nb]).max() * min(fit.half, F.SHAPE_REACH) < 2.5 * tol
        if max(abs(dp[0]), abs(dp[1])) < tol and still:
            dq = dp[2:6].reshape(2, 2) @ fit.uv + dp[0:2, None]
            if bend:
                dq += np.outer(fit.d, dp[6:9] @ fit.Q)
            fit.smp = (S + Sx * dq[0] + Sy * dq[1], Sx, Sy)
            return F.OK, "", it
        if it >= F.WANDER_ITER and math.hypot(dp[0], dp[1]) > 0.1:
            break
    return F.NOT_CONVERGED, f"no convergence in {it} iterations", it


def _scene(seed=4, blur=1.2):
    rng = np.random.default_rng(seed)
    img = ndimage.gaussian_filter(rng.normal(100, 30, (120, 120)), blur)
    y, x = np.mgrid[0:120, 0:120] / 120.0
    search = ndimage.map_coordinates(img, [np.mgrid[0:120, 0:120][0] + 0.37 + 1.5 * x * y,
                                           np.mgrid[0:120, 0:120][1] - 0.21 + 0.02 * (y - 0.5) * 120],
                                     order=3, mode="mirror") * 1.1 + 5 + rng.normal(0, 1.0, (120, 120))
    return img, search


def _fit(img, search, half=16, weighted=False, start=(60.0, 60.0)):
    T, u, v = F.template(img, 60.3, 59.6, half)
    w = np.exp(-(u ** 2 + v ** 2) / (2 * 8.0 ** 2)) if weighted else None
    fit = F.Fit(T, u, v, Spline(search), np.array([0.1, 0.995]) / np.hypot(0.1, 0.995), half, w=w)
    if weighted:
        fit.pw = np.linspace(0.5, 1.0, T.size)
    fit.t, fit.A = np.array(start, float), np.eye(2)
    return fit


CASES = {   # how the loop ends: (the fit's and the run's arguments, the status)
    "converges": (dict(), F.OK),
    "a finer tolerance": (dict(tol=3e-3), F.OK),     # an iteration more than at 0.01 px here
    "weighted": (dict(weighted=True), F.OK),
    "rival given up": (dict(need_rho=1.5), F.LOW_CORRELATION),
    "rival kept": (dict(need_rho=0.5), F.OK),
    "moved": (dict(max_move=0.05), F.MOVED),
    "shape": (dict(max_shape_change=0.001), F.SHAPE),
    "not converged": (dict(max_iter=2, tol=1e-9), F.NOT_CONVERGED),
    "outside": (dict(start=(110.0, 60.0)), F.OUTSIDE),
    "no texture": (dict(flat=True), F.TEXTURE),
}


@pytest.mark.parametrize("case", CASES)
def test_the_compiled_loop_is_its_definition(case):
    kw, status = dict(CASES[case][0]), CASES[case][1]
    img, search = _scene()
    if kw.pop("flat", False):
        img, search = np.full_like(img, 80.0), np.full_like(search, 80.0)
    fit = _fit(img, search, weighted=kw.pop("weighted", False), start=kw.pop("start", (60.0, 60.0)))
    args = dict(max_iter=kw.pop("max_iter", 20), t0=fit.t.copy(), max_move=kw.pop("max_move", 3.0),
                A0inv=np.eye(2), max_shape_change=kw.pop("max_shape_change", 0.25), **kw)
    compiled, python = fit.copy(), fit.copy()
    got = compiled.run(False, **args)
    want = _run_by_python(python, False, **args)
    assert got == want and got[0] == status
    if case == "converges":             # and the bend from there, its first sample carried
        got, want = compiled.run(True, **args), _run_by_python(python, True, **args)
        assert got == want and got[0] == F.OK
        assert np.abs(compiled.c).max() > 0
    for name in ("t", "A", "c"):
        assert np.allclose(getattr(compiled, name), getattr(python, name), rtol=0, atol=1e-9), name
    if python.g1 is not None:
        assert compiled.g0 == pytest.approx(python.g0, abs=1e-9) and compiled.g1 == pytest.approx(python.g1, rel=1e-12)
    assert (compiled.smp is None) == (python.smp is None)
    if python.smp is not None:
        for a, b in zip(compiled.smp, python.smp):
            assert np.allclose(a, b, rtol=0, atol=1e-9)


@pytest.mark.parametrize("k", [8, 11])
@pytest.mark.parametrize("n", [1, 2, 49, 4225])
def test_the_normal_equations_are_the_products(k, n):
    rng = np.random.default_rng(k * n)
    J, r = rng.normal(size=(k, n)), rng.normal(size=n)
    N, b = np.full((k, k), np.nan), np.full(k, np.nan)
    K.normals(J, r, N, b)
    assert np.allclose(N, J @ J.T, rtol=1e-13, atol=1e-12) and np.array_equal(N, N.T)
    assert np.allclose(b, J @ r, rtol=1e-13, atol=1e-12)


@pytest.mark.parametrize("bend", [False, True])
def test_the_patch_sample_is_the_splines_value_at_each_pixel(bend):
    rng = np.random.default_rng(11)
    sp = Spline(ndimage.gaussian_filter(rng.normal(100, 30, (90, 100)), 1.0), c0=7, r0=3)
    k = np.arange(-20, 21.0)
    v, u = np.meshgrid(k, k, indexing="ij")
    u, v = u.ravel(), v.ravel()
    Q = np.vstack([u ** 2, u * v, v ** 2]) / 20
    t, A, c, d = np.array([55.3, 47.8]), np.array([[1.03, 0.04], [-0.02, 0.97]]), np.array([0.2, -0.1, 0.3]), \
        np.array([0.6, 0.8])
    S, Sx, Sy = np.empty(u.size), np.empty(u.size), np.empty(u.size)
    assert K.sample_patch(sp.flat, sp.width, sp.c0, sp.r0, sp.lo, sp.hi, t, A, c, d, u, v, Q, bend, S, Sx, Sy)
    q = t[:, None] + A @ np.vstack([u, v]) + (np.outer(d, c @ Q) if bend else 0)
    want = sp.sample(q[0], q[1])
    for got, w in zip((S, Sx, Sy), want):
        assert np.allclose(got, w, rtol=0, atol=1e-11)
