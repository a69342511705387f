"""Semi-global matching of one rectified pair, and per-cell fusion of the pairs' heights.

Pair level: two images already resampled onto one frame in which the parallax runs along x
(columns) only. OpenCV's StereoSGBM (semi-global matching, Hirschmüller 2008, with its own
left–right check and speckle filter) gives the disparity ``d = x_left − x_right`` in pixels
(1/16 px steps, parabolic subpixel), NaN where it found none. The search range comes from a
stated height uncertainty: ``|Δh| ≤ R`` metres is ``|d| ≤ k·R/g`` pixels for a pair whose
along-track relief factors differ by ``k`` (``tanθ_left·s_left − tanθ_right·s_right``) on a
frame of ``g`` metres per pixel.

Fusion: up to three height estimates per cell (F–N, N–B, F–B), each with a σ; a value agrees
when it lies within ``τ·σ`` of the cell's median; the fused height is the σ-weighted mean of
the agreeing values and the quality the number of them. Blunders are removed, not averaged.
"""
from __future__ import annotations

from prismstation.core.lazy_cv2 import cv2  # imported at first use: start-up saving
import numpy as np

#: a-priori σ of one refined SGBM disparity (pixels): the fusion's tolerance is built from it.
#: Checked against the scatter between the pairs (``Dsm.info["levels"][…]["pair_scatter_in_sigma"]``):
#: 1.10 at 2.5 m frames on a simulated triplet (0.35 px gave 1.33)
SIGMA_DISPARITY_PX = 0.45


def disparity_search(half_range_m: float, k: float, g: float, block: int = 5) -> tuple[int, int]:
    """``(min_disparity, num_disparities)`` covering ``|Δh| ≤ half_range_m`` (pixels; the count is
    a multiple of 16, as StereoSGBM requires)."""
    r = abs(k) * float(half_range_m) / float(g)
    lo = int(np.floor(-r)) - 1
    n = int(np.ceil((2 * r + 3) / 16.0)) * 16
    return lo, max(n, 16)


def to_uint8(img: np.ndarray, valid: np.ndarray | None = None) -> np.ndarray:
    """Linear stretch of the 0.5–99.5 % range of ``img`` (NaN ignored) to 0–255, NaN → 0."""
    step = max(1, int(np.sqrt(img.size / 250_000)))
    sub = img[::step, ::step]
    v = sub[np.isfinite(sub) if valid is None else valid[::step, ::step] & np.isfinite(sub)]
    if v.size == 0:
        return np.zeros(img.shape, np.uint8)
    lo, hi = np.percentile(v, [0.5, 99.5])
    out = (np.nan_to_num(img, nan=lo) - lo) * (255.0 / max(hi - lo, 1e-6))
    return np.clip(out, 0, 255).astype(np.uint8)


def sgbm(left: np.ndarray, right: np.ndarray, min_disparity: int, num_disparities: int, *,
         block: int = 5, uniqueness: int = 5, lr_max_diff: int = 1) -> np.ndarray:
    """Disparity ``x_left − x_right`` (pixels, float32, NaN where none) of two uint8 images.

    Left–right consistency: OpenCV's ``disp12MaxDiff`` (pixels); small blobs that differ from
    their surroundings by more than 2 px are removed (speckle filter); disparities within a
    pixel of either end of the range are dropped (the truth may lie beyond).
    """
    m = cv2.StereoSGBM_create(minDisparity=int(min_disparity), numDisparities=int(num_disparities),
                              blockSize=block, P1=8 * block * block, P2=32 * block * block,
                              disp12MaxDiff=lr_max_diff, uniquenessRatio=uniqueness,
                              speckleWindowSize=64, speckleRange=2,
                              mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)
    d = m.compute(left, right).astype(np.float32) / 16.0
    # at an end of the search range the true disparity may lie beyond it: no match
    d[(d < min_disparity + 1) | (d > min_disparity + num_disparities - 2)] = np.nan
    # the SGBM edge band where the search leaves the right image
    d[:, : max(min_disparity + num_disparities, 0)] = np.nan
    return d


def refine_subpixel(left: np.ndarray, right: np.ndarray, disparity: np.ndarray, half: int = 2) -> np.ndarray:
    """Subpixel disparity from the ZNCC of ``(2·half+1)²`` windows at ``round(d) − 1, 0, +1``
    (parabola through the three scores); where the parabola has no maximum the input stays.

    ``left``, ``right`` float32 images of the frame; ``disparity`` as from :func:`sgbm`.
    """
    rows, cols = left.shape
    size = (2 * half + 1, 2 * half + 1)
    box = lambda a: cv2.boxFilter(a, cv2.CV_32F, size, borderType=cv2.BORDER_REFLECT)  # noqa: E731
    d0 = np.rint(np.nan_to_num(disparity, nan=0.0)).astype(np.float32)
    xx = np.arange(cols, dtype=np.float32)[None, :] - d0
    yy = np.repeat(np.arange(rows, dtype=np.float32)[:, None], cols, 1)
    m_l = box(left)
    v_l = box(left * left) - m_l * m_l
    scores = []
    for s in (-1.0, 0.0, 1.0):
        r = cv2.remap(right, xx - s, yy, cv2.INTER_NEAREST, borderMode=cv2.BORDER_REPLICATE)
        m_r = box(r)
        v_r = box(r * r) - m_r * m_r
        scores.append((box(left * r) - m_l * m_r) / np.sqrt(np.maximum(v_l * v_r, 1e-12)))
    a, b, c = scores
    den = a - 2 * b + c
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = np.where(den < 0, 0.5 * (a - c) / den, np.nan)
    ok = np.isfinite(disparity) & (np.abs(frac) <= 0.75)
    return np.where(ok, d0 + frac, disparity).astype(np.float32)


def fuse(values: np.ndarray, sigmas: np.ndarray, tau: float = 3.0) -> tuple[np.ndarray, np.ndarray]:
    """Fuse per-cell height estimates.

    Parameters
    ----------
    values : (P, rows, cols) metres, NaN where a pair has none.
    sigmas : (P, rows, cols) or (P,) their σ (metres).
    tau : agreement threshold in σ of the difference to the median.

    Returns
    -------
    heights : (rows, cols) σ-weighted mean of the agreeing values; NaN where fewer than two
        agree (cells with one value, or two that disagree, are left to :func:`resolve_single`).
    quality : (rows, cols) uint8, number of agreeing values (0 where fewer than two).
    """
    v = np.asarray(values, np.float32)
    s = np.asarray(sigmas, np.float32)
    s = np.broadcast_to(s[:, None, None] if s.ndim == 1 else s, v.shape)
    finite = np.isfinite(v)
    with np.errstate(invalid="ignore", divide="ignore"):
        med = _nanmedian0(v)
        # a value's tolerance: its own σ and the median's (≈ the smallest σ present)
        s_med = np.min(np.where(finite, s, np.inf), axis=0)
        agree = np.abs(v - med) <= tau * np.sqrt(s * s + s_med * s_med)
        w = np.where(agree, 1.0 / (s * s), 0.0)
        n = agree.sum(axis=0)
        h = (np.where(agree, v, 0.0) * w).sum(axis=0) / w.sum(axis=0)
    h = np.where(n >= 2, h, np.nan).astype(np.float32)
    return h, np.where(n >= 2, n, 0).astype(np.uint8)


def resolve_single(fused: np.ndarray, quality: np.ndarray, values: np.ndarray, tolerance_m: float):
    """Cells with no agreeing pair: take the candidate closest to the local median of the
    fused surface (5×5, voids filled from the nearest fused cell) if within ``tolerance_m``;
    quality 1. Arrays are changed in place and returned."""
    from scipy import ndimage
    todo = (quality == 0) & np.isfinite(values).any(axis=0)
    ok = np.isfinite(fused)
    if not todo.any() or not ok.any():
        return fused, quality
    idx = ndimage.distance_transform_edt(~ok, return_distances=False, return_indices=True)
    local = cv2.medianBlur(fused[tuple(idx)].astype(np.float32), 5)
    with np.errstate(invalid="ignore"):
        dev = np.abs(values - local[None])
        best = np.argmin(np.where(np.isfinite(dev), dev, np.inf), axis=0)
    cand = np.take_along_axis(values, best[None], 0)[0]
    take = todo & (np.abs(cand - local) <= tolerance_m)
    fused[take] = cand[take]
    quality[take] = 1
    return fused, quality


def _nanmedian0(v: np.ndarray) -> np.ndarray:
    """Median over axis 0 ignoring NaN (NaN where all are), without numpy's warnings (which
    are not thread-safe to silence)."""
    srt = np.sort(v, axis=0)                       # NaN last
    n = np.isfinite(v).sum(axis=0)
    lo = np.clip((n - 1) // 2, 0, len(v) - 1)[None]
    hi = np.clip(n // 2, 0, len(v) - 1)[None]
    m = 0.5 * (np.take_along_axis(srt, lo, 0)[0] + np.take_along_axis(srt, hi, 0)[0])
    return np.where(n > 0, m, np.nan)


def median_filter(disparity: np.ndarray, size: int = 3) -> np.ndarray:
    """Each disparity replaced by the median of the ``size × size`` window around it, NaN
    (no match) left out and kept NaN (the outlier filter of the usual SGM chains; float32)."""
    rows, cols = disparity.shape
    r = size // 2
    pad = np.pad(np.asarray(disparity, np.float32), r, constant_values=np.nan)
    med = _nanmedian0(np.stack([pad[i:i + rows, j:j + cols] for i in range(size) for j in range(size)]))
    return np.where(np.isfinite(disparity), med, np.nan).astype(np.float32)
