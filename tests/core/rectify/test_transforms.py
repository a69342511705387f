"""Image → map transforms: exact recovery, noise floor, GDAL and scikit-image cross-checks."""
import warnings

import numpy as np
import pytest

from prismstation.core.models.rectify import (KINDS, compare_transforms, fit_transform, format_rmse_table,
                                       min_points, n_params, poly_exponents)
from prismstation.errors import ModelError

E0, N0 = 512000.0, 4601000.0


def _poly_truth(src, degree, rng):
    """Map points from a random polynomial of ``degree`` in raw pixel coordinates."""
    exps = poly_exponents(degree)
    scale = np.array([1000.0 ** -(i + j - 1) for i, j in exps])
    A = rng.normal(0, 1, (2, len(exps))) * scale * 0.002
    A[0, 1], A[1, 2] = 2.5, -2.5      # dominant pixel size
    A[:, 0] = (E0, N0)
    phi = np.stack([src[:, 0] ** i * src[:, 1] ** j for i, j in exps], axis=1)
    return phi @ A.T, A


def _homography_truth(src):
    H = np.array([[2.4, 0.3, E0], [0.2, -2.6, N0], [2e-6, -1e-6, 1.0]])
    h = np.column_stack([src, np.ones(len(src))]) @ H.T
    return h[:, :2] / h[:, 2:], H


def _truth(kind, src, seed):
    """Exact map points of ``src`` under a fixed transform of ``kind`` (chosen by ``seed``)."""
    if kind == "projective":
        return _homography_truth(src)[0]
    degree = 1 if kind == "affine" else int(kind[4:])
    return _poly_truth(src, degree, np.random.default_rng(seed))[0]


@pytest.mark.parametrize("kind", KINDS)
def test_exact_data_recovered_and_inverse_round_trips(kind):
    rng = np.random.default_rng(1)
    src = rng.uniform(0, 10000, (25, 2))
    dst = _truth(kind, src, 11)
    t = fit_transform(kind, src, dst)
    q = rng.uniform(0, 10000, (50, 2))
    assert np.abs(t(q) - _truth(kind, q, 11)).max() < 1e-5
    assert t.rmse < 1e-6
    assert t.n_params == n_params(kind) and t.dof == 2 * 25 - n_params(kind)
    back = t.inverse(t(q))
    assert np.abs(back - q).max() < 1e-6


def test_published_parameters_affine_projective_polynomial():
    rng = np.random.default_rng(2)
    src = rng.uniform(0, 10000, (12, 2))
    dst = src @ np.array([[2.5, 0.1], [0.05, -2.45]]).T + [E0, N0]
    p = fit_transform("affine", src, dst).params
    assert np.allclose(p, [2.5, 0.1, E0, 0.05, -2.45, N0], rtol=1e-9)
    dst, H = _homography_truth(src)
    p = fit_transform("projective", src, dst).params
    assert np.allclose(p, [H[0, 0], H[0, 1], H[0, 2], H[1, 0], H[1, 1], H[1, 2], H[2, 0], H[2, 1]],
                       rtol=1e-7, atol=1e-12)
    for degree in (2, 3):
        dst, A = _poly_truth(src, degree, rng)
        p = fit_transform(f"poly{degree}", src, dst).params
        assert np.allclose(p, A.ravel(), rtol=1e-5, atol=1e-14)


@pytest.mark.parametrize("kind", KINDS)
def test_rmse_matches_ideal_noise_floor(kind):
    """E[Σv²/n_obs] = σ²(1 − u/n_obs) at GCPs; σ²(1 + u/n_obs) at check points sharing the
    GCP positions with fresh noise (mean leverage u/n_obs exactly, for a linear model)."""
    rng = np.random.default_rng(3)
    sigma, npts, trials = 1.5, 30, 300
    u, nobs = n_params(kind), 2 * npts
    src = rng.uniform(0, 10000, (npts, 2))
    truth = _truth(kind, src, 4)
    g2, i2, params = [], [], []
    for _ in range(trials):
        t = fit_transform(kind, src, truth + rng.normal(0, sigma, truth.shape))
        g2.append(t.rmse ** 2 / 2)           # per-coordinate mean square
        icp = truth + rng.normal(0, sigma, truth.shape)
        i2.append(np.mean(t.residuals(src, icp) ** 2))
        params.append(t.params)
    dof = nobs - u
    # chi-square: Σv²/σ² ~ χ²(dof), sd of the mean over trials sqrt(2·dof/trials)/nobs
    tol_g = 4 * sigma ** 2 * np.sqrt(2 * dof / trials) / nobs
    assert abs(np.mean(g2) - sigma ** 2 * (1 - u / nobs)) < tol_g
    tol_i = 4 * np.std(i2) / np.sqrt(trials) + 0.02 * sigma ** 2
    assert abs(np.mean(i2) - sigma ** 2 * (1 + u / nobs)) < tol_i
    # RMSE itself against σ·sqrt(1 ∓ u/n): within 3 %
    assert np.sqrt(np.mean(g2)) == pytest.approx(sigma * np.sqrt(1 - u / nobs), rel=0.03)
    assert np.sqrt(np.mean(i2)) == pytest.approx(sigma * np.sqrt(1 + u / nobs), rel=0.03)
    # formal parameter σ agrees with the spread over trials
    t = fit_transform(kind, src, truth + rng.normal(0, sigma, truth.shape))
    emp = np.std(params, axis=0)
    ratio = (t.std / t.sigma0 * sigma) / emp
    assert np.all((ratio > 0.8) & (ratio < 1.25)), ratio


def _gcps(src, dst):
    from rasterio.control import GroundControlPoint
    return [GroundControlPoint(row=y, col=x, x=X, y=Y) for (x, y), (X, Y) in zip(src, dst)]


@pytest.mark.parametrize("npts,kind", [(5, "affine"), (5, "poly1"), (8, "poly2"), (40, "poly2")])
def test_agrees_with_gdal_gcp_polynomial_transformer(npts, kind):
    """GDAL picks order 1 below 6 GCPs and order 2 from 6 on; both are ordinary LSQ."""
    from rasterio.transform import GCPTransformer

    rng = np.random.default_rng(5)
    src = rng.uniform(0, 6000, (npts, 2))
    dst = _poly_truth(src, 2, rng)[0] + rng.normal(0, 2.0, (npts, 2))
    q = rng.uniform(0, 6000, (30, 2))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with GCPTransformer(_gcps(src, dst)) as g:
            xs, ys = g.xy(q[:, 1], q[:, 0], offset="ul")
    ours = fit_transform(kind, src, dst)(q)
    assert np.abs(np.column_stack([xs, ys]) - ours).max() < 1e-4


@pytest.mark.parametrize("kind,sk", [("affine", "AffineTransform"),
                                     ("projective", "ProjectiveTransform"),
                                     ("poly2", 2), ("poly3", 3)])
def test_agrees_with_scikit_image_estimators(kind, sk):
    skt = pytest.importorskip("skimage.transform")
    rng = np.random.default_rng(6)
    src = rng.uniform(0, 1000, (30, 2))
    dst = _truth(kind, src, 7) - [E0, N0]   # keep skimage well conditioned
    if isinstance(sk, int):
        ref = skt.PolynomialTransform.from_estimate(src, dst, order=sk)
    else:
        ref = getattr(skt, sk).from_estimate(src, dst)
    q = rng.uniform(0, 1000, (40, 2))
    assert np.abs(ref(q) - fit_transform(kind, src, dst)(q)).max() < 1e-5
    if isinstance(sk, int):
        return   # skimage's polynomial estimate is algebraic on raw coordinates: noisy fits differ
    # with noise both are least-squares estimates: they differ well below the noise
    noisy = dst + rng.normal(0, 1.0, dst.shape)
    ref = (skt.PolynomialTransform.from_estimate(src, noisy, order=sk) if isinstance(sk, int)
           else getattr(skt, sk).from_estimate(src, noisy))
    assert np.abs(ref(q) - fit_transform(kind, src, noisy)(q)).max() < 0.5


def test_affine_matches_plain_least_squares_with_noise():
    rng = np.random.default_rng(8)
    src = rng.uniform(0, 10000, (20, 2))
    dst = src @ np.array([[2.5, 0.1], [0.05, -2.45]]).T + [E0, N0] + rng.normal(0, 3, (20, 2))
    A = np.column_stack([src, np.ones(20)])
    cx, *_ = np.linalg.lstsq(A, dst[:, 0] - E0, rcond=None)
    cy, *_ = np.linalg.lstsq(A, dst[:, 1] - N0, rcond=None)
    p = fit_transform("affine", src, dst).params
    assert np.allclose(p, np.r_[cx[:2], cx[2] + E0, cy[:2], cy[2] + N0], rtol=1e-9)


@pytest.mark.parametrize("kind", KINDS)
def test_too_few_points_is_a_model_error(kind):
    rng = np.random.default_rng(9)
    src = rng.uniform(0, 100, (min_points(kind) - 1, 2))
    with pytest.raises(ModelError, match="at least"):
        fit_transform(kind, src, src * 2)


def test_degenerate_geometry_is_a_model_error_not_linalg_error():
    t = np.linspace(0, 100, 12)
    line = np.column_stack([t, 2 * t + 1])
    for kind in KINDS:
        with pytest.raises(ModelError, match="collinear|determine"):
            fit_transform(kind, line, line * 3)
    # projective: three of four points on a line
    sq = np.array([[0, 0], [1, 0], [2, 0], [0, 1.0]])
    with pytest.raises(ModelError):
        fit_transform("projective", sq, sq)
    # poly2 on a circle: 1, x², y² are linearly dependent
    a = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    circle = np.column_stack([np.cos(a), np.sin(a)]) * 50 + 100
    with pytest.raises(ModelError, match="conic"):
        fit_transform("poly2", circle, circle)
    with pytest.raises(ModelError):
        fit_transform("affine", [[0, 0], [1, np.nan], [2, 3]], [[0, 0], [1, 1], [2, 3]])
    with pytest.raises(ModelError, match="unknown"):
        fit_transform("spline", line, line)


def test_compare_transforms_honours_icps_and_reports_failures():
    rng = np.random.default_rng(10)
    src = rng.uniform(0, 8000, (12, 2))
    dst = _poly_truth(src, 2, rng)[0] + rng.normal(0, 1, (12, 2))
    icp = np.zeros(12, bool)
    icp[[1, 4, 7]] = True
    reports = compare_transforms(src, dst, icp)
    assert [r.kind for r in reports] == list(KINDS)
    by = {r.kind: r for r in reports}
    assert not by["poly3"].ok and "10" in by["poly3"].error       # 9 GCPs < 10
    r = by["poly2"]
    refit = fit_transform("poly2", src[~icp], dst[~icp])       # ICPs never in the fit
    v = dst - refit(src)
    assert np.allclose(r.residuals, v)
    assert r.rmse_icp == pytest.approx(np.sqrt(np.mean((v[icp] ** 2).sum(axis=1))))
    assert r.rmse_gcp == pytest.approx(np.sqrt(np.mean((v[~icp] ** 2).sum(axis=1))))
    assert (r.n_gcp, r.n_icp) == (9, 3)
    table = format_rmse_table({"left": reports, "right": reports})
    assert "left GCP" in table and "right ICP" in table and "poly3" in table
    assert f"{r.rmse_gcp:.3f}" in table


def test_affine_parameters_match_rasterio_from_gcps():
    from rasterio.transform import from_gcps

    rng = np.random.default_rng(12)
    src = rng.uniform(0, 5000, (12, 2))
    dst = src @ np.array([[2.5, 0.1], [0.05, -2.45]]).T + [E0, N0] + rng.normal(0, 2, (12, 2))
    a = from_gcps(_gcps(src, dst))             # GDAL's least-squares GCPs → geotransform
    p = fit_transform("affine", src, dst).params
    assert np.allclose(p, [a.a, a.b, a.c, a.d, a.e, a.f], rtol=1e-8)
