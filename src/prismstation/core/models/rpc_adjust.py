"""Bias-compensated RPC block adjustment (Grodecki & Dial 2003; Fraser & Hanley 2003).

Unknowns: each image's bias parameters (:mod:`prismstation.core.models.rpc_bias`; an image may be
held fixed at zero bias) and each point's ground coordinates. Observations:

- image measurements ``(x, y)`` px with σ px: ``xy − Δ_k(xy) = rpc_k(lon, lat, h) + v``;
- ground control: the GCP's known (lon, lat, h) with σ (east, north, up) in metres;
- height constraints on tie points: a reference DEM's ellipsoidal height with its σ (m).

Gauss–Newton on the stacked system; the points' 3 × 3 blocks are eliminated (reduced normal
equations), the bias block is solved after Jacobi normalisation, and its condition number is
checked. Point corrections are in local east-north-up metres, so point covariances come out in
metres; positions are kept as (lon°, lat°, ellipsoidal h m). Without GCPs the block's position
is free: one image is held fixed (by default the first), the others' biases are relative to it.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from prismstation.core.adjustment.estimate import SINGULAR, degenerate
from prismstation.core.models.rpc import Rpc, wrap180
from prismstation.core.models.rpc_bias import (BIAS_MODELS, BiasedRpc, _inv3, _rays, bias_design,
                                        intersect_points, metres_per_degree)
from prismstation.errors import ModelError


@dataclass(frozen=True, eq=False)
class RpcAdjustment:
    """Result of :func:`adjust` (units: image px, ground metres, biases as in
    :mod:`~prismstation.core.models.rpc_bias`).

    ``models`` the fitted :class:`BiasedRpc` per image; ``bias_cov`` per image ``(p, p)``
    (zeros for a fixed image); ``lon, lat, h`` ``(n,)`` and ``point_cov`` ``(n, 3, 3)`` ENU m²;
    ``residuals`` ``(m, 2)`` px (observed − computed) of the image observations,
    ``redundancy`` and ``std_residuals`` ``(m, 2)`` (externally studentised, as in
    :mod:`prismstation.core.adjustment.lsq`); ``gcp_residuals`` ``(g, 3)`` m (known − adjusted, ENU) and
    ``height_residuals`` ``(k,)`` m. Covariances are a-posteriori (``σ0²·Q``) when
    ``dof > 0``.
    """

    models: list
    bias_cov: list
    fixed: tuple
    lon: np.ndarray
    lat: np.ndarray
    h: np.ndarray
    point_cov: np.ndarray
    residuals: np.ndarray
    redundancy: np.ndarray
    std_residuals: np.ndarray
    gcp_residuals: np.ndarray
    height_residuals: np.ndarray
    sigma0: float
    dof: int
    iterations: int
    point: np.ndarray
    image: np.ndarray

    def bias_std(self, k: int) -> np.ndarray:
        return np.sqrt(np.diag(self.bias_cov[k]))

    def rms_by_image(self) -> np.ndarray:
        """RMS of the image residuals ``(n_images, 2)`` px (x, y)."""
        out = np.full((len(self.models), 2), np.nan)
        for k in range(len(self.models)):
            r = self.residuals[self.image == k]
            if len(r):
                out[k] = np.sqrt(np.mean(r ** 2, axis=0))
        return out


def adjust(models: Sequence[Rpc], point, image, xy, sigma, *, bias="shift", fixed=None,
           gcp_point=(), gcp_llh=None, gcp_sigma=None, height_point=(), height=None,
           height_sigma=None, centres=None, n_points: int | None = None, bias_sigma=None,
           bias_prior=None, max_iter: int = 20, tol: float = 1e-6) -> RpcAdjustment:
    """Fit each image's bias and every point's ground to the observations.

    ``models`` ``Rpc`` per image (of a :class:`BiasedRpc` only its RPC is used: the biases
    start from zero); ``point``, ``image`` ``(m,)`` indices and ``xy`` ``(m, 2)`` px
    with ``sigma`` px (scalar, ``(m,)`` or ``(m, 2)``); ``bias`` one model name or one per
    image; ``fixed`` image indices held at zero bias (default: image 0 when there is no GCP,
    none otherwise). ``gcp_point`` ``(g,)`` with ``gcp_llh`` ``(g, 3)`` (lon°, lat°,
    ellipsoidal h m) and ``gcp_sigma`` ``(g, 3)`` m (east, north, up); ``height_point`` ``(k,)``
    with ``height`` and ``height_sigma`` ``(k,)`` m. ``centres`` ``(n_images, 2)``: each
    bias's reference point, px (default: the mean of the image's observations).
    ``bias_sigma``: the a-priori σ of the bias parameters (Grodecki & Dial 2003's a-priori
    covariance of the adjustment parameters): a function ``kind → (p,)`` σ in the parameters'
    units, each parameter then observed as 0 with that σ; None: no a-priori weight.
    ``bias_prior``: image index → ``(values (p,), σ (p,))`` of its ``bias`` model's
    parameters observed a priori (an orientation made elsewhere: from a reference DEM), in
    place of ``bias_sigma``'s zeros, at that image's ``centres`` (give them).

    Raises :class:`~prismstation.errors.DegenerateGeometry` when the biases are not
    determined (say no GCP and no fixed image) and :class:`ModelError` when a point is
    undetermined or Gauss–Newton does not converge in ``max_iter`` iterations (``tol``: px
    for biases and m for points).
    """
    rpcs = [m.rpc if isinstance(m, BiasedRpc) else m for m in models]
    ni = len(rpcs)
    point, image = np.asarray(point, int), np.asarray(image, int)
    xy = np.asarray(xy, float).reshape(-1, 2)
    m = len(point)
    sig = np.asarray(sigma, float)
    sig = np.broadcast_to(sig.reshape(-1, 1) if sig.ndim == 1 else sig, (m, 2))
    if not (np.all(np.isfinite(xy)) and np.all(sig > 0)):
        raise ModelError("image observations: non-finite coordinates or σ ≤ 0")
    n = int(point.max()) + 1 if n_points is None else n_points
    kinds = [bias] * ni if isinstance(bias, str) else list(bias)
    gcp_point = np.asarray(gcp_point, int)
    g = len(gcp_point)
    gcp_llh = np.zeros((0, 3)) if g == 0 else np.asarray(gcp_llh, float).reshape(g, 3)
    gcp_sig = np.zeros((0, 3)) if g == 0 else np.broadcast_to(np.asarray(gcp_sigma, float), (g, 3))
    height_point = np.asarray(height_point, int)
    hk = len(height_point)
    hval = np.asarray(height, float).reshape(hk) if hk else np.zeros(0)
    hsig = np.broadcast_to(np.asarray(height_sigma, float), (hk,)) if hk else np.zeros(0)
    if fixed is None:
        fixed = (0,) if g == 0 else ()
    fixed = tuple(sorted(set(int(k) for k in fixed)))
    if centres is None:
        centres = np.array([xy[image == k].mean(0) if np.any(image == k) else (0.0, 0.0)
                            for k in range(ni)])
    centres = np.asarray(centres, float).reshape(ni, 2)
    # global bias columns
    cols, start = [], 0
    for k in range(ni):
        p = 0 if k in fixed else BIAS_MODELS[kinds[k]]
        cols.append(slice(start, start + p))
        start += p
    nb = start
    D = np.zeros((m, 2, nb))
    for k in range(ni):
        sel = image == k
        if cols[k].stop > cols[k].start:
            D[sel, :, cols[k]] = bias_design(kinds[k], xy[sel, 0], xy[sel, 1], *centres[k])
    w = 1.0 / sig ** 2
    prior_w = np.zeros(nb)                 # 1/σ² of each parameter's a-priori observation (0: none)
    prior_mu = np.zeros(nb)                # its a-priori value
    for k in range(ni):
        if cols[k].stop > cols[k].start:
            if bias_prior and k in bias_prior:
                prior_mu[cols[k]] = np.asarray(bias_prior[k][0], float)
                prior_w[cols[k]] = 1.0 / np.asarray(bias_prior[k][1], float) ** 2
            elif bias_sigma is not None:
                prior_w[cols[k]] = 1.0 / np.asarray(bias_sigma(kinds[k]), float) ** 2
    params = prior_mu.copy()               # the biases start from their a-priori values

    def biased():
        return [BiasedRpc(rpcs[k], "none" if k in fixed else kinds[k],
                          None if k in fixed else params[cols[k]], *centres[k]) for k in range(ni)]

    # first ground: GCPs where known, others intersected with the a-priori biases
    hc = np.full(n, np.nan)
    hs = np.full(n, np.nan)
    hc[height_point], hs[height_point] = hval, hsig
    gc_h = np.full(n, np.nan)
    gc_h[gcp_point], hs_g = gcp_llh[:, 2], np.full(n, np.nan)
    hs_g[gcp_point] = gcp_sig[:, 2]
    first = intersect_points(biased(), point, image, xy, sig, n,
                             height=np.where(np.isfinite(gc_h), gc_h, hc),
                             height_sigma=np.where(np.isfinite(gc_h), hs_g, hs))
    lon, lat, h = first.lon.copy(), first.lat.copy(), first.h.copy()
    lon[gcp_point], lat[gcp_point], h[gcp_point] = gcp_llh.T

    for it in range(1, max_iter + 1):
        sol = _normal_solve(biased(), point, image, xy, w, D, lon, lat, h, n, gcp_point, gcp_llh,
                            gcp_sig, height_point, hval, hsig, need_cov=False, prior=(prior_w, params - prior_mu))
        db, dp = sol["db"], sol["dp"]
        params = params + db
        ke, kn = metres_per_degree(lat, h)
        lon, lat, h = lon + dp[:, 0] / ke, lat + dp[:, 1] / kn, h + dp[:, 2]
        if max(np.max(np.abs(db), initial=0.0), np.max(np.abs(dp), initial=0.0)) < tol:
            break
    else:
        raise ModelError(f"RPC bias adjustment did not converge in {max_iter} iterations")
    fin = _normal_solve(biased(), point, image, xy, w, D, lon, lat, h, n, gcp_point, gcp_llh,
                        gcp_sig, height_point, hval, hsig, need_cov=True, prior=(prior_w, params - prior_mu))
    n_obs = 2 * m + 3 * g + hk + int(np.count_nonzero(prior_w))
    dof = n_obs - nb - 3 * n
    if dof < 0:
        raise degenerate(f"RPC bias adjustment: {nb + 3 * n} unknowns, {n_obs} observations")
    wv = [fin["v"] * np.sqrt(w), fin["vg"] / gcp_sig, fin["vh"] / hsig, (params - prior_mu) * np.sqrt(prior_w)]
    ssr = float(sum(np.sum(a * a) for a in wv))
    sigma0 = float(np.sqrt(ssr / dof)) if dof > 0 else float("nan")
    s2 = sigma0 ** 2 if dof > 0 else 1.0
    red = fin["red"]
    std = np.full((m, 2), np.nan)
    if dof > 1:
        ok = red > 1e-9
        s_i2 = (ssr - wv[0][ok] ** 2 / red[ok]) / (dof - 1)
        std[ok] = wv[0][ok] / np.sqrt(np.maximum(s_i2, 1e-300) * red[ok])
    bias_cov = [np.zeros((BIAS_MODELS["none" if k in fixed else kinds[k]],) * 2) if k in fixed
                else s2 * fin["Qbb"][cols[k], cols[k]] for k in range(ni)]
    return RpcAdjustment(biased(), bias_cov, fixed, lon, lat, h, s2 * fin["Qpp"], fin["v"], red,
                         std, fin["vg"], fin["vh"], sigma0, dof, it, point, image)


def _normal_solve(models, point, image, xy, w, D, lon, lat, h, n, gcp_point, gcp_llh, gcp_sig,
                  height_point, hval, hsig, need_cov, prior=None):
    """One Gauss–Newton step on the reduced normal equations (points eliminated); ``prior``
    ``(weights (nb,), current parameters (nb,))`` of the parameters' a-priori observations."""
    v, J = _rays(models, point, image, xy, lon, lat, h)        # (m, 2), (m, 2, 3) px/m
    nb = D.shape[2]
    Nbb = np.einsum("mai,ma,maj->ij", D, w, D)
    rb = np.einsum("mai,ma,ma->i", D, w, v)
    if prior is not None and nb:
        Nbb = Nbb + np.diag(prior[0])
        rb = rb - prior[0] * prior[1]
    Nbp = np.zeros((n, nb, 3))
    np.add.at(Nbp, point, np.einsum("mai,ma,maj->mij", D, w, J))
    Npp = np.zeros((n, 3, 3))
    rp = np.zeros((n, 3))
    np.add.at(Npp, point, np.einsum("mai,ma,maj->mij", J, w, J))
    np.add.at(rp, point, np.einsum("mai,ma,ma->mi", J, w, v))
    ke, kn = metres_per_degree(lat, h)
    vg = np.zeros((0, 3))
    if len(gcp_point):
        p = gcp_point
        vg = np.column_stack([wrap180(gcp_llh[:, 0] - lon[p]) * ke[p], (gcp_llh[:, 1] - lat[p]) * kn[p],
                              gcp_llh[:, 2] - h[p]])
        wg = 1.0 / gcp_sig ** 2
        for c in range(3):
            np.add.at(Npp[:, c, c], p, wg[:, c])
            np.add.at(rp[:, c], p, wg[:, c] * vg[:, c])
    vh = hval - h[height_point] if len(height_point) else np.zeros(0)
    if len(height_point):
        np.add.at(Npp[:, 2, 2], height_point, 1.0 / hsig ** 2)
        np.add.at(rp[:, 2], height_point, vh / hsig ** 2)
    Qp0 = _inv3(Npp)                                           # (n, 3, 3)
    T = np.einsum("nbi,nij->nbj", Nbp, Qp0)                    # Nbp Npp⁻¹
    S = Nbb - np.einsum("nbj,ncj->bc", T, Nbp)
    rs = rb - np.einsum("nbj,nj->b", T, rp)
    if nb:
        d = np.sqrt(np.diag(S))
        if np.any(~(d > 0)):
            raise degenerate("RPC bias adjustment: a bias parameter has no observation "
                             "(an image without measurements?)")
        Sn = S / np.outer(d, d)
        s = np.linalg.svd(Sn, compute_uv=False)
        kappa = s[0] / s[-1] if s[-1] > 0 else np.inf
        if kappa > SINGULAR:
            raise degenerate("RPC bias adjustment: the image biases are not determined (no GCP "
                             "and no image held fixed, or too few points for the bias model; "
                             f"condition number {kappa:.3g})", kappa)
        Qbb = np.linalg.inv(Sn) / np.outer(d, d)
        db = Qbb @ rs
    else:
        Qbb, db = np.zeros((0, 0)), np.zeros(0)
    dp = np.einsum("nij,nj->ni", Qp0, rp - np.einsum("nbj,b->nj", Nbp, db))
    out = {"db": db, "dp": dp, "v": v, "vg": vg, "vh": vh}
    if not need_cov:
        return out
    Qbp = -np.einsum("bc,ncj->nbj", Qbb, T)                    # (n, nb, 3)
    Qpp = Qp0 + np.einsum("nbi,bc,ncj->nij", T, Qbb, T)
    # leverages of the image observations: a = [D_i, J_i]
    Dq = np.einsum("mai,ij,maj->ma", D, Qbb, D)
    Dp = 2.0 * np.einsum("mai,mij,maj->ma", D, Qbp[point], J)
    Jq = np.einsum("mai,mij,maj->ma", J, Qpp[point], J)
    red = np.clip(1.0 - w * (Dq + Dp + Jq), 0.0, 1.0)
    out.update(Qbb=Qbb, Qpp=Qpp, red=red)
    return out


def adjust_snooping(models, point, image, xy, sigma, *, t_max: float = 4.0, max_rounds: int = 100,
                    height_point=(), height=None, height_sigma=None, **kw):
    """:func:`adjust` with data snooping (Baarda): while the largest externally studentised
    residual exceeds ``t_max``, drop that observation's point (all its rays and its height) and
    fit again. Returns ``(result, kept)``: ``kept`` ``(n,)`` bool over the input's points; the
    result's points are the kept ones, renumbered in order. GCPs are not supported here (pass
    them to :func:`adjust`)."""
    point = np.asarray(point, int)
    n = int(point.max()) + 1
    kept = np.ones(n, bool)
    hp = np.asarray(height_point, int)
    hv = None if height is None else np.asarray(height, float)
    hs = None if height_sigma is None else np.broadcast_to(np.asarray(height_sigma, float), hp.shape)
    sig = np.broadcast_to(np.asarray(sigma, float).reshape(-1, 1) if np.ndim(sigma) == 1
                          else np.asarray(sigma, float), (len(point), 2))
    for _ in range(max_rounds + 1):
        new = np.cumsum(kept) - 1
        obs = kept[point]
        hsel = kept[hp] if hp.size else np.zeros(0, bool)
        res = adjust(models, new[point[obs]], np.asarray(image)[obs], np.asarray(xy)[obs], sig[obs],
                     n_points=int(kept.sum()), height_point=new[hp[hsel]] if hp.size else (),
                     height=None if hv is None else hv[hsel],
                     height_sigma=None if hs is None else hs[hsel], **kw)
        t = np.abs(res.std_residuals).max(1)
        if not np.any(t > t_max):
            return res, kept
        worst = np.flatnonzero(kept)[res.point[int(np.nanargmax(t))]]
        kept[worst] = False
    raise ModelError(f"data snooping: still a residual above {t_max} after {max_rounds} rounds")
