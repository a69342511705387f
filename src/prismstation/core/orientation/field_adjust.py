"""One adjustment of the DEM orientation's shift field from every matched cell of every patch.

The relative DEMs of the patches (``prismstation.ops.orient_dem``) are cells ``c`` placed on
the map by the ancillary N model at ``(e_c, n_c)`` with a relative height ``h_c`` (smoothed
like the reference). The truth is the cell moved by the shift field ``s(x, y) = (dE, dN, dh)``,
a function of the cell's N-image position ``(x_c, y_c)``: per component ``θ_k0 + θ_ku·u +
θ_kv·v`` over normalised coordinates ``(u, v)`` (:class:`Basis`; a component may keep its
constant only; :mod:`prismstation.core.orientation.field_model`). Each cell observes

    f_c = R(e_c + dE − oE, n_c + dN − oN) + oh − (h_c + dh)  ≈ 0,

``R`` the reference DEM (:class:`Surface`) and ``o`` the reference's own offset from the
ground control's frame (estimated only when GCPs observe the field directly,
:class:`FieldObs`; otherwise the field is relative to the reference's frame). Gauss–Newton on
all cells at once, so that every slope direction of the scene contributes and a patch too
flat to fix its shift alone still gives what it has.

Weights and robustness. Per patch, cells beyond ``k``·NMAD of the patch's median residual are
left out; the others weigh ``1 / (s_p²·A_p)``: ``s_p`` the patch's NMAD, ``A_p`` the
correlation area of its residuals (:func:`prismstation.core.matching.coreg.correlation_area`), so that
correlated neighbours count as the independent cells they are worth. What the cells' noise
does not explain — each patch's relative DEM and the reference differing by a shift of their
own (the reference's errors correlated over kilometres, attitude that is not affine) — is a
random shift ``b_p ~ N(0, Σ_b)`` per patch, ``Σ_b`` diagonal (E, N, h), estimated from the data
by restricted maximum likelihood (EM) and eliminated from the normal equations patch by patch
(:mod:`prismstation.core.orientation.field_stats` holds these patch-level steps: the variance
components, each patch's test against the others with its full 3 × 3 information, and the
jackknife).

A prior ``θ ~ N(0, diag(prior_sigma²))`` (the a-priori geolocation σ) keeps the solution
defined on terrain that fixes nothing (a plane): its σ then says so.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from prismstation.core.matching.coreg import correlation_area
from prismstation.core.orientation.field_model import Basis, Distortion, Surface
from prismstation.core.adjustment.stats import nmad

COMPONENTS = ("E", "N", "h")
#: cells beyond this many NMAD of their patch's median residual are left out
K_OUTLIER = 3.0
#: smallest residual spread (m) a patch is credited with (a perfect match is not infinite weight)
MIN_SPREAD_M = 0.05
#: Gauss–Newton stops when no part of the field moves by more than this (m) over the image
TOL_M = 1e-3
#: Gauss–Newton that has not settled within its iterations still counts as converged when its
#: last step is below this share of the σ the cells' shared relief gives (:func:`signal_share`)
JITTER = 0.1


@dataclass(frozen=True)
class Cells:
    """Matched cells, ``(m,)`` arrays: N-image position ``x, y`` (px), ancillary map position
    ``e, n`` (m), relative height ``h`` (m), ``patch`` index, and ``row, col`` on a common grid
    (for the residuals' spatial correlation). Sorted by patch."""

    x: np.ndarray
    y: np.ndarray
    e: np.ndarray
    n: np.ndarray
    h: np.ndarray
    patch: np.ndarray
    row: np.ndarray
    col: np.ndarray

    @classmethod
    def join(cls, parts) -> "Cells":
        """One set from per-patch dicts of the fields above (``patch`` may be a scalar)."""
        cat = {k: np.concatenate([np.broadcast_to(np.asarray(p[k]), np.shape(p["h"])) for p in parts])
               if parts else np.zeros(0) for k in cls.__dataclass_fields__}
        order = np.argsort(cat["patch"], kind="stable")
        return cls(**{k: v[order].astype(int if k in ("patch", "row", "col") else float)
                      for k, v in cat.items()})

    def __len__(self) -> int:
        return int(self.h.size)

    def take(self, keep: np.ndarray) -> "Cells":
        return Cells(*(getattr(self, k)[keep] for k in self.__dataclass_fields__))


@dataclass(frozen=True)
class FieldObs:
    """Direct observations of the field (GCPs): component ``comp`` (0 E, 1 N, 2 h) of the
    shift at N position ``x, y`` is ``value`` ± ``sigma`` (m), in the ground control's frame."""

    x: np.ndarray
    y: np.ndarray
    comp: np.ndarray
    value: np.ndarray
    sigma: np.ndarray
    ids: tuple = ()

    def __len__(self) -> int:
        return int(np.size(self.value))


@dataclass
class PatchSums:
    """What each patch's cells add to the normal equations at the current parameters
    (``P`` patches, ``u`` unknowns): ``N`` (P, u, u) and ``b`` (P, u) for the parameters,
    ``I`` (P, 3, 3) and ``h`` (P, 3) for the patch's own shift, ``B`` (P, 3, u) the cross terms
    (all with ``+Jᵀ W f`` on the right, i.e. the step solves ``N Δ = −b``); per patch the cells
    used, their NMAD ``spread`` (m), correlation area ``area`` (cells) and ``ssr`` (Σ w f²)."""

    N: np.ndarray
    b: np.ndarray
    I: np.ndarray
    h: np.ndarray
    B: np.ndarray
    used: np.ndarray
    spread: np.ndarray
    area: np.ndarray
    ssr: np.ndarray
    inlier: np.ndarray = field(default=None)


def _unknowns(basis: Basis, free_offset, n_dist: int = 0) -> np.ndarray:
    """``(12 + n_dist,)`` bool: the field's estimated terms, the reference offset's free
    components (``free_offset``: a bool for all three, or (3,) bools), then the height
    distortion's ``n_dist`` terms (:class:`Distortion`)."""
    return np.r_[basis.active, np.broadcast_to(np.asarray(free_offset, bool), (3,)), np.ones(n_dist, bool)]


def _psi(distortion, x, y) -> np.ndarray:
    return np.zeros(np.shape(x) + (0,)) if distortion is None else distortion.psi(x, y)


def residuals(cells: Cells, surface: Surface, basis: Basis, theta, offset=(0.0, 0.0, 0.0),
              distortion: Distortion | None = None, delta=()):
    """``f`` (m,) and the reference gradients ``gx, gy`` at the moved cells (NaN where the
    reference has none); ``delta`` the height distortion's terms (:class:`Distortion`)."""
    s = basis.predict(theta, cells.x, cells.y)
    o = np.asarray(offset, float)
    r, gx, gy = surface.sample(cells.e + s[:, 0] - o[0], cells.n + s[:, 1] - o[1])
    dist = _psi(distortion, cells.x, cells.y) @ np.asarray(delta, float) if len(delta) else 0.0
    return r + o[2] - cells.h - s[:, 2] - dist, gx, gy


def accumulate(cells: Cells, surface: Surface, basis: Basis, theta, offset, n_patches: int,
               free_offset=False, k_outlier: float = K_OUTLIER,
               areas: np.ndarray | None = None, frozen: PatchSums | None = None,
               own_gradients: tuple | None = None, distortion: Distortion | None = None,
               delta=()) -> PatchSums:
    """The patches' sums (:class:`PatchSums`) at ``theta`` (9,), ``offset`` (3,) and the height
    distortion's terms ``delta`` (``distortion``, :class:`Distortion`).
    ``areas``: correlation areas to use (default: measured from the residuals here);
    ``frozen``: earlier sums whose inlier cells, spreads and areas are kept (the weights fixed,
    so that Gauss–Newton minimises one objective: cells at the outlier bound flipping in and
    out made it cycle). ``own_gradients``: the cells' own gradients ``(gx, gy)`` (m,) (their
    relative DEM's, :func:`cell_gradients`); given, the reference's gradients in the sums are
    scaled per patch by ``√ρ_p`` (:func:`signal_share`) — for the covariance, not for steps."""
    f, gx, gy = residuals(cells, surface, basis, theta, offset, distortion, delta)
    psi = _psi(distortion, cells.x, cells.y)
    act = _unknowns(basis, free_offset, psi.shape[-1])
    u = int(act.sum())
    P = n_patches
    out = PatchSums(np.zeros((P, u, u)), np.zeros((P, u)), np.zeros((P, 3, 3)), np.zeros((P, 3)),
                    np.zeros((P, 3, u)), np.zeros(P, int), np.full(P, np.nan), np.ones(P), np.zeros(P),
                    np.zeros(len(cells), bool))
    phi = basis.phi(cells.x, cells.y)
    bounds = np.searchsorted(cells.patch, np.arange(P + 1))
    for p in range(P):
        sl = slice(bounds[p], bounds[p + 1])
        fp = f[sl]
        ok = np.isfinite(fp) & np.isfinite(gx[sl]) & np.isfinite(gy[sl])
        if ok.sum() < 10:
            continue
        if frozen is not None:
            ok &= frozen.inlier[sl]
            if ok.sum() < 10 or not frozen.used[p]:
                continue
            spread, area = float(frozen.spread[p]), float(frozen.area[p])
        else:
            # the cells' noise is what is left about the patch's OWN best shift: residuals about
            # the field alone also hold the patch's shift, which Σ_b is there to describe
            gp = np.column_stack([gx[sl], gy[sl], -np.ones(fp.size)])
            e = _about_own_shift(gp, fp, ok)
            spread = max(nmad(e[ok]), MIN_SPREAD_M)
            ok &= np.abs(e - np.median(e[ok])) <= k_outlier * spread
            if ok.sum() < 10:
                continue
            e = _about_own_shift(gp, fp, ok)
            spread = max(nmad(e[ok]), MIN_SPREAD_M)
            if areas is None or not np.isfinite(areas[p]):
                area = _area(cells, sl, np.where(ok, e, np.nan))
            else:
                area = float(areas[p])
        w = 1.0 / (spread ** 2 * area)
        ph = phi[sl][ok]
        k = 1.0
        if own_gradients is not None:
            k = np.sqrt(signal_share(gx[sl][ok], gy[sl][ok], own_gradients[0][sl][ok], own_gradients[1][sl][ok]))
        g = np.column_stack([k * gx[sl][ok], k * gy[sl][ok], -np.ones(ok.sum())])  # the patch's shift
        J = np.column_stack([g[:, :1] * ph, g[:, 1:2] * ph, -ph, -g, -psi[sl][ok]])[:, act]   # the parameters
        fo = fp[ok]
        out.N[p], out.b[p] = w * J.T @ J, w * J.T @ fo
        out.I[p], out.h[p], out.B[p] = w * g.T @ g, w * g.T @ fo, w * g.T @ J
        out.used[p], out.spread[p], out.area[p], out.ssr[p] = ok.sum(), spread, area, w * float(fo @ fo)
        out.inlier[np.arange(sl.start, sl.stop)[ok]] = True
    return out


def cell_gradients(cells: "Cells", posting: float) -> tuple[np.ndarray, np.ndarray]:
    """The gradients ``(∂h/∂E, ∂h/∂N)`` (m,) of the cells' own relative DEMs, patch by patch on
    their grid (``row``, ``col``; cells ``posting`` m apart); NaN at a void's or a patch's edge."""
    gx, gy = np.full(len(cells), np.nan), np.full(len(cells), np.nan)
    bounds = np.searchsorted(cells.patch, np.arange(int(cells.patch.max(initial=-1)) + 2))
    for a, b in zip(bounds[:-1], bounds[1:]):
        if b - a < 9:
            continue
        r, c = cells.row[a:b] - cells.row[a:b].min(), cells.col[a:b] - cells.col[a:b].min()
        grid = np.full((r.max() + 1, c.max() + 1), np.nan)
        grid[r, c] = cells.h[a:b]
        if min(grid.shape) < 3:
            continue
        dy, dx = np.gradient(grid, posting)
        gx[a:b], gy[a:b] = dx[r, c], -dy[r, c]          # rows run south
    return gx, gy


def signal_share(gx, gy, ox, oy) -> float:
    """ρ in [0, 1]: the share of the variation of the reference's gradients ``gx, gy`` about
    their mean that is relief the cells' own gradients ``ox, oy`` see too,
    ``Σ (g − ḡ)·(o − ō) / Σ |g − ḡ|²`` (cells where both are finite). The reference's own noise
    makes gradients the relative DEM does not share: counted as relief, they state a shift
    fixed to metres on terrain that fixes it to tens (a plane under SRTM's 2 m noise); both
    measure the same relief and their noises are independent, so their product keeps the
    relief's part only. The mean gradient is left out: a tilted plane fixes no shift (it is a
    height), and on hills that are nearly a plane at the patch's scale it made ρ near 1 while
    the reference's noise was most of what varied (on another simulator's 10 km scene, SRTM-like
    4 m noise: gradients varying by 0.05 where the relief's varied by 0.008)."""
    ok = np.isfinite(gx) & np.isfinite(gy) & np.isfinite(ox) & np.isfinite(oy)
    if ok.sum() < 10:
        return 0.0
    gx, gy, ox, oy = (v[ok] - v[ok].mean() for v in (gx, gy, ox, oy))
    den = float(np.sum(gx ** 2 + gy ** 2))
    if den <= 0:
        return 0.0
    return float(np.clip(np.sum(gx * ox + gy * oy) / den, 0.0, 1.0))


def _about_own_shift(g: np.ndarray, f: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """Residuals ``f`` (m,) less the least-squares shift of the cells ``ok`` (Jacobian ``g``
    (m, 3)); NaN outside ``ok``."""
    b = np.linalg.lstsq(g[ok], f[ok], rcond=None)[0]
    return np.where(ok, f - g @ b, np.nan)


def _area(cells: Cells, sl: slice, res: np.ndarray) -> float:
    """Correlation area (cells) of one patch's residuals laid back on its grid."""
    r, c = cells.row[sl], cells.col[sl]
    grid = np.full((r.max() - r.min() + 1, c.max() - c.min() + 1), np.nan)
    grid[r - r.min(), c - c.min()] = res
    return correlation_area(grid)


def obs_sums(obs: FieldObs | None, basis: Basis, theta, free_offset, n_dist: int = 0):
    """The GCPs' normal equations ``(N, b)`` at ``theta`` (zeros without GCPs)."""
    act = _unknowns(basis, free_offset, n_dist)
    u = int(act.sum())
    if obs is None or not len(obs):
        return np.zeros((u, u)), np.zeros(u)
    phi = basis.phi(obs.x, obs.y)
    J = np.zeros((len(obs), 12 + n_dist))
    for k in range(3):
        sel = obs.comp == k
        J[sel, 3 * k:3 * k + 3] = phi[sel]
    J = J[:, act]
    f = np.einsum("ij,ij->i", phi, np.asarray(theta, float).reshape(3, 3)[obs.comp]) - obs.value
    w = 1.0 / np.asarray(obs.sigma, float) ** 2
    return (J * w[:, None]).T @ J, (J * w[:, None]).T @ f


@dataclass(frozen=True)
class FieldFit:
    """The adjusted field. ``theta`` (9,) per component (E, N, h) its terms (1, u, v) in m;
    ``offset`` (3,) the reference's offset from the ground control (zeros without GCPs);
    ``delta`` (D,) the relative DEMs' height distortion along the track (:class:`Distortion`, m;
    empty without); ``cov`` (12 + D, 12 + D) of ``(theta, offset, delta)`` from the adjustment
    with ``Σ_b``; ``cov_jack`` the
    patches' jackknife of the same (NaN with fewer than 3 patches); ``sigma_b`` (3,) m each
    patch's own shift beyond its cells' noise (E, N, h). Per patch (P,): ``used`` (kept and
    with cells), ``cells`` used, ``spread`` (m, NMAD), ``area`` (correlation area, cells),
    ``shift`` (P, 3) its own departure from the field (m), the test ``T`` against the others'
    field with ``dof`` and critical value ``crit``; ``rejected`` the patches removed as
    blunders, in order. ``reason`` is "" when the adjustment converged; ``info`` (P, 3, 3) the
    information each patch's cells give its own shift (1/m²)."""

    basis: Basis
    theta: np.ndarray
    offset: np.ndarray
    cov: np.ndarray
    cov_jack: np.ndarray
    sigma_b: np.ndarray
    used: np.ndarray
    cells: np.ndarray
    spread: np.ndarray
    area: np.ndarray
    shift: np.ndarray
    T: np.ndarray
    dof: np.ndarray
    crit: np.ndarray
    rejected: tuple
    iterations: int
    reason: str = ""
    info: np.ndarray | None = None
    delta: np.ndarray = field(default_factory=lambda: np.zeros(0))
    distortion: Distortion | None = None

    def __bool__(self) -> bool:
        return not self.reason

    def field(self, x, y) -> np.ndarray:
        """The field (..., 3) (dE, dN, dh, m) at N positions ``x, y``."""
        return self.basis.predict(self.theta, x, y)

    def sigma(self, x, y) -> np.ndarray:
        """σ (..., 3) of the field at ``x, y``: the adjustment's or the jackknife's, the larger."""
        s = self.basis.predict_sigma(self.cov[:9, :9], x, y)
        if np.isfinite(self.cov_jack).all():
            s = np.maximum(s, self.basis.predict_sigma(self.cov_jack[:9, :9], x, y))
        return s

    def cov_at(self, x: float, y: float, jackknife: bool = True) -> np.ndarray:
        """(3, 3) covariance of the field's (dE, dN, dh) at one N position ``x, y``."""
        p = self.basis.phi(x, y)
        Phi = np.kron(np.eye(3), p[None, :])                        # (3, 9)
        c = Phi @ self.cov[:9, :9] @ Phi.T
        if jackknife and np.isfinite(self.cov_jack).all():
            cj = Phi @ self.cov_jack[:9, :9] @ Phi.T
            if np.trace(cj) > np.trace(c):
                c = cj
        return c


def _expand(values, act, fill=0.0):
    out = np.full(act.size, fill, float)
    out[act] = values
    return out


def adjust_field(cells: Cells, surface: Surface, basis: Basis, theta0, *, n_patches: int,
                 prior_sigma, obs: FieldObs | None = None, alpha: float = 0.05,
                 max_iter: int = 30, max_reject: int | None = None,
                 distortion: Distortion | None = None, distortion_sigma: float = 1.0) -> FieldFit:
    """Adjust the field (module docstring) from the start ``theta0`` (9,).

    ``prior_sigma`` (9,) m: the a-priori σ of each parameter (zero-mean prior). With ``obs``
    (GCPs) the reference's offset is estimated too. With ``distortion`` the relative DEMs'
    heights may also hold its polynomials along the track (:class:`Distortion`), each of
    a-priori σ ``distortion_sigma`` (m). Patches whose own shift departs from the
    others' field beyond the χ² test at ``alpha`` are removed one at a time, at most
    ``max_reject`` (default a quarter of them)."""
    from prismstation.core.orientation import field_stats as fs  # start-up: scipy.stats takes a second or more to import

    # the reference's offset is free in each component some GCP observes
    free = np.zeros(3, bool) if obs is None else np.isin(np.arange(3), np.asarray(obs.comp))
    nd = 0 if distortion is None else len(distortion)
    act = _unknowns(basis, free, nd)
    theta = np.where(basis.active, np.asarray(theta0, float), 0.0)
    offset = np.zeros(3)
    delta = np.zeros(nd)
    P = int(n_patches)
    keep = np.ones(P, bool)
    limit = P // 4 if max_reject is None else int(max_reject)
    prior_w = np.r_[1.0 / np.square(np.asarray(prior_sigma, float)), np.zeros(3),
                    np.full(nd, 1.0 / float(distortion_sigma) ** 2)][act]
    rejected: list[int] = []
    total, reason = 0, ""
    own = cell_gradients(cells, surface.posting)

    def extra(th):
        No, bo = obs_sums(obs, basis, th, free, nd)
        return No + np.diag(prior_w), bo + prior_w * np.r_[th, offset, delta][act]

    def gauss_newton(sb, keep):
        # the weights (inlier cells, spreads, correlation areas) are measured at the first three
        # iterations, then kept: one objective, not one that moves by millimetres at every step
        nonlocal theta, offset, delta, total
        frozen = None
        for i in range(max_iter):
            S = accumulate(cells, surface, basis, theta, offset, P, free, frozen=frozen, distortion=distortion,
                           delta=delta)
            if i >= 2:
                frozen = S
            k = keep & (S.used > 0)
            if not k.any():
                return S, k, False
            Nx, bx = extra(theta)
            d, C = fs.solve(S, k, sb, Nx, bx)
            step = _expand(d, act)
            theta, offset, delta = theta + step[:9], offset + step[9:12], delta + step[12:]
            total += 1
            # converged: no term moves by more than a millimetre or a fiftieth of its σ
            if np.all(np.abs(d) < np.maximum(TOL_M, 0.02 * np.sqrt(np.diag(C)))):
                # the covariance's sums: the reference's gradients as far as the cells share them
                S = accumulate(cells, surface, basis, theta, offset, P, free, areas=S.area, own_gradients=own,
                               distortion=distortion, delta=delta)
                return S, keep & (S.used > 0), True
        # the steps' σ counts every gradient of the reference as relief; where most of them are
        # its noise (smooth hills under SRTM) the steps jitter on that noise by decimetres, far
        # below the σ the relief the cells share allows: converged as far as the data tell
        S2 = accumulate(cells, surface, basis, theta, offset, P, free, areas=S.area, own_gradients=own,
                        distortion=distortion, delta=delta)
        k2 = keep & (S2.used > 0)
        if k2.any():
            Nx, bx = extra(theta)
            _, C2 = fs.solve(S2, k2, sb, Nx, bx)
            if np.all(np.abs(d) < np.maximum(TOL_M, JITTER * np.sqrt(np.diag(C2)))):
                return S2, k2, True
        return S, k, False

    while True:
        sb = np.zeros(3)
        for _ in range(5):
            S, k, ok = gauss_newton(sb, keep)
            if not k.any():
                reason = "no patch has cells that the reference DEM covers"
                break
            reason = "" if ok else f"the adjustment did not converge within {max_iter} iterations"
            Nx, bx = extra(theta)
            new = fs.variance_components(S, k, Nx, bx, start=np.maximum(sb, 1.0))
            if np.all(np.abs(np.sqrt(new) - np.sqrt(sb)) <= 0.02 * np.sqrt(new) + 1e-3):
                sb = new
                break
            sb = new
        if reason.startswith("no patch"):
            break
        Nx, bx = extra(theta)
        loo = fs.leave_one_out(S, k, sb, Nx, bx, alpha)
        excess = np.where(k, loo.T / loo.crit, 0.0)
        worst = int(np.nanargmax(np.nan_to_num(excess, nan=0.0)))
        if excess[worst] > 1.0 and len(rejected) < limit and k.sum() > 3:
            keep[worst] = False
            rejected.append(worst)
            continue
        break
    u = int(act.sum())
    if reason.startswith("no patch"):
        n = 12 + nd
        return FieldFit(basis, theta, offset, np.full((n, n), np.nan), np.full((n, n), np.nan),
                        np.full(3, np.nan), np.zeros(P, bool), np.zeros(P, int), np.full(P, np.nan),
                        np.full(P, np.nan), np.full((P, 3), np.nan), np.full(P, np.nan), np.zeros(P, int),
                        np.full(P, np.nan), tuple(rejected), total, reason, None, delta, distortion)
    d, C = fs.solve(S, k, sb, Nx, bx)
    b, _ = fs.patch_shifts(S, k, sb, d, C)
    shift = np.full((P, 3), np.nan)
    shift[k] = b
    n = 12 + nd
    cov = np.zeros((n, n))
    cov[np.ix_(act, act)] = C
    jack = fs.jackknife(loo.delta[k]) if k.sum() >= 3 else np.full((u, u), np.nan)
    cov_jack = np.full((n, n), np.nan)
    if np.isfinite(jack).all():
        cov_jack = np.zeros((n, n))
        cov_jack[np.ix_(act, act)] = jack
    return FieldFit(basis, theta, offset, cov, cov_jack, np.sqrt(sb), k, S.used, S.spread, S.area, shift,
                    np.where(k, loo.T, np.nan), np.where(k, loo.dof, 0), np.where(k, loo.crit, np.nan),
                    tuple(rejected), total, reason, S.I, delta, distortion)
