"""Image-space bias of an RPC (Grodecki & Dial 2003; Fraser & Hanley 2003) and multi-ray
intersection.

A biased model maps ground to image as ``xy = rpc(lon, lat, h) + Δ(xy)``: the bias ``Δ`` is a
function of the image point itself (of the *observed* point in an adjustment, which keeps it
linear in its parameters). With ``u = (x − x0) / 1000`` and ``v = (y − y0) / 1000`` (pixels
from the image's reference point ``(x0, y0)``, in thousands of pixels), the models are

=============== ==== =========================================================================
``none``          0  Δx = 0, Δy = 0
``shift``         2  Δx = a0, Δy = b0  (params ``a0, b0``)
``shift_drift``   3  Δx = a0, Δy = b0 + b2·v  (params ``a0, b0, b2``): the line (along-track)
                     error drifts linearly with the line, i.e. with time — a line-rate or
                     pitch-rate error of a pushbroom image
``affine``        6  Δx = a0 + a1·u + a2·v, Δy = b0 + b1·u + b2·v  (``a0, a1, a2, b0, b1, b2``)
=============== ==== =========================================================================

``a0, b0`` are pixels, the others pixels per 1000 pixels. Ground is (lon°, lat°, ellipsoidal
h m); covariances of ground points are given in metres in the local east-north-up frame.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from prismstation.core.adjustment import lsq
from prismstation.core.models.rpc import Rpc
from prismstation.errors import ModelError

#: bias models and their parameter counts
BIAS_MODELS = {"none": 0, "shift": 2, "shift_drift": 3, "affine": 6}
#: the parameters' names, in their order
BIAS_NAMES = {"none": (), "shift": ("a0", "b0"), "shift_drift": ("a0", "b0", "b2"),
              "affine": ("a0", "a1", "a2", "b0", "b1", "b2")}
#: image-space unit of the bias's linear terms (pixels)
BIAS_UNIT_PX = 1000.0

WGS84_A = 6378137.0
WGS84_E2 = (1.0 / 298.257223563) * (2.0 - 1.0 / 298.257223563)


def metres_per_degree(lat, h=0.0):
    """``(east, north)`` metres per degree of longitude and latitude at ``lat``°, ``h`` m
    (WGS 84 radii of curvature)."""
    s = np.sin(np.radians(lat))
    w = 1.0 - WGS84_E2 * s * s
    n = WGS84_A / np.sqrt(w)
    m = WGS84_A * (1.0 - WGS84_E2) / w ** 1.5
    k = np.pi / 180.0
    return (n + h) * np.cos(np.radians(lat)) * k, (m + h) * k


def bias_design(kind: str, x, y, x0: float = 0.0, y0: float = 0.0) -> np.ndarray:
    """∂(Δx, Δy)/∂params at image points ``(x, y)`` ``(n,)``: ``(n, 2, p)``."""
    if kind not in BIAS_MODELS:
        raise ModelError(f"unknown bias model {kind!r} (one of {', '.join(BIAS_MODELS)})")
    x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
    u, v = (x - x0) / BIAS_UNIT_PX, (y - y0) / BIAS_UNIT_PX
    one, z = np.ones_like(u), np.zeros_like(u)
    cols = {"none": [],
            "shift": [(one, z), (z, one)],
            "shift_drift": [(one, z), (z, one), (z, v)],
            "affine": [(one, z), (u, z), (v, z), (z, one), (z, u), (z, v)]}[kind]
    if not cols:
        return np.zeros(x.shape + (2, 0))
    return np.stack([np.stack(c, axis=-1) for c in cols], axis=-1)


def bias_linear(kind: str, params, x0: float = 0.0, y0: float = 0.0):
    """The bias as ``Δ(xy) = c + M·(xy − xy0)``: constant ``c`` (2,) px and matrix ``M``
    (2, 2) px per px."""
    params = np.asarray(params, float)
    c = bias_design(kind, x0, y0, x0, y0) @ params
    M = np.zeros((2, 2))
    for k, (dx, dy) in enumerate(((BIAS_UNIT_PX, 0.0), (0.0, BIAS_UNIT_PX))):
        M[:, k] = (bias_design(kind, x0 + dx, y0 + dy, x0, y0) @ params - c) / BIAS_UNIT_PX
    return c, M


@dataclass(frozen=True, eq=False)
class BiasedRpc:
    """An RPC with an image-space bias: ``xy = rpc(ground) + Δ(xy)`` (module docstring)."""

    rpc: Rpc
    kind: str = "none"
    params: np.ndarray = None     # (p,)
    x0: float = 0.0               # reference point of the bias (pixels)
    y0: float = 0.0

    def __post_init__(self):
        p = np.zeros(BIAS_MODELS[self.kind]) if self.params is None else np.asarray(self.params, float)
        if p.shape != (BIAS_MODELS.get(self.kind, -1),):
            raise ModelError(f"bias {self.kind!r} takes {BIAS_MODELS.get(self.kind)} parameters, "
                             f"got {p.shape}")
        object.__setattr__(self, "params", p)

    def _linear(self):
        """Δ(xy) = c + M·(xy − xy0): constant ``c`` (2,) and matrix ``M`` (2, 2)."""
        return bias_linear(self.kind, self.params, self.x0, self.y0)

    def bias_at(self, x, y) -> np.ndarray:
        """Δ at image points (the bias evaluated at the observed point): ``(n, 2)``."""
        return bias_design(self.kind, x, y, self.x0, self.y0) @ self.params

    def project(self, lon, lat, h):
        """Ground → image ``(x, y)``, the bias solved exactly (it is linear in xy)."""
        x, y, _ = self.project_with_partials(lon, lat, h, partials=False)
        return x, y

    def project_with_partials(self, lon, lat, h, partials: bool = True):
        """``x, y`` and ``J`` ``(..., 2, 3)`` ∂(x, y)/∂(lon°, lat°, h m) with the bias."""
        if partials:
            xr, yr, J = self.rpc.project_with_partials(lon, lat, h)
        else:
            (xr, yr), J = self.rpc.project(lon, lat, h), None
        c, M = self._linear()
        # xy = r + c + M (xy − xy0)  ⇒  (I − M) xy = r + c − M xy0
        A = np.linalg.inv(np.eye(2) - M)
        bx = xr + c[0] - M[0, 0] * self.x0 - M[0, 1] * self.y0
        by = yr + c[1] - M[1, 0] * self.x0 - M[1, 1] * self.y0
        x, y = A[0, 0] * bx + A[0, 1] * by, A[1, 0] * bx + A[1, 1] * by
        if J is not None:
            J = np.einsum("ij,...jk->...ik", A, J)
        return x, y, J

    def localize(self, x, y, h, **kw):
        """Image ``(x, y)`` at ellipsoidal ``h`` → ``(lon°, lat°)``; raises :class:`ModelError`
        where Newton does not converge (:meth:`Rpc.localize`)."""
        d = self.bias_at(x, y)
        return self.rpc.localize(np.asarray(x, float) - d[..., 0], np.asarray(y, float) - d[..., 1], h, **kw)


def as_biased(model) -> BiasedRpc:
    return model if isinstance(model, BiasedRpc) else BiasedRpc(model)


# ------------------------------------------------------------------------ intersection
@dataclass(frozen=True, eq=False)
class Intersection:
    """Ground points intersected from their rays: ``lon, lat, h`` ``(n,)`` (degrees, ellipsoidal
    metres); ``cov`` ``(n, 3, 3)`` a-priori covariance (from the measurements' σ) in local east,
    north, up metres; ``residuals`` ``(m, 2)`` px observed − computed per observation;
    ``sigma0`` ``(n,)`` per point (NaN without redundancy)."""

    lon: np.ndarray
    lat: np.ndarray
    h: np.ndarray
    cov: np.ndarray
    residuals: np.ndarray
    sigma0: np.ndarray
    iterations: int


def intersect_points(models: Sequence, point, image, xy, sigma, n_points: int | None = None, *,
                     height=None, height_sigma=None, h0=None, tol_m: float = 1e-5,
                     max_iter: int = 30) -> Intersection:
    """Multi-ray intersection of many points at once (Gauss–Newton, 3 unknowns per point).

    ``models`` per image (:class:`Rpc` or :class:`BiasedRpc`); observation ``i`` is point
    ``point[i]`` seen in image ``image[i]`` at ``xy[i]`` px with σ ``sigma[i]`` px (scalar or
    ``(m, 2)``). ``height``/``height_sigma`` ``(n,)`` (NaN = none) add a height observation
    (a reference DEM), which lets a point seen once be placed. Raises :class:`ModelError` when a
    point is undetermined (one ray and no height) or Gauss–Newton does not converge.
    """
    models = [as_biased(m) for m in models]
    point, image = np.asarray(point, int), np.asarray(image, int)
    xy = np.asarray(xy, float).reshape(-1, 2)
    m = len(point)
    sig = np.broadcast_to(np.asarray(sigma, float).reshape(-1, 1) if np.ndim(sigma) == 1
                          else np.asarray(sigma, float), (m, 2))
    n = int(point.max()) + 1 if n_points is None else n_points
    hc = np.full(n, np.nan) if height is None else np.asarray(height, float)
    hs = np.full(n, np.nan) if height_sigma is None else np.asarray(height_sigma, float)
    has_h = np.isfinite(hc) & np.isfinite(hs) & (hs > 0)
    rays = np.bincount(point, minlength=n)
    bad = np.flatnonzero((rays < 2) & ~has_h)
    if bad.size:
        raise ModelError(f"{bad.size} point(s) seen in fewer than 2 images without a height "
                         f"(first: point {bad[0]}); they cannot be intersected")
    # first guess: the first ray at the point's height (or its model's height offset)
    first = np.full(n, -1)
    first[point[::-1]] = np.arange(m)[::-1]
    lon, lat, h = np.zeros(n), np.zeros(n), np.zeros(n)
    for k, mod in enumerate(models):
        sel = np.flatnonzero(image[first] == k)
        if sel.size:
            hh = np.where(has_h[sel], hc[sel], mod.rpc.h_off if h0 is None else h0)
            o = first[sel]
            lon[sel], lat[sel] = mod.localize(xy[o, 0], xy[o, 1], hh)
            h[sel] = hh
    w = 1.0 / sig ** 2
    for it in range(1, max_iter + 1):
        v, Jm = _rays(models, point, image, xy, lon, lat, h)
        N = np.zeros((n, 3, 3))
        r = np.zeros((n, 3))
        np.add.at(N, point, np.einsum("mai,ma,maj->mij", Jm, w, Jm))
        np.add.at(r, point, np.einsum("mai,ma,ma->mi", Jm, w, v))
        N[has_h, 2, 2] += 1.0 / hs[has_h] ** 2
        r[has_h, 2] += (hc[has_h] - h[has_h]) / hs[has_h] ** 2
        Q = _inv3(N)
        d = np.einsum("nij,nj->ni", Q, r)
        ke, kn = metres_per_degree(lat, h)
        lon, lat, h = lon + d[:, 0] / ke, lat + d[:, 1] / kn, h + d[:, 2]
        if np.max(np.abs(d), initial=0.0) < tol_m:
            break
    else:
        raise ModelError(f"intersection did not converge in {max_iter} iterations "
                         f"(largest step {np.max(np.abs(d)):.3g} m)")
    v, _ = _rays(models, point, image, xy, lon, lat, h)
    ssr = np.bincount(point, (w * v * v).sum(1), minlength=n)
    ssr[has_h] += ((hc[has_h] - h[has_h]) / hs[has_h]) ** 2
    dof = 2 * rays + has_h - 3
    with np.errstate(invalid="ignore", divide="ignore"):
        s0 = np.where(dof > 0, np.sqrt(ssr / np.maximum(dof, 1)), np.nan)
    return Intersection(lon, lat, h, Q, v, s0, it)


def intersect(models: Sequence, xy, sigma=0.5, **kw) -> Intersection:
    """One point seen in ``len(models)`` images at ``xy`` ``(k, 2)`` px (σ px): its ground
    point, 3 × 3 covariance in ENU metres and residuals (as :func:`intersect_points`)."""
    xy = np.asarray(xy, float).reshape(-1, 2)
    k = len(xy)
    return intersect_points(models, np.zeros(k, int), np.arange(k), xy,
                            np.broadcast_to(np.asarray(sigma, float), (k,)), 1, **kw)


def _rays(models, point, image, xy, lon, lat, h):
    """Residuals observed − computed ``(m, 2)`` px and ∂(x, y)/∂(E, N, U) ``(m, 2, 3)`` px/m,
    the bias evaluated at the observed points."""
    m = len(point)
    v = np.zeros((m, 2))
    J = np.zeros((m, 2, 3))
    for k, mod in enumerate(models):
        sel = np.flatnonzero(image == k)
        if not sel.size:
            continue
        p = point[sel]
        x, y, Jd = mod.rpc.project_with_partials(lon[p], lat[p], h[p])
        d = mod.bias_at(xy[sel, 0], xy[sel, 1])
        v[sel, 0] = xy[sel, 0] - d[:, 0] - x
        v[sel, 1] = xy[sel, 1] - d[:, 1] - y
        ke, kn = metres_per_degree(lat[p], h[p])
        J[sel] = Jd / np.stack([ke, kn, np.ones_like(ke)], axis=-1)[:, None, :]
    return v, J


def _inv3(N):
    """Inverse of a stack of symmetric 3 × 3 matrices, refusing singular ones."""
    det = np.linalg.det(N)
    scale = np.einsum("nii->n", N) ** 3
    if np.any(~(np.abs(det) > 1e-12 * scale)):
        i = int(np.flatnonzero(~(np.abs(det) > 1e-12 * scale))[0])
        raise ModelError(f"point {i}: its rays do not determine it (parallel rays or too few)")
    return np.linalg.inv(N)


@dataclass(frozen=True, eq=False)
class RpcBias:
    """A view's fitted image-space bias (:mod:`~prismstation.core.models.rpc_bias`): ``model`` its
    name, ``params`` ``(p,)`` (``a0, b0`` px, the others px per 1,000 px), ``cov`` ``(p, p)``,
    ``x0, y0`` its reference point (px); ``fixed`` the view is the datum, held at zero bias;
    ``lsq`` this view's share of the adjustment (its observations' residuals, redundancy
    numbers and studentised residuals; the adjustment's σ0 and dof)."""

    model: str = "none"
    params: np.ndarray = None
    cov: np.ndarray = None
    x0: float = 0.0
    y0: float = 0.0
    fixed: bool = False
    lsq: lsq.LsqResult | None = None

    def __post_init__(self):
        p = BIAS_MODELS[self.model]
        object.__setattr__(self, "params", np.zeros(p) if self.params is None else np.asarray(self.params, float))
        object.__setattr__(self, "cov", np.zeros((p, p)) if self.cov is None else np.asarray(self.cov, float))

    @property
    def names(self) -> tuple:
        return BIAS_NAMES[self.model]

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.cov), 0.0, None))

    @property
    def sigma0(self) -> float | None:
        return None if self.lsq is None else self.lsq.sigma0

    @property
    def dof(self) -> int:
        return 0 if self.lsq is None else self.lsq.dof

    @property
    def reference_px(self) -> tuple[float, float]:
        """``(x0, y0)`` px: the image point the parameters ``a0, b0`` are the bias at."""
        return float(self.x0), float(self.y0)

    def biased(self, rpc: Rpc) -> BiasedRpc:
        return BiasedRpc(rpc, self.model, self.params, self.x0, self.y0)

    @property
    def M(self) -> np.ndarray:
        """``(2, 2)``: the bias written as ``Δxy = M·xy + b`` (px per px)."""
        return bias_linear(self.model, self.params, self.x0, self.y0)[1]

    @property
    def b(self) -> np.ndarray:
        """``(2,)`` px: the constant of ``Δxy = M·xy + b``."""
        c, M = bias_linear(self.model, self.params, self.x0, self.y0)
        return c - M @ np.array([self.x0, self.y0])
