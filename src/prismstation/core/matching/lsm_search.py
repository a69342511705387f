"""Point transfer with a shape: correlation along the search direction in the reference's
geometry, then least-squares matching (:mod:`prismstation.core.matching.lsm`) from the best peaks.

Coordinates as in :mod:`prismstation.core.matching.lsm` (docs/model.md §1). The caller gives the
predicted position ``pred`` of the point in the search image and the predicted local shape
``A0`` (2×2, search pixels per reference pixel), e.g. from the sensor model and the terrain
slope. The search image is resampled into the reference's geometry through ``A0`` around the
prediction (bilinear), so the template correlates there as if the views were alike; the
search covers ``±along`` px along ``direction`` (the parallax direction: where an unknown
height moves the point) and ``±across`` px across it, in search-image pixels.

Each of the best correlation peaks (up to ``candidates``) starts a least-squares match; the
one that converges with the highest correlation wins. A second converged match elsewhere
(more than 1 px away) that fits nearly as well (residual variance within ``ambiguity`` times
the best one's) makes the result ``ambiguous``; a winner at the end of the search range is
``border``.
"""
from __future__ import annotations

from dataclasses import replace

from prismstation.core.lazy_cv2 import cv2  # imported at first use: start-up saving
import numpy as np
from scipy import ndimage

from prismstation.core.matching import lsm
from prismstation.core.matching.lsm import LsmResult, failed
from prismstation.core.matching.lsm_spline import search_spline

AMBIGUOUS, BORDER, LOW_SCORE = "ambiguous", "border", "low_score"

AMBIGUITY = 1.5
"""Two matches whose misfits ``1 − ρ²`` lie within this factor fit alike (an F test at 99 % on
a template's pixels, their correlation allowed for); beyond it one fits clearly better."""

MISFIT_FLOOR = 1e-6
"""The least misfit ``1 − ρ²`` two matches are compared by: below it (a thousandth of a grey
value on a texture of 30) the difference is the interpolation's arithmetic, not the images'
(exact copies of a patch)."""


def misfit(rho: float) -> float:
    """The residual variance share ``1 − ρ²`` two matches are compared by (at least
    :data:`MISFIT_FLOOR`)."""
    return max(1.0 - rho ** 2, MISFIT_FLOOR)


def _frame(direction):
    d = np.asarray(direction, float)
    d = d / np.hypot(*d)
    return d, np.array([-d[1], d[0]])


def correlate(reference, x: float, y: float, search, pred, A0, direction, along: float,
              across: float, half: int):
    """NCC of the template at ``(x, y)`` over the search region resampled through ``A0``.

    Returns ``(ncc, shifts, allowed)``: the NCC surface ``(m, n)``; ``shifts(k, l)`` → the
    search-image offset from ``pred`` (px) of NCC cell ``(l, k)``; ``allowed`` the cells inside
    the search region. None when the template leaves the reference image."""
    i0, j0 = int(np.floor(x)), int(np.floor(y))
    if not (half <= j0 < reference.shape[0] - half and half <= i0 < reference.shape[1] - half):
        return None
    tpl = np.asarray(reference[j0 - half:j0 + half + 1, i0 - half:i0 + half + 1], np.float32)
    d, c = _frame(direction)
    A0 = np.asarray(A0, float)
    Ainv = np.linalg.inv(A0)
    corners = np.array([s * along * d + t * across * c for s in (-1, 1) for t in (-1, 1)]) @ Ainv.T
    k0 = int(np.floor(corners[:, 0].min())) - 1
    l0 = int(np.floor(corners[:, 1].min())) - 1
    k1 = int(np.ceil(corners[:, 0].max())) + 1
    l1 = int(np.ceil(corners[:, 1].max())) + 1
    # R[l, k] = S(pred + A0·(w_tl + (k0 + k, l0 + l)) + …): the template's top-left offset w_tl
    ou, ov = i0 - half + 0.5 - x, j0 - half + 0.5 - y
    kk = (np.arange(k1 - k0 + 2 * half + 1) + k0 + ou)[None, :]        # broadcast, not meshed:
    ll = (np.arange(l1 - l0 + 2 * half + 1) + l0 + ov)[:, None]        # the same sums, fewer passes
    mx = ((pred[0] - 0.5 + A0[0, 0] * kk) + A0[0, 1] * ll).astype(np.float32)
    my = ((pred[1] - 0.5 + A0[1, 0] * kk) + A0[1, 1] * ll).astype(np.float32)
    lo_x, lo_y = int(max(np.floor(mx.min()) - 2, 0)), int(max(np.floor(my.min()) - 2, 0))
    hi_x = int(min(np.ceil(mx.max()) + 3, search.shape[1]))
    hi_y = int(min(np.ceil(my.max()) + 3, search.shape[0]))
    if hi_x - lo_x < 4 or hi_y - lo_y < 4:
        return None
    crop = np.asarray(search[lo_y:hi_y, lo_x:hi_x], np.float32)
    R = cv2.remap(crop, mx - lo_x, my - lo_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                  borderValue=np.nan)
    valid = np.isfinite(R)
    R = np.where(valid, R, 0.0).astype(np.float32)
    ncc = cv2.matchTemplate(R, tpl, cv2.TM_CCOEFF_NORMED)
    # cells whose window holds a pixel from outside the search image are not allowed
    full = (np.full(ncc.shape, tpl.size, np.float32) if valid.all() else
            cv2.matchTemplate(valid.astype(np.float32), np.ones_like(tpl), cv2.TM_CCORR))
    # each cell's offset A0·(k, l) along d and across c: a row term plus a column term
    sk, sl = (np.arange(ncc.shape[1]) + k0)[None, :], (np.arange(ncc.shape[0]) + l0)[:, None]
    ad, ac = A0.T @ d, A0.T @ c
    allowed = ((np.abs(ad[0] * sk + ad[1] * sl) <= along + 0.5)
               & (np.abs(ac[0] * sk + ac[1] * sl) <= across + 0.5)
               & (full > tpl.size - 0.5) & np.isfinite(ncc))

    def shifts(k, l):
        return A0 @ np.array([k + k0, l + l0], float)

    return np.where(np.isfinite(ncc), ncc, -1.0), shifts, allowed


def best_score(reference, x: float, y: float, search, pred, A0, direction, along: float,
               across: float, half: int) -> float:
    """The highest NCC of :func:`correlate` in the search region (−1 when there is none): a
    cheap first test of a start shape ``A0`` before a least-squares match."""
    cor = correlate(reference, x, y, search, pred, A0, direction, along, across, half)
    if cor is None or not cor[2].any():
        return -1.0
    return float(cor[0][cor[2]].max())


def _parabola(m1: float, m0: float, p1: float) -> float:
    den = m1 - 2.0 * m0 + p1
    if not np.isfinite(den) or den >= 0:
        return 0.0
    return float(np.clip(0.5 * (m1 - p1) / den, -0.5, 0.5))


def peaks(ncc, allowed, n: int, min_score: float):
    """Up to ``n`` local maxima ``(score, k, l)`` (subpixel by a parabola per axis) of ``ncc``
    in ``allowed``, best first, scoring at least ``min_score``."""
    masked = np.where(allowed, ncc, -np.inf)
    is_max = (masked == ndimage.maximum_filter(masked, size=3, mode="constant", cval=-np.inf))
    is_max &= masked >= min_score
    idx = np.flatnonzero(is_max)
    idx = idx[np.argsort(masked.ravel()[idx])[::-1][:n]]
    out = []
    for i in idx:
        l, k = np.unravel_index(i, ncc.shape)
        sk = _parabola(ncc[l, k - 1], ncc[l, k], ncc[l, k + 1]) if 0 < k < ncc.shape[1] - 1 else 0.0
        sl = _parabola(ncc[l - 1, k], ncc[l, k], ncc[l + 1, k]) if 0 < l < ncc.shape[0] - 1 else 0.0
        out.append((float(ncc[l, k]), k + sk, l + sl))
    return out


def _ends(results) -> list:
    """Where the whole template's fits of the converged ``results`` ended (``extra["fit"]``):
    a peak that ends there too is the same match (:data:`lsm.SAME`)."""
    return [r.extra["fit"] for r in results if r.ok and "fit" in r.extra]


def match(reference, x: float, y: float, search, pred, A0, direction=(0.0, 1.0), *,
          along: float = 10.0, across: float = 1.5, half: int = 12, candidates: int = 3,
          min_ncc: float = 0.3, ambiguity: float = AMBIGUITY, max_shape_change: float = 0.25,
          coarse: float = 0.0, coarse_after: tuple | None = None, rival: float = 3.0, probe: bool = False,
          **options) -> LsmResult:
    """Find the point ``(x, y)`` of ``reference`` in ``search``.

    ``pred``: predicted position (px), ``A0``: predicted shape (2×2), ``direction``: search
    direction in the search image; ``along``, ``across``: half-lengths (px) of the search
    region; ``half``: template half size; ``candidates``: correlation peaks tried (at least
    ``min_ncc``); ``ambiguity``: a second match whose residual variance (``1 − ρ²``) is within
    this factor of the best one's makes the result ambiguous (1.5: an F test at 99 % on the
    template's pixels, their correlation allowed for), a converged one refused only for its σ
    (``texture``) too;
    ``max_shape_change``: how far the shape may move from ``A0`` (:func:`lsm.refine`);
    ``coarse``: σ (px) of a pass on both images smoothed, made when the best peak's
    least-squares match failed, before the full resolution again from its end (0: none): for
    a shape known only roughly, or a fit that crept between the minima of point-sampled
    texture; ``coarse_after``: the failures that call it (None: any but ``outside``);
    ``rival``: once the best peak converged, a peak whose misfit ``1 − NCC²`` exceeds this
    factor times the best peak's is not tried (the matching improves both alike); ``probe``:
    the prediction is a start too when the best match lies more than 1 px from it (a
    prediction from a reference DEM: the texture may fit there as well, a minimum no
    correlation peak starts from). Other ``options`` go to :func:`lsm.refine`.
    The result's ``score`` is the best peak's NCC, ``rho`` the fitted correlation.
    """
    pred = np.asarray(pred, float)
    A0 = np.asarray(A0, float)
    cor = correlate(reference, x, y, search, pred, A0, direction, along, across, half)
    if cor is None:
        return failed(pred[0], pred[1], lsm.OUTSIDE, "template or search region leaves its image", shape=A0)
    ncc, shifts, allowed = cor
    found = peaks(ncc, allowed, candidates, min_ncc)
    if not found:
        best = float(np.max(np.where(allowed, ncc, -1.0))) if allowed.any() else np.nan
        return failed(pred[0], pred[1], LOW_SCORE, f"no correlation peak above {min_ncc:.2f} "
                      f"(best {best:.2f})", shape=A0, score=best)
    d, c = _frame(direction)
    # one spline of the whole band when it is short; over a long band each peak's own
    # (prefiltering hundreds of pixels for three patches costs more than three small ones)
    spline = (search_spline(search, pred, A0, half, np.hypot(along, across) + options.get("max_move", 3.0) + 1)
              if along <= 2 * half else None)
    results = []
    for score, k, l in found:
        if results and results[0].ok and 1 - score ** 2 > rival * (1 - found[0][0] ** 2):
            break   # a peak this much weaker than a converged best cannot rival it
        t0 = pred + shifts(k, l)
        # a rival of a converged best matters only if it correlates nearly as well
        top = max((r.rho for r in results if r.ok), default=None)
        need = None if top is None else float(np.sqrt(max(1.0 - ambiguity * misfit(top), 0.0)))
        r = lsm.refine(reference, x, y, search, t0, A0, half=half, spline=spline,
                       max_shape_change=max_shape_change, need_rho=need, found=_ends(results), **options)
        if (not r.ok and coarse > 0 and r.status != lsm.OUTSIDE and not results
                and (coarse_after is None or r.status in coarse_after)):
            # a smoothed pass, then the full resolution from its end (for the best peak only:
            # the others are there to expose an ambiguity)
            r0 = lsm.refine(reference, x, y, search, t0, A0, half=half, smooth=coarse,
                            max_shape_change=max_shape_change, **{**options, "min_rho": 0.0, "max_sigma": np.inf})
            if r0.ok:
                r = lsm.refine(reference, x, y, search, (r0.x, r0.y), r0.shape, half=half, spline=spline,
                               max_shape_change=max_shape_change, **options)
                why = lsm.shape_check(A0, r.shape, options.get("parallax"), max_shape_change)
                if r.ok and why:   # the limits count from the prediction
                    r = replace(r, status=lsm.SHAPE, reason=why + " from the prediction")
        results.append(replace(r, score=score))
    good = [r for r in results if r.ok]
    if not good:
        first = results[0]
        return first
    good.sort(key=lambda r: -r.rho)
    best = good[0]
    off = np.array([best.x, best.y]) - pred
    if abs(off @ d) > along + 0.5 or abs(off @ c) > across + 0.5:
        return replace(best, status=BORDER, reason="the match lies at the end of the search range")
    if probe and np.hypot(*off) > 1.0:
        need = float(np.sqrt(max(1.0 - ambiguity * misfit(best.rho), 0.0)))
        results.append(lsm.refine(reference, x, y, search, pred, A0, half=half, spline=spline,
                                  max_shape_change=max_shape_change, need_rho=need, found=_ends(results), **options))
        good = good + [results[-1]] if results[-1].ok else good
    # a rival refused only for its σ (converged, too little texture in one direction) still says
    # the texture fits there: one that fits as well is as much an ambiguity as a kept one
    vague = [r for r in results if r.status == lsm.TEXTURE and np.isfinite(r.rho)]
    for r in good[1:] + vague:
        if np.hypot(r.x - best.x, r.y - best.y) > 1.0 and misfit(r.rho) <= ambiguity * misfit(best.rho):
            return replace(best, status=AMBIGUOUS, reason=f"two matches {np.hypot(r.x - best.x, r.y - best.y):.1f} px "
                           f"apart correlate alike ({best.rho:.3f}, {r.rho:.3f}): repetitive or flat texture")
    return best
