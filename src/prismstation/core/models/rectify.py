"""2-D image → map transforms for single-image rectification (docs/model.md §4; Subaryono et al., AVNIR).

Every transform maps image coordinates ``(x, y)`` (column, row, pixels, origin at the
top-left corner of the top-left pixel) to map coordinates ``(X, Y)`` (metres, projected CRS).
All follow the estimator protocol of :mod:`prismstation.core.adjustment.estimate`:

- ``FittedTransform.fit(src, dst, kind)`` → a fitted, immutable transform, or a falsy
  :class:`~prismstation.core.adjustment.estimate.FailedFit` with the reason; ``fit_transform(kind, src,
  dst)`` raises :class:`~prismstation.errors.DegenerateGeometry` (too few points, collinear,
  nearly collinear or otherwise degenerate geometry) or :class:`ModelError` instead;
- ``t(xy)`` forward, ``t.inverse(XY)`` backward (closed form or Newton iterations);
- ``t.residuals(src, dst)`` observed − computed ``dst − t(src)`` in map units;
- ``t.params`` in the published form of the paper, ``t.cov`` their covariance,
  ``t.sigma0`` (map units), ``t.dof``, ``t.rmse`` (planimetric, over the fitting points).

Kinds: ``affine`` (6 parameters, ≥3 points), ``projective`` (8, ≥4), ``poly1``–``poly3``
(polynomials of total degree 1–3 with terms ``1, x, y, x², xy, y², x³, x²y, xy², y³`` — GDAL's
order; 3, 6, 10 points). Solved by least squares after centring and scaling both point sets.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from math import comb

import numpy as np
from scipy.optimize import least_squares

from prismstation.core.adjustment.estimate import (Normaliser, check_points, check_spread, condition_number,
                                        degenerate, failure_or)
from prismstation.errors import ModelError

KINDS = ("affine", "projective", "poly1", "poly2", "poly3")
_RCOND = 1e-9


def _as_points(a, name: str) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.ndim != 2 or a.shape[1] != 2:
        raise ModelError(f"{name} must be an (n, 2) array of points, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ModelError(f"{name} contains non-finite coordinates")
    return a


def poly_exponents(degree: int) -> list[tuple[int, int]]:
    """Exponents ``(i, j)`` of the terms ``x^i·y^j`` of total degree ≤ ``degree`` (GDAL order)."""
    return [(d - j, j) for d in range(degree + 1) for j in range(d + 1)]


def _monomials(u: np.ndarray, exps) -> np.ndarray:
    return np.stack([u[:, 0] ** i * u[:, 1] ** j for i, j in exps], axis=1)


def _monomial_jac(u: np.ndarray, exps) -> tuple[np.ndarray, np.ndarray]:
    dx = np.stack([i * u[:, 0] ** max(i - 1, 0) * u[:, 1] ** j for i, j in exps], axis=1)
    dy = np.stack([j * u[:, 0] ** i * u[:, 1] ** max(j - 1, 0) for i, j in exps], axis=1)
    return dx, dy


def _raw_basis_map(exps, c: np.ndarray, s: float) -> np.ndarray:
    """Matrix ``L`` with ``φ_k((p − c)/s) = Σ_m L[k, m]·φ_m(p)`` (binomial expansion)."""
    index = {e: k for k, e in enumerate(exps)}
    L = np.zeros((len(exps), len(exps)))
    for k, (i, j) in enumerate(exps):
        for a in range(i + 1):
            for b in range(j + 1):
                coef = comb(i, a) * (-c[0]) ** (i - a) * comb(j, b) * (-c[1]) ** (j - b)
                L[k, index[(a, b)]] += coef / s ** (i + j)
    return L


@dataclass(frozen=True, eq=False)
class FittedTransform:
    """A transform fitted to ``n`` control points; immutable.

    Attributes
    ----------
    kind : one of :data:`KINDS`.
    params : (u,) parameters in the published (un-normalised) form:
        affine ``[a1, a2, a3, b1, b2, b3]`` with ``X = a1·x + a2·y + a3``, ``Y = b1·x + b2·y + b3``;
        projective ``[a1, a2, a3, a4, a5, a6, c1, c2]`` (Subaryono et al.'s equations);
        polyN ``[A_0..A_{m−1}, B_0..B_{m−1}]`` for the terms of :func:`poly_exponents`.
    cov : (u, u) covariance of ``params`` (σ0²-scaled; NaN without redundancy).
    sigma0 : a-posteriori standard deviation of one map coordinate (metres), NaN if dof = 0.
    n_points, dof : number of fitting points and redundancy ``2n − u``.
    fit_residuals : (n, 2) observed − computed at the fitting points (metres).
    """

    kind: str
    params: np.ndarray
    cov: np.ndarray
    sigma0: float
    n_points: int
    dof: int
    fit_residuals: np.ndarray
    _p: np.ndarray = field(repr=False)        # parameters in normalised space
    _src: Normaliser = field(repr=False)
    _dst: Normaliser = field(repr=False)

    @classmethod
    def fit(cls, src, dst, kind: str = "affine"):
        """:func:`fit_transform` returning a falsy :class:`~prismstation.core.adjustment.estimate.FailedFit`
        with the reason instead of raising."""
        return failure_or(fit_transform, kind, src, dst)

    @property
    def n_params(self) -> int:
        return int(self.params.size)

    @property
    def rmse(self) -> float:
        """Planimetric RMSE ``sqrt(mean(vX² + vY²))`` over the fitting points (metres)."""
        return float(np.sqrt(np.mean((self.fit_residuals ** 2).sum(axis=1))))

    @property
    def std(self) -> np.ndarray:
        """(u,) standard deviations of :attr:`params`."""
        return np.sqrt(np.diag(self.cov))

    # -- evaluation -------------------------------------------------------------------------
    def _fwd_norm(self, u: np.ndarray) -> np.ndarray:
        p = self._p
        if self.kind == "projective":
            den = p[6] * u[:, 0] + p[7] * u[:, 1] + 1.0
            return np.stack([(p[0] * u[:, 0] + p[1] * u[:, 1] + p[2]) / den,
                             (p[3] * u[:, 0] + p[4] * u[:, 1] + p[5]) / den], axis=1)
        exps = _exps(self.kind)
        m = len(exps)
        phi = _monomials(u, exps)
        return np.stack([phi @ p[:m], phi @ p[m:]], axis=1)

    def __call__(self, xy) -> np.ndarray:
        """Map ``(n, 2)`` image points ``(x, y)`` to ``(n, 2)`` map points ``(X, Y)``."""
        xy = np.atleast_2d(np.asarray(xy, float))
        return self._dst.back(self._fwd_norm(self._src.fwd(xy)))

    def inverse(self, XY, *, iterations: int = 20, tol: float = 1e-10) -> np.ndarray:
        """Map ``(n, 2)`` map points to image points; closed form for affine / projective,
        Newton iterations from the affine part for polynomials (NaN where they diverge)."""
        v = self._dst.fwd(np.atleast_2d(np.asarray(XY, float)))
        p = self._p
        if self.kind in ("affine", "poly1", "projective"):
            if self.kind == "projective":
                H = np.array([[p[0], p[1], p[2]], [p[3], p[4], p[5]], [p[6], p[7], 1.0]])
            else:  # internal terms 1, x, y
                H = np.array([[p[1], p[2], p[0]], [p[4], p[5], p[3]], [0, 0, 1.0]])
            h = np.column_stack([v, np.ones(len(v))]) @ np.linalg.inv(H).T
            return self._src.back(h[:, :2] / h[:, 2:3])
        exps = _exps(self.kind)
        m = len(exps)
        A = np.array([[p[1], p[2]], [p[m + 1], p[m + 2]]])   # linear part (terms x, y)
        u = (v - np.array([p[0], p[m]])) @ np.linalg.inv(A).T
        active = np.all(np.isfinite(u), axis=1)
        for _ in range(iterations):
            idx = np.nonzero(active)[0]
            if idx.size == 0:
                break
            ua = u[idx]
            f = self._fwd_norm(ua) - v[idx]
            dx, dy = _monomial_jac(ua, exps)
            a, b = dx @ p[:m], dy @ p[:m]
            c, d = dx @ p[m:], dy @ p[m:]
            with np.errstate(all="ignore"):
                det = a * d - b * c
                sx = (d * f[:, 0] - b * f[:, 1]) / det
                sy = (a * f[:, 1] - c * f[:, 0]) / det
            u[idx, 0] -= sx
            u[idx, 1] -= sy
            with np.errstate(invalid="ignore"):
                done = (np.abs(sx) < tol) & (np.abs(sy) < tol)
                lost = ~np.isfinite(sx) | ~np.isfinite(sy) | (np.abs(ua).max(axis=1) > 1e6)
            active[idx[done | lost]] = False
        with np.errstate(invalid="ignore", over="ignore"):
            bad = ~np.all(np.abs(self._fwd_norm(u) - v) < 1e-6, axis=1)
        u[bad] = np.nan
        return self._src.back(u)

    def residuals(self, src, dst) -> np.ndarray:
        """(n, 2) observed − computed: ``dst − self(src)`` in map units."""
        return np.asarray(dst, float) - self(src)


def _exps(kind: str):
    return poly_exponents(1 if kind == "affine" else int(kind[4:]))


def n_params(kind: str) -> int:
    """Number of parameters of a transform kind."""
    if kind not in KINDS:
        raise ModelError(f"unknown transform {kind!r}; choose one of {', '.join(KINDS)}")
    return 8 if kind == "projective" else 2 * len(_exps(kind))


def min_points(kind: str) -> int:
    """Minimum number of control points a transform kind needs."""
    return (n_params(kind) + 1) // 2


def _check_geometry(u: np.ndarray, kind: str, n: int) -> None:
    """Too few points, or points (nearly) on a line: every kind has an affine part."""
    check_points(n, min_points(kind), f"{kind} transform", "control points")
    check_spread(u, f"{kind} transform", "control points")


def _check_design(A: np.ndarray, kind: str, why: str) -> None:
    """The full design singular (beyond the affine part): the points do not determine it."""
    k = condition_number(A)
    if not k < 1 / _RCOND:
        raise degenerate(f"{kind} transform: the control points do not determine its "
                         f"{n_params(kind)} parameters ({why}; condition number {k:.3g})", k)


def fit_transform(kind: str, src, dst) -> FittedTransform:
    """Fit a transform ``kind`` mapping image points ``src`` (n, 2) to map points ``dst`` (n, 2).

    Raises
    ------
    DegenerateGeometry
        Too few points, points on or nearly on a line (condition number of the normalised
        ``[1, x, y]`` above :data:`~prismstation.core.adjustment.estimate.MAX_CONDITION`), or a
        configuration that does not determine the parameters (e.g. poly2 on a conic).
    ModelError
        Unknown kind, non-finite input, mismatched point counts.
    """
    u_count = n_params(kind)
    src = _as_points(src, "image points")
    dst = _as_points(dst, "map points")
    if len(src) != len(dst):
        raise ModelError(f"{len(src)} image points but {len(dst)} map points")
    ns, nd = Normaliser.of(src), Normaliser.of(dst)
    u, v = ns.fwd(src), nd.fwd(dst)
    n = len(src)
    _check_geometry(u, kind, n)
    if kind == "projective":
        p, J = _fit_projective(u, v)
    else:
        exps = _exps(kind)
        Phi = _monomials(u, exps)
        _check_design(Phi, kind, "points on a line or a conic")
        coef, *_ = np.linalg.lstsq(Phi, v, rcond=None)
        p = np.concatenate([coef[:, 0], coef[:, 1]])
        J = np.zeros((2 * n, u_count))
        m = len(exps)
        J[:n, :m], J[n:, m:] = Phi, Phi
    model = FittedTransform(kind, p, np.empty(0), np.nan, n, 2 * n - u_count,
                            np.empty((0, 2)), p, ns, nd)
    res = dst - model(src)
    dof = 2 * n - u_count
    sigma0 = float(np.sqrt((res ** 2).sum() / dof)) if dof > 0 else float("nan")
    # covariance of normalised parameters, in normalised map units, then to published form
    Jinv = np.linalg.pinv(J.T @ J)
    cov_n = Jinv * (sigma0 / nd.scale) ** 2 if dof > 0 else np.full_like(Jinv, np.nan)
    T, offset = _published_map(kind, p, ns, nd)
    params = T @ p + offset
    cov = T @ cov_n @ T.T
    return FittedTransform(kind, params, cov, sigma0, n, dof, res, p, ns, nd)


def _fit_projective(u: np.ndarray, v: np.ndarray):
    """Linear (DLT) start then Gauss–Newton on the geometric residuals, normalised space."""
    n = len(u)
    x, y, X, Y = u[:, 0], u[:, 1], v[:, 0], v[:, 1]
    A = np.zeros((2 * n, 8))
    A[:n, 0], A[:n, 1], A[:n, 2], A[:n, 6], A[:n, 7] = x, y, 1, -x * X, -y * X
    A[n:, 3], A[n:, 4], A[n:, 5], A[n:, 6], A[n:, 7] = x, y, 1, -x * Y, -y * Y
    _check_design(A, "projective", "three of four points on a line?")
    p0, *_ = np.linalg.lstsq(A, np.concatenate([X, Y]), rcond=None)

    def resid(p):
        den = p[6] * x + p[7] * y + 1.0
        return np.concatenate([(p[0] * x + p[1] * y + p[2]) / den - X,
                               (p[3] * x + p[4] * y + p[5]) / den - Y])

    sol = least_squares(resid, p0, method="lm" if 2 * n >= 8 else "trf", xtol=1e-14, ftol=1e-14)
    p = sol.x
    den = p[6] * x + p[7] * y + 1.0
    if np.any(np.sign(den) != np.sign(den[0])):
        raise ModelError("projective transform: the horizon line crosses the control points")
    return p, sol.jac


def _published_map(kind, p, ns: Normaliser, nd: Normaliser):
    """Linear map ``params = T·p + offset`` (Jacobian for the projective case)."""
    cs, ss, cd, sd = ns.centre, ns.scale, nd.centre, nd.scale
    if kind == "projective":
        # X = sd·(p0 u + p1 v + p2)/(p6 u + p7 v + 1) + cd with u = (x − cs)/ss: homography
        # composition; derivative taken numerically (8 parameters, smooth).
        def pub(q):
            Hn = np.array([[q[0], q[1], q[2]], [q[3], q[4], q[5]], [q[6], q[7], 1.0]])
            Ns = np.array([[1 / ss, 0, -cs[0] / ss], [0, 1 / ss, -cs[1] / ss], [0, 0, 1]])
            Nd = np.array([[sd, 0, cd[0]], [0, sd, cd[1]], [0, 0, 1]])
            H = Nd @ Hn @ Ns
            H = H / H[2, 2]
            return np.array([H[0, 0], H[0, 1], H[0, 2], H[1, 0], H[1, 1], H[1, 2], H[2, 0], H[2, 1]])
        f0 = pub(p)
        T = np.empty((8, 8))
        for k in range(8):
            h = 1e-7 * max(1.0, abs(p[k]))
            dp = np.zeros(8)
            dp[k] = h
            T[:, k] = (pub(p + dp) - pub(p - dp)) / (2 * h)
        return T, f0 - T @ p
    exps = _exps(kind)
    m = len(exps)
    L = _raw_basis_map(exps, cs, ss)         # φ_norm = L φ_raw  →  raw coef = sd·Lᵀ a
    T = np.zeros((2 * m, 2 * m))
    T[:m, :m] = T[m:, m:] = sd * L.T
    offset = np.zeros(2 * m)
    offset[0], offset[m] = cd
    if kind == "affine":   # published [a1, a2, a3, b1, b2, b3]: terms reordered x, y, 1
        order = [1, 2, 0, 4, 5, 3]
        return T[order], offset[order]
    return T, offset


# -- side-by-side comparison with check points (Subaryono et al., Table 4.1) --------------------------

@dataclass(frozen=True, eq=False)
class TransformReport:
    """One transform fitted on the GCPs and evaluated on GCPs and ICPs.

    ``residuals`` (n, 2) are observed − computed for every point in input order (metres; NaN
    if the fit failed); RMSEs are planimetric ``sqrt(mean(vX² + vY²))`` per point kind (NaN
    when there is no such point). ``error`` holds the reason when the fit failed.
    """

    kind: str
    n_params: int
    n_gcp: int
    n_icp: int
    transform: FittedTransform | None
    residuals: np.ndarray
    rmse_gcp: float
    rmse_icp: float
    rmse_gcp_xy: tuple[float, float]
    rmse_icp_xy: tuple[float, float]
    error: str | None = None

    @property
    def ok(self) -> bool:
        return self.error is None


def _rms(v: np.ndarray) -> tuple[float, tuple[float, float]]:
    if len(v) == 0:
        return float("nan"), (float("nan"), float("nan"))
    rx, ry = np.sqrt(np.mean(v ** 2, axis=0))
    return float(np.hypot(rx, ry)), (float(rx), float(ry))


def compare_transforms(src, dst, is_check=None, kinds=KINDS) -> tuple[TransformReport, ...]:
    """Fit every transform of ``kinds`` on the GCPs and report residuals on GCPs and ICPs.

    Parameters
    ----------
    src, dst : (n, 2) image points (x, y pixels) and map points (X, Y metres).
    is_check : (n,) bool, True for independent check points (never used in a fit).

    A transform that cannot be fitted (too few GCPs, degenerate geometry) gets a report with
    its ``error`` set instead of raising.
    """
    src = _as_points(src, "image points")
    dst = _as_points(dst, "map points")
    icp = np.zeros(len(src), bool) if is_check is None else np.asarray(is_check, bool)
    gcp = ~icp
    out = []
    for kind in kinds:
        t = FittedTransform.fit(src[gcp], dst[gcp], kind)
        if not t:
            nan = np.full(src.shape, np.nan)
            out.append(TransformReport(kind, n_params(kind), int(gcp.sum()), int(icp.sum()),
                                       None, nan, float("nan"), float("nan"),
                                       (float("nan"),) * 2, (float("nan"),) * 2, t.reason))
            continue
        v = t.residuals(src, dst)
        rg, rgxy = _rms(v[gcp])
        ri, rixy = _rms(v[icp])
        out.append(TransformReport(kind, t.n_params, int(gcp.sum()), int(icp.sum()), t, v,
                                   rg, ri, rgxy, rixy))
    return tuple(out)


def format_rmse_table(reports_by_image: dict) -> str:
    """Plain-text table: one row per transform, GCP and ICP RMSE (metres) per image.

    ``reports_by_image`` maps an image name to the output of :func:`compare_transforms`.
    """
    names = list(reports_by_image)
    head = f"{'transform':<12}{'u':>3}" + "".join(f"{n + ' GCP':>16}{n + ' ICP':>16}" for n in names)
    lines = [head, "-" * len(head)]
    kinds = [r.kind for r in next(iter(reports_by_image.values()))] if names else []
    for i, kind in enumerate(kinds):
        row = f"{kind:<12}{n_params(kind):>3}"
        notes = []
        for n in names:
            r = reports_by_image[n][i]
            if r.ok:
                row += "".join(f"{v:>14.3f} m" if np.isfinite(v) else f"{'—':>16}"
                               for v in (r.rmse_gcp, r.rmse_icp))
            else:
                row += f"{'—':>16}{'—':>16}"
                notes.append(f"{n}: {r.error}")
        lines.append(row + ("   (" + "; ".join(notes) + ")" if notes else ""))
    return "\n".join(lines)
