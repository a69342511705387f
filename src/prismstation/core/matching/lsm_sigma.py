"""What a least-squares match's σ is made of (:mod:`prismstation.core.matching.lsm`): the images' noise,
its share of the gradients, and the displacement the patch's shape does not follow.

Arrays: template grids ``(n, n)`` (rows, columns), grey values; displacements in pixels.
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage

GRADIENT_NOISE = 2.18
"""Variance of a gradient component of the cubic B-spline interpolating unit white noise, over
all sub-pixel positions (numerically: 2.18; the interpolated values themselves 0.77)."""
_LAPLACE = np.array([[1.0, -2.0, 1.0], [-2.0, 4.0, -2.0], [1.0, -2.0, 1.0]])


def noise_sigma(a) -> float:
    """σ of white noise in the image patch ``a`` (grey values): Immerkaer's (1996) difference
    of Laplacians, which removes any locally planar signal, its median made robust to the
    texture that leaks through (an upper bound on textured ground: 20 % high on the
    simulator's images, right to 1 DN on Pléiades with 20 DN of added noise)."""
    a = np.asarray(a, np.float64)
    if min(a.shape) < 3:
        return 0.0
    L = ndimage.correlate(a, _LAPLACE, mode="nearest")[1:-1, 1:-1]
    return 1.4826 * float(np.median(np.abs(L))) / 6.0


def gradient_noise_inflation(gx, gy, var: float, count: float | None = None) -> float:
    """Factor on the position's covariance for the noise in the gradients ``gx, gy`` (the
    design's, grey values per px): their noise power, :data:`GRADIENT_NOISE` times the noise
    variance ``var``, is no information about the position, so the structure tensor
    ``G = Σ∇∇ᵀ`` overstates it; the factor is ``λ(G) / λ(G − n·GRADIENT_NOISE·var·I)`` in its
    weakest direction; infinite when the noise has all of the gradients' power there.
    ``count``: the noise's weight in ``G`` (the pixel count; ``Σw²`` for gradients weighted
    by ``w``)."""
    G = np.array([[gx @ gx, gx @ gy], [gx @ gy, gy @ gy]])
    lam = float(np.linalg.eigvalsh(G)[0])
    c = GRADIENT_NOISE * var * (gx.size if count is None else count)
    return lam / (lam - c) if lam > c else float("inf")


def unmodelled_sigma(G, r, n_params: int, block: int = 4, w=None, other=None) -> float:
    """σ (px) of the displacement in one direction that the patch's shape does not follow.

    ``G``: the fitted patch's gradient in that direction (e.g. the parallax) on the template grid
    ``(n, n)`` (grey values per px), ``r``: the residuals ``(n, n)``, ``n_params``: the
    adjustment's parameter count. Each ``block × block`` part of the template gets its own
    displacement ``δ = ΣGr / ΣG²`` (the residual a displacement leaves is ``G·δ``); what the
    residuals hold beyond it is noise of variance ``σn²``; the σ is the ``ΣG²``-weighted RMS of
    the ``δ`` less their noise ``σn²/ΣG²``. Along the parallax: the relief within the template
    that no affine or quadratic patch follows — the error it leaves at the point is of that
    size. ``w`` (``(n, n)``): weights of the pixels (a block counts by its mean weight).
    ``other``: the gradient in the perpendicular direction; given, each block's displacement
    is solved in both directions together, so that displacement along ``other`` (relief, when
    ``G`` is across the parallax) is not read into ``G``'s where the texture's gradients
    correlate."""
    n = r.shape[0]
    m = n // block
    if m < 2:
        return 0.0
    lo = (n - m * block) // 2

    def sums(a):
        """Sums of ``a`` over the ``m × m`` blocks, ``(m²,)``."""
        return a[lo:lo + m * block, lo:lo + m * block].reshape(m, block, m, block).sum(axis=(1, 3)).ravel()

    g2, p, rr = sums(G * G), sums(G * r), float(sums(r * r).sum())
    if np.any(g2 <= 0):
        return 0.0
    if other is None:
        delta = p / g2
        rss, unknowns = rr - float(delta @ p), m * m
    else:
        go, gc, q = sums(other * other), sums(G * other), sums(other * r)
        det = g2 * go - gc ** 2
        if np.any(det <= 1e-9 * g2 * go):
            return 0.0
        delta, delta_o = (go * p - gc * q) / det, (g2 * q - gc * p) / det
        rss, unknowns = rr - float(delta @ p + delta_o @ q), 2 * m * m
        g2 = det / go                                   # the information on δ left by the other
    # the residuals less each block's fitted displacement: noise
    noise = rss / max(m * m * block * block - unknowns - n_params, 1)
    wb = 1.0 if w is None else sums(w) / block ** 2
    excess = np.sum(wb * (g2 * delta ** 2 - noise)) / np.sum(wb * g2)
    return float(np.sqrt(max(excess, 0.0)))


def texture_sigma(a) -> float:
    """σ (px) a template ``a`` (grey values, ``(n, n)``) can fix a position to in its weakest
    direction, before any match: the noise (:func:`noise_sigma`, in both views) over the
    structure tensor's smaller eigenvalue, less the noise's own share of the gradients (central
    differences: half the noise variance per component). Infinite where the noise has all of
    it — a template inside a flat parcel, or on one straight edge (which fixes nothing along it)."""
    a = np.asarray(a, np.float64)
    gy, gx = np.gradient(a)
    gx, gy = gx[1:-1, 1:-1].ravel(), gy[1:-1, 1:-1].ravel()
    var = noise_sigma(a) ** 2
    G = np.array([[gx @ gx, gx @ gy], [gx @ gy, gy @ gy]])
    lam = float(np.linalg.eigvalsh(G)[0]) - 0.5 * var * gx.size
    return float(np.sqrt(2.0 * var / lam)) if lam > 0 else float("inf")

