"""One DSM tile from the triplet: pairs rectified through the fitted model, matched, fused.

The matching frame is a ground grid aligned with the flight direction: frame pixel ``(x, y)``
(x column, y row, centres at ``i + 0.5``) is the map point ``P = origin + g·(x·t + y·u)``,
``t`` the unit flight direction, ``u`` across it, ``g`` metres per pixel. View ``V`` is
resampled onto the frame at the prior surface ``h0``: ``O_V(P) = I_V(G_V(W_V(P)))`` with
``W_V(P) = P + h0(P)·r_V(P)``, ``r_V`` the relief shift per metre of height (docs/model.md §2) and
``G_V`` the view's ancillary affine followed by its fitted bias. Because the across-track
relief shift is the same in every view, a height error moves a point along ``t`` only: the
parallax runs along x. A ground point ``Q`` at height ``h`` seen at ``P_A`` in the left and
``P_B`` in the right image satisfies ``W_A(P_A) − W_B(P_B) = h·(r_A − r_B)(Q)``, so

    h = ((P_A − P_B)·t + h0(P_A)·r_A·t − h0(P_B)·r_B·t) / ((r_A − r_B)·t)

exactly (given the model), whatever the prior; ``Q = W_A(P_A) − h·r_A``. The left view is the
more forward one (F–N, N–B, F–B), so disparities grow with height.

Heights are ellipsoidal metres, map coordinates metres of the scene's CRS.
"""
from __future__ import annotations

from dataclasses import dataclass

from prismstation.core.lazy_cv2 import cv2  # imported at first use: start-up saving
import numpy as np

from prismstation.core.models import prism
from prismstation.core.matching import sgm
from prismstation.core.models.solution import Solution
from prismstation.core.adjustment.stats import nmad

PAIRS = (("F", "N"), ("N", "B"), ("F", "B"))


@dataclass(frozen=True)
class Frame:
    """A track-aligned ground grid: ``origin`` (E, N) of its top-left corner, unit ``t`` (+x)
    and ``u`` (+y), ``g`` metres per pixel, ``shape`` (rows, cols)."""

    origin: tuple
    t: tuple
    u: tuple
    g: float
    shape: tuple

    def to_map(self, x, y) -> np.ndarray:
        """Map points ``(..., 2)`` of frame coordinates ``x``, ``y`` (pixels)."""
        x, y = np.asarray(x, float)[..., None], np.asarray(y, float)[..., None]
        return np.asarray(self.origin) + self.g * (x * np.asarray(self.t) + y * np.asarray(self.u))

    def affine(self) -> np.ndarray:
        """2×3 matrix: frame coordinates → map."""
        t, u = np.asarray(self.t), np.asarray(self.u)
        return np.column_stack([self.g * t, self.g * u, np.asarray(self.origin)])


def frame_over(sol: Solution, corners_en, g: float, margin_x_m: float, margin_y_m: float) -> Frame:
    """The frame aligned with the flight direction at the centre of ``corners_en`` ``(k, 2)``
    covering them with the margins (metres) along and across track."""
    c = np.asarray(corners_en, float)
    mid = c.mean(axis=0)
    _, t = sol.scene.track.foot(mid)
    u = np.array([-t[1], t[0]])
    x, y = (c - mid) @ t, (c - mid) @ u
    x0, y0 = x.min() - margin_x_m, y.min() - margin_y_m
    cols = int(np.ceil((x.max() + margin_x_m - x0) / g))
    rows = int(np.ceil((y.max() + margin_y_m - y0) / g))
    origin = mid + x0 * t + y0 * u
    return Frame(tuple(origin), tuple(t), tuple(u), float(g), (rows, cols))


def view_affine(sol: Solution, view: str) -> np.ndarray:
    """2×3 matrix of ``G_V``: map metres (after the relief shift) → image pixels, bias included."""
    m = sol.scene.views[view].map_to_image.matrix
    b = sol.bias[view]
    lin = (np.eye(2) + b.M) @ m[:, :2]
    return np.column_stack([lin, (np.eye(2) + b.M) @ m[:, 2] + b.b])


def relief_rate(sol: Solution, view: str, frame: Frame, step: int = 32) -> np.ndarray:
    """``r_V`` (rows, cols, 2) float32: map shift per metre of height on the frame's pixel
    centres, computed every ``step`` pixels and interpolated (it varies slowly)."""
    rows, cols = frame.shape
    ys = np.linspace(0.5, rows - 0.5, max(2, rows // step + 2))
    xs = np.linspace(0.5, cols - 0.5, max(2, cols // step + 2))
    en = frame.to_map(*np.meshgrid(xs, ys))
    r = prism.relief_shift(sol.scene, sol.scene.views[view], en, 1.0).astype(np.float32)
    return cv2.resize(r, (cols, rows), interpolation=cv2.INTER_LINEAR)


def resample_view(image: np.ndarray, index_of, sol: Solution, view: str, frame: Frame,
                  h0: np.ndarray, r: np.ndarray) -> np.ndarray:
    """``O_V`` on the frame (float32, NaN outside the image array).

    ``image`` an array of the view (window, possibly reduced); ``index_of`` (2, 3) maps image
    pixel coordinates to that array's index coordinates (so that pixel centre ``i + 0.5`` of
    the full image becomes the array index of that sample).
    """
    G = view_affine(sol, view)
    m = np.asarray(index_of, float)
    A = m[:, :2] @ G[:, :2]                       # map → array index, linear part
    o = m[:, :2] @ G[:, 2] + m[:, 2]
    F = frame.affine()                            # frame coords → map
    M = A @ F[:, :2]                              # frame coords → array index
    c = A @ F[:, 2] + o + 0.5 * M.sum(axis=1)     # (pixel centres at i + 0.5)
    rows, cols = frame.shape
    i = np.arange(cols, dtype=np.float32)[None, :]
    j = np.arange(rows, dtype=np.float32)[:, None]
    ar = r @ A.T.astype(np.float32)               # array-index shift per metre of height
    mx = (c[0] + M[0, 0] * i + M[0, 1] * j + h0 * ar[..., 0]).astype(np.float32)
    my = (c[1] + M[1, 0] * i + M[1, 1] * j + h0 * ar[..., 1]).astype(np.float32)
    return cv2.remap(np.asarray(image, np.float32), mx, my, cv2.INTER_CUBIC,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)


@dataclass(frozen=True)
class FrameImage:
    """One view on the frame, prepared once for all its pairs: ``u8`` (stretched, for SGBM),
    ``f32`` (NaN → 0, for the refinement), ``bad`` (uint8, 1 outside the image and within two
    blocks of it), ``r`` (rows, cols, 2) relief rate and ``rt`` its along-track part."""

    u8: np.ndarray
    f32: np.ndarray
    bad: np.ndarray
    r: np.ndarray
    rt: np.ndarray


def prepare(ortho: np.ndarray, r: np.ndarray, frame: Frame, block: int = 5) -> FrameImage:
    """A :class:`FrameImage` from a resampled view (float32, NaN outside) and its relief rate.

    The band of two blocks along the image edge is marked bad: SGBM's aggregation paths run
    through the blank outside there (measured: blunders within about two blocks)."""
    valid = np.isfinite(ortho)
    bad = cv2.dilate((~valid).astype(np.uint8), np.ones((2 * block, 2 * block), np.uint8))
    return FrameImage(sgm.to_uint8(ortho, valid), np.where(valid, ortho, 0).astype(np.float32), bad,
                      r, r @ np.asarray(frame.t, np.float32))


def match_pair(left: FrameImage, right: FrameImage, frame: Frame, h0: np.ndarray,
               half_range_m: float, transform, shape, *, block: int = 5,
               refine: bool = False) -> tuple[np.ndarray, np.ndarray, float]:
    """Match two prepared frame images; the heights binned onto the north-up grid
    ``transform`` (a, b, c, d, e, f), ``shape``: ``(mean height, sample count, k)`` per cell,
    NaN where none; ``k = (r_A − r_B)·t``, metres of parallax per metre of height."""
    rt_l, rt_r, r_l = left.rt, right.rt, left.r
    k = float(np.median(rt_l[::8, ::8] - rt_r[::8, ::8]))
    lo, n = sgm.disparity_search(half_range_m, k, frame.g, block)
    d = sgm.sgbm(left.u8, right.u8, lo, n, block=block)
    if refine:
        d = sgm.refine_subpixel(left.f32, right.f32, d)
    rows, cols = frame.shape
    # whole-frame arrays (float32, no gathers): the right image's column of each left pixel
    xr = np.arange(cols, dtype=np.float32)[None, :] - d
    yy = np.repeat(np.arange(rows, dtype=np.float32)[:, None], cols, 1)
    at_r = lambda a, how: cv2.remap(a, xr, yy, how, borderMode=cv2.BORDER_CONSTANT, borderValue=1)  # noqa: E731
    d[(left.bad > 0) | (at_r(right.bad, cv2.INTER_NEAREST) > 0)] = np.nan
    h0_r = at_r(h0, cv2.INTER_LINEAR)               # h0 at the right image's position
    rr = at_r(rt_r, cv2.INTER_LINEAR)
    h = (d * frame.g + h0 * rt_l - h0_r * rr) / (rt_l - rr)
    # ground position W_A(P_A) − h·r_A as the output grid's fractional cell index; float32
    # relative to the grid's corner (35 km in float32: millimetres)
    a, _, c, _, e, f = (float(v) for v in tuple(transform)[:6])
    t, u, g = np.asarray(frame.t), np.asarray(frame.u), frame.g
    x = (np.arange(cols, dtype=np.float32) + 0.5)[None, :]
    y = (np.arange(rows, dtype=np.float32) + 0.5)[:, None]
    dh = h0 - h
    cell = []
    for axis, origin, step in ((0, c, a), (1, f, e)):
        o = np.float32((frame.origin[axis] - origin) / step)
        cell.append(np.floor(o + x * np.float32(g * t[axis] / step) + y * np.float32(g * u[axis] / step)
                             + dh * (r_l[..., axis] / np.float32(step))))
    ci, ri = cell
    ok = np.isfinite(h) & (ci >= 0) & (ci < shape[1]) & (ri >= 0) & (ri < shape[0])
    kk = ri[ok].astype(np.int64) * shape[1] + ci[ok].astype(np.int64)
    cnt = np.bincount(kk, minlength=shape[0] * shape[1]).reshape(shape)
    s = np.bincount(kk, weights=h[ok], minlength=shape[0] * shape[1]).reshape(shape)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(cnt > 0, s / cnt, np.nan).astype(np.float32), cnt, k


@dataclass(frozen=True)
class TileResult:
    """Fused heights (rows, cols) float32 NaN-void, quality (pairs agreeing, uint8), the pair
    grids (P, rows, cols) and their sample counts, and ``z_nmad``: the NMAD of the F–B
    height's differences to F–N and N–B in units of their formal σ (1 when the a-priori
    disparity σ is right; from ``z_count`` differences)."""

    heights: np.ndarray
    quality: np.ndarray
    pair_heights: np.ndarray
    pair_counts: np.ndarray
    z_nmad: float = float("nan")
    z_count: int = 0


def tile_dsm(sol: Solution, images: dict, frame: Frame, h0: np.ndarray, transform, shape,
             half_range_m: float, *, pairs=PAIRS, block: int = 5, refine: bool = False,
             sigma_px: float = sgm.SIGMA_DISPARITY_PX, tau: float = 3.0) -> TileResult:
    """Heights of a north-up output tile (``transform``, ``shape``) from the views in ``images``
    (``{view: (array, index_of)}``, see :func:`resample_view`), matched on ``frame`` around the
    prior ``h0`` (frame-shaped, metres) within ``±half_range_m``."""
    views = sorted({v for p in pairs for v in p})
    r = {v: relief_rate(sol, v, frame) for v in views}
    fi = {v: prepare(resample_view(*images[v], sol, v, frame, h0, r[v]), r[v], frame, block) for v in views}
    vals, counts, sig = [], [], []
    for a, b in pairs:
        hv, n, k = match_pair(fi[a], fi[b], frame, h0, half_range_m, transform, shape,
                              block=block, refine=refine)
        vals.append(hv)
        counts.append(n)
        with np.errstate(divide="ignore"):
            sig.append(sigma_px * frame.g / abs(k) / np.sqrt(np.maximum(n, 1)))
    vals, counts, sig = np.stack(vals), np.stack(counts), np.stack(sig)
    h, q = sgm.fuse(vals, sig, tau)
    # the σ claim against the scatter: differences of the F–B height to the other two, in σ
    z = [(vals[2] - vals[p]) / np.sqrt(sig[2] ** 2 + sig[p] ** 2) for p in (0, 1)] if len(vals) == 3 else []
    z = np.concatenate([v[q == 3] for v in z]) if z else np.zeros(0)
    z = z[np.isfinite(z)]
    # robust: NMAD of z (1.0 when the σ are right), from the cells all three pairs agree on
    z_nmad = nmad(z)
    tol = tau * 2 * float(sig.max())
    h, q = sgm.resolve_single(h, q, vals, max(tol, 3 * frame.g))
    return TileResult(h, q, vals, counts.astype(np.int32), z_nmad, int(z.size))
