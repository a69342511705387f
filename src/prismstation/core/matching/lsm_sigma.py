"""What a least-squares match's σ is made of (:mod:`prismstation.core.matching.lsm`): the images' noise,
its share of the gradients, and the displacement the patch's shape does not follow.

Arrays: template grids ``(n, n)`` (rows, columns), grey values; displacements in pixels.
"""
from __future__ import annotations

import numpy as np

from prismstation.core.lazy_cv2 import lazy_module

kernel = lazy_module("prismstation.core.matching.lsm_kernel")  # numba at first use: start-up saving

GRADIENT_NOISE = 2.18
"""Variance of a gradient component of the cubic B-spline interpolating unit white noise, over
all sub-pixel positions (numerically: 2.18; the interpolated values themselves 0.77)."""
_EMPTY = np.empty((0, 0))


def noise_sigma(a) -> float:
    """σ of white noise in the image patch ``a`` (grey values): Immerkaer's (1996) difference
    of Laplacians, which removes any locally planar signal, its median made robust to the
    texture that leaks through (an upper bound on textured ground: 20 % high on the
    simulator's images, right to 1 DN on Pléiades with 20 DN of added noise)."""
    a = np.asarray(a, np.float64)
    if min(a.shape) < 3:
        return 0.0
    return _noise_of(np.abs(_laplace_inner(a)))


def _noise_of(lap) -> float:
    """The noise σ (grey values) from absolute differences of Laplacians ``lap`` (finite): their
    median as a normal σ (× 1.4826), over the kernel's gain on white noise (6)."""
    return 1.4826 * _median(lap) / 6.0


def _median(a) -> float:
    """``np.median`` of the finite array ``a``, to the bit, without its generality's cost (a
    quarter of the time for a template's few thousand values, called ten times a point)."""
    a = np.asarray(a).ravel()
    k = a.size // 2
    if a.size % 2:
        return float(np.partition(a, k)[k])
    p = np.partition(a, (k - 1, k))
    return float((p[k - 1] + p[k]) / 2)


def _laplace_inner(a):
    """The difference of Laplacians (the kernel ``[1, −2, 1]ᵀ[1, −2, 1]``: the second
    difference down the columns, then along the rows) at the interior pixels of ``a``:
    ``(rows − 2, cols − 2)``, what :func:`noise_sigma` takes the median of."""
    r = a[1:-1]
    v = a[:-2] + a[2:] - 2.0 * r                              # the column second difference
    return (v[:, :-2] + v[:, 2:]) - 2.0 * v[:, 1:-1]


def largest_sigma(cov) -> float:
    """σ (px) of a 2 × 2 covariance ``cov`` (px²) in its weakest direction: the larger semi-axis."""
    return float(np.sqrt(np.linalg.eigvalsh(cov)[-1]))


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


def unmodelled_sigma(G, r, n_params: int, block: int = 4, w=None, other=None, floor: bool = False,
                     both: bool = False):
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
    correlate. ``floor``: the variance no smaller than its own standard error under noise alone
    — where a few blocks hold the information (point-sampled parcels) the estimate is noisy,
    and clipped at zero it stated 0.04 px for errors of 0.10 px on another simulator's scene.
    ``both``: ``(σ, σ with that floor)`` from one pass."""
    n = r.shape[0]
    m = n // block
    if m < 2:
        return (0.0, 0.0) if both else 0.0
    lo = (n - m * block) // 2

    mom = np.empty((3 if other is None else 6, m * m))
    kernel.block_moments(np.ascontiguousarray(G, float), np.ascontiguousarray(r, float),
                  _EMPTY if other is None else np.ascontiguousarray(other, float), lo, m, block, mom)
    g2, p, rr = mom[0], mom[1], float(mom[2].sum())
    if np.any(g2 <= 0):
        return (0.0, 0.0) if both else 0.0
    if other is None:
        delta = p / g2
        rss, unknowns = rr - float(delta @ p), m * m
    else:
        go, gc, q = mom[3], mom[4], mom[5]
        det = g2 * go - gc ** 2
        if np.any(det <= 1e-9 * g2 * go):
            return (0.0, 0.0) if both else 0.0
        delta, delta_o = (go * p - gc * q) / det, (g2 * q - gc * p) / det
        rss, unknowns = rr - float(delta @ p + delta_o @ q), 2 * m * m
        g2 = det / go                                   # the information on δ left by the other
    # the residuals less each block's fitted displacement: noise
    noise = rss / max(m * m * block * block - unknowns - n_params, 1)
    if w is None:
        wb = np.ones_like(g2)
    else:
        wb = w[lo:lo + m * block, lo:lo + m * block].reshape(m, block, m, block).sum(axis=(1, 3)).ravel() / block ** 2
    excess = np.sum(wb * (g2 * delta ** 2 - noise)) / np.sum(wb * g2)
    plain = float(np.sqrt(max(excess, 0.0)))
    if not (floor or both):
        return plain
    # the estimate's own standard error where no block displacement shows: each block's
    # term g2·δ² − σn² has variance 2σn⁴ when δ is noise alone
    floored = float(np.sqrt(max(excess, noise * np.sqrt(2.0 * np.sum(wb ** 2)) / np.sum(wb * g2))))
    return (plain, floored) if both else floored


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


SAMPLING_BLOCK = 8
"""Side (px) of the blocks within which point-sampled edges are taken to share their phase
error (an edge's crossings in neighbouring rows lie alike between their samples; on
point-sampled Voronoi parcels the σ grew by a tenth from 4 px blocks to 8, and little more
beyond)."""

#: A Gaussian-blurred straight edge, point-sampled at a random phase in two views and matched
#: by the cubic B-spline (1-D, 400 phases per blur σ of 0, 0.05 … 0.7 px): the ratio
#: ``Σ Δ±k² / Δ₀²`` (k = 1, 2) of the sample differences beside the crossing to the crossing's
#: own (0 for a hard edge: all of the step lies between two samples), and the RMS error (px)
#: of the position per view it leaves — 0.30 px unblurred (a uniform ±0.5 px phase), under
#: 0.01 px from a blur of 0.55 px on, where the interpolant places the edge between samples.
_SAMPLING_RATIO = np.array([0.0, 0.031, 0.078, 0.088, 0.124, 0.156, 0.186, 0.218, 0.270, 0.299, 0.342,
                            0.401, 0.450, 0.493, 0.565, 0.7])
_SAMPLING_PX = np.array([0.298, 0.238, 0.201, 0.163, 0.126, 0.099, 0.068, 0.048, 0.033, 0.021, 0.014,
                         0.008, 0.005, 0.003, 0.002, 0.0])


def sampling_px(a, noise: float):
    """``(ex, ey)`` ``(n, n)``: σ (px) of where a point-sampled edge at each pixel of ``a``
    (grey values) lies, along x and along y, in one view.

    A hard edge between two samples lies anywhere between them (±0.5 px, σ 0.29 px): the
    samples say only which side of it each pixel centre is on. A crossing (a difference of
    neighbouring samples above twice its noise, ``noise`` the images' σ) is told from a blurred
    edge, which samples place well, by the share of the change the two differences on each
    side hold (none for a hard edge; white texture rarely has four quiet neighbours); the σ
    from that share is the table above, given to the four pixels whose values the crossing's
    place moves. 0 away from crossings (and for any band-limited texture)."""
    a = np.ascontiguousarray(a, np.float64)
    v = 2.0 * noise ** 2                                  # noise variance of a difference
    ex, ey = np.empty_like(a), np.empty(a.shape[::-1])
    kernel.crossing_sigma(a, v, _SAMPLING_RATIO, _SAMPLING_PX, ex)
    kernel.crossing_sigma(np.ascontiguousarray(a.T), v, _SAMPLING_RATIO, _SAMPLING_PX, ey)
    return ex, ey.T


def sampling_scatter(J, gx, gy, ex, ey, block: int = SAMPLING_BLOCK):
    """``Σ_B c cᵀ`` ``(k, k)``: the covariance of ``Jᵀr`` for the residuals point sampling
    leaves, ``r = gx·ux + gy·uy`` with ``ux``, ``uy`` the edges' displacements (σ ``ex``,
    ``ey``, px, :func:`sampling_px`), alike within a ``block × block`` block and independent
    between blocks. ``J`` ``(n, n, k)``: the (weighted) design on the template grid; ``gx``,
    ``gy`` ``(n, n)``: the gradients (grey values per px). The position's covariance in one
    view is ``N⁻¹ Σ N⁻¹`` (``N`` the normal matrix)."""
    mb = -(-J.shape[0] // block)
    cx, cy = np.empty((mb * mb, J.shape[2])), np.empty((mb * mb, J.shape[2]))
    kernel.edge_sums(np.ascontiguousarray(J, float), np.ascontiguousarray(gx * ex), np.ascontiguousarray(gy * ey),
                     block, cx, cy)
    return cx.T @ cx + cy.T @ cy


def template_sigmas(a, halves, block: int = 4, stop: float = 0.0) -> list[tuple[float, float]]:
    """For each half size ``h`` of ``halves``, the σ (px) the ``(2h+1)²`` template centred in
    ``a`` (grey values, square, odd side) can fix a position to in its weakest direction before
    any match: ``(from the noise, from the noise and point sampling)`` — the first as
    :func:`texture_sigma`, the second adding :func:`sampling_px`'s displacements in both views
    (the position alone; the match's shape adds to it). One pass over ``a`` for all sizes;
    with ``stop`` > 0, none after the first size whose two σ are both at most ``stop``."""
    a = np.asarray(a, np.float64)
    c = a.shape[0] // 2
    lap = np.abs(_laplace_inner(a))        # at the pixels of a[1:-1, 1:-1]
    gy, gx = np.gradient(a)
    edges = None                # the crossings, once, at the largest template's noise
    out = []
    for h in halves:
        sl = slice(c - h, c + h + 1)
        inner = slice(c - h + 1, c + h)
        noise = _noise_of(lap[c - h:c + h - 1, c - h:c + h - 1])
        var = noise ** 2
        x, y = gx[inner, inner].ravel(), gy[inner, inner].ravel()
        G = np.array([[x @ x, x @ y], [x @ y, y @ y]])
        lam = float(np.linalg.eigvalsh(G)[0]) - 0.5 * var * x.size
        s_noise = float(np.sqrt(2.0 * var / lam)) if lam > 0 else float("inf")
        if not np.isfinite(s_noise):
            out.append((s_noise, s_noise))
            continue
        if edges is None:
            top = max(halves)
            edges = sampling_px(a, _noise_of(lap[c - top:c + top - 1, c - top:c + top - 1]))
        ex, ey = edges[0][sl, sl], edges[1][sl, sl]
        if not (ex.any() or ey.any()):
            out.append((s_noise, s_noise))
            if s_noise <= stop:
                break
            continue
        J = np.stack([gx[sl, sl], gy[sl, sl]], -1)
        Mi = np.linalg.inv(np.einsum("ijk,ijl->kl", J, J))
        C = 2.0 * Mi @ sampling_scatter(J, J[..., 0], J[..., 1], ex, ey, block) @ Mi
        out.append((s_noise, float(np.hypot(s_noise, np.sqrt(max(np.linalg.eigvalsh(C)[-1], 0.0))))))
        if out[-1][1] <= stop:
            break
    return out
