"""JPEG block-noise reduction for display and matching (Tadono et al. 2008, §3).

PRISM data were JPEG-compressed on board; flat areas show steps on the 8×8 (or 16×8) grid of
the compression blocks. This is a simplified deblocking filter in the spirit of H.264's loop
filter and of Kamiya & Saito (2007): at every block boundary, where the step across the
boundary is small (below ``alpha``) and both sides are smooth (their gradients next to the
boundary below ``beta``), the step is spread as a linear ramp over ``half`` pixels on each side.
Steps on real edges (large, or amid texture) are left alone. Vertical boundaries are filtered
first, then horizontal ones, as in H.264.

Image arrays are (rows, cols); the block grid starts at the top-left pixel.
"""
from __future__ import annotations

import numpy as np

from prismstation.errors import ModelError


def _steps(img: np.ndarray, bw: int) -> tuple[np.ndarray, np.ndarray]:
    """|horizontal differences| across block boundaries and inside blocks."""
    d = np.abs(np.diff(img.astype(np.float64), axis=1))   # d[:, j] = img[:, j+1] − img[:, j]
    at = (np.arange(d.shape[1]) + 1) % bw == 0
    return d[:, at], d[:, ~at]


def blockiness(img, block=(8, 8)) -> float:
    """Mean |step| across block boundaries divided by mean |step| inside blocks (rows and
    columns pooled). About 1 for an image without block artefacts, larger with them."""
    img = np.asarray(img)
    bh, bw = block
    a1, i1 = _steps(img, bw)
    a2, i2 = _steps(img.T, bh)
    at = np.concatenate([a1.ravel(), a2.ravel()]).mean()
    inside = np.concatenate([i1.ravel(), i2.ravel()]).mean()
    return float(at / inside) if inside > 0 else float("inf")


def _filter_columns(f: np.ndarray, bw: int, alpha: float, beta: float, half: int) -> None:
    """Filter the vertical block boundaries of float image ``f`` in place."""
    cols = np.arange(bw, f.shape[1] - half + 1, bw)     # q0 column; p0 = cols − 1
    cols = cols[cols - half >= 0]
    if cols.size == 0:
        return
    p = np.stack([f[:, cols - 1 - k] for k in range(half)])   # (half, rows, nb)
    q = np.stack([f[:, cols + k] for k in range(half)])
    step = q[0] - p[0]
    # the part of the step not explained by the local gradient on either side
    grad = 0.5 * ((p[0] - p[1]) + (q[1] - q[0]))
    jump = step - grad
    # both sides smooth over the whole ramp: their own gradients stay below beta
    smooth = np.all(np.abs(np.diff(p, axis=0)) < beta, axis=0) & \
        np.all(np.abs(np.diff(q, axis=0)) < beta, axis=0)
    mask = smooth & (np.abs(step) < alpha)
    delta = np.where(mask, jump, 0.0)
    for k in range(half):
        w = (half - k - 0.5) / (2.0 * half)
        f[:, cols - 1 - k] += w * delta
        f[:, cols + k] -= w * delta


def deblock(img, block=(8, 8), alpha: float | None = None, beta: float | None = None,
            half: int | None = None) -> np.ndarray:
    """Reduce block artefacts of a JPEG-compressed image.

    Parameters
    ----------
    img : (rows, cols) grey image, any integer or float dtype.
    block : (block rows, block cols), e.g. (8, 8) or (8, 16) for 16×8 units.
    alpha : largest boundary step treated as an artefact (grey levels). Default 24 for
        8-bit data, scaled by the image's 1–99 % range / 255 for other dtypes.
    beta : largest gradient beside the boundary for a side to count as smooth. Default alpha / 4.
    half : ramp half-length in pixels (default 2: measured on JPEG-compressed real imagery,
        longer ramps smear texture and raise the error to the original).

    Returns
    -------
    Filtered image with the dtype of ``img`` (rounded and clipped for integers).
    """
    a = np.asarray(img)
    if a.ndim != 2:
        raise ModelError(f"deblock needs a 2-D grey image, got shape {a.shape}")
    bh, bw = (int(block[0]), int(block[1]))
    if bh < 2 or bw < 2:
        raise ModelError(f"block size {block} is too small")
    if alpha is None:
        if a.dtype == np.uint8:
            scale = 1.0
        else:
            lo, hi = np.nanpercentile(a, [1, 99]) if a.size else (0.0, 255.0)
            scale = max(float(hi - lo), 1e-12) / 255.0
        alpha = 24.0 * scale
    if beta is None:
        beta = alpha / 4.0
    if half is None:
        half = min(2, bh // 2, bw // 2)
    f = a.astype(np.float64)
    _filter_columns(f, bw, alpha, beta, half)
    ft = f.T.copy()
    _filter_columns(ft, bh, alpha, beta, half)
    f = ft.T
    if np.issubdtype(a.dtype, np.integer):
        info = np.iinfo(a.dtype)
        return np.clip(np.rint(f), info.min, info.max).astype(a.dtype)
    return f.astype(a.dtype)
