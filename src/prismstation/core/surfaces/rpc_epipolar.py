"""Local epipolar rectification of an RPC pair, and triangulation of its disparities.

Over a tile of the left image, a pair of pushbroom images is close to a pair of affine
cameras: the s2p approach (de Franchis et al. 2014) rectifies each tile by affine maps fitted
to that approximation. Here the correspondences come from the (biased) RPCs themselves: image
points of the left tile lifted to ground at three heights spanning the tile's a-priori height
range, and projected into the right image. Their affine fundamental matrix (the left null
vector of the centred 4-column correspondence matrix, Hartley & Zisserman §14.2) gives the
epipolar direction in each image; the left image is rotated so that its epipolar lines are
rows, the right one is mapped so that corresponding points share a row and, at the middle of
the height range, a column. The disparity ``d = x'_left − x'_right`` then grows with height.

Triangulation goes through the RPCs, bias included, not through the affine approximation:
on a lattice of the rectified grid (every ``step`` px) each left pixel's ray is lifted to three
heights (:meth:`BiasedRpc.localize`), its ground point mapped (``to_map``) and projected into
the right image; per pixel, the right image's rectified column and the map position are
quadratic in height, and the height is where that column equals ``x' − d``.

Conventions: image points ``(x, y)`` = (column, row) pixels, pixel centre at ``+0.5``; the
rectified grid likewise (array index ``i`` ↔ coordinate ``i + 0.5``). Heights are
ellipsoidal metres; map coordinates are whatever ``to_map`` returns (metres of a projected CRS).
"""
from __future__ import annotations

from dataclasses import dataclass

from prismstation.core.lazy_cv2 import cv2  # imported at first use: start-up saving
import numpy as np

from prismstation.core.models.rpc_bias import as_biased
from prismstation.errors import ModelError

#: pixels the rectified grid reaches beyond SGBM's edge band and the search on either side
EDGE_PAD_PX = 8


@dataclass(frozen=True)
class PairRectification:
    """Affine maps of a left-image tile and the right image onto one rectified grid.

    ``left``, ``right`` (2, 3): image pixel ``(x, y)`` → rectified ``(x', y')``; ``shape``
    (rows, cols) of the grid; ``disparity`` (lo, hi) px: ``x'_left − x'_right`` over the
    height range ``heights`` (lo, hi) m at the tile's sample points, widened by the margin;
    ``search`` (min_disparity, num_disparities) StereoSGBM's range covering it (a multiple of
    16 disparities); ``epipolar_error_px``:
    the largest ``|y'_left − y'_right|`` of exact RPC correspondences over the tile and height
    range (the affine approximation's error); ``px_per_m``: median of ``|∂d/∂h|``.
    """

    left: np.ndarray
    right: np.ndarray
    shape: tuple
    disparity: tuple
    search: tuple
    heights: tuple
    epipolar_error_px: float
    px_per_m: float

    def inverse(self, which: str) -> np.ndarray:
        """(2, 3): rectified ``(x', y')`` → image pixel, of ``"left"`` or ``"right"``."""
        return invert_affine(self.left if which == "left" else self.right)


def invert_affine(m: np.ndarray) -> np.ndarray:
    lin = np.linalg.inv(m[:, :2])
    return np.column_stack([lin, -lin @ m[:, 2]])


def apply_affine(m: np.ndarray, x, y):
    x, y = np.asarray(x, float), np.asarray(y, float)
    return m[0, 0] * x + m[0, 1] * y + m[0, 2], m[1, 0] * x + m[1, 1] * y + m[1, 2]


def correspondences(model_a, model_b, window, heights, n: int = 7):
    """Exact RPC correspondences over the left window ``(x0, y0, width, height)`` px: an
    ``n × n`` grid lifted to each of ``heights`` (m) and projected into the right image.
    Returns ``pa`` (k, 2), ``pb`` (k, 2), ``h`` (k,)."""
    a, b = as_biased(model_a), as_biased(model_b)
    x0, y0, w, hgt = (float(v) for v in window)
    gx, gy = np.meshgrid(np.linspace(x0, x0 + w, n), np.linspace(y0, y0 + hgt, n))
    pa, pb, hh = [], [], []
    for h in heights:
        lon, lat = a.localize(gx.ravel(), gy.ravel(), np.full(gx.size, float(h)))
        xb, yb = b.project(lon, lat, float(h))
        pa.append(np.column_stack([gx.ravel(), gy.ravel()]))
        pb.append(np.column_stack([xb, yb]))
        hh.append(np.full(gx.size, float(h)))
    return np.concatenate(pa), np.concatenate(pb), np.concatenate(hh)


def rectify_pair(model_a, model_b, window, height_range, *, margin_px: float = 4.0) -> PairRectification:
    """The rectification of the left tile ``window`` = (x0, y0, width, height) px and the right
    image, for ground within ``height_range`` = (lo, hi) ellipsoidal metres.

    ``model_a``, ``model_b``: :class:`~prismstation.core.models.rpc.Rpc` or
    :class:`~prismstation.core.models.rpc_bias.BiasedRpc` (the fitted bias is part of the geometry).
    The grid covers the window's rotated bounding box, widened on the left by the largest
    disparity plus ``EDGE_PAD_PX`` (StereoSGBM matches nothing in its leftmost
    ``max disparity`` columns) and on the right by the most negative one; the disparity range
    is widened by ``margin_px`` on each side (what remains of the bias's uncertainty, and
    the affine approximation's error). Raises :class:`ModelError` if the pair has no stereo
    (parallel rays) or the right image would be mirrored.
    """
    lo, hi = (float(v) for v in height_range)
    if not hi > lo:
        raise ModelError(f"height range {lo:g}..{hi:g} m is empty")
    mid = 0.5 * (lo + hi)
    pa, pb, hh = correspondences(model_a, model_b, window, (lo, mid, hi))
    ma, mb = pa.mean(axis=0), pb.mean(axis=0)
    _, s, vt = np.linalg.svd(np.column_stack([pa - ma, pb - mb]), full_matrices=False)
    nv = vt[-1]
    na = np.hypot(nv[0], nv[1])
    if na < 1e-9 or np.hypot(nv[2], nv[3]) < 1e-9:
        raise ModelError("the pair's epipolar geometry is degenerate (no overlap or no stereo)")
    ab, cd = nv[:2] / na, nv[2:] / na
    rot = np.array([[ab[1], -ab[0]], [ab[0], ab[1]]])           # rows x', y' (det +1)
    L = np.column_stack([rot, -rot @ ma])
    ya = (pa - ma) @ ab
    yb = -(pb - mb) @ cd
    # right x' fitted to the left x' at the middle height: x'_b = α·(pb − mb) + β
    xa = (pa - ma) @ rot[0]
    sel = hh == mid
    A = np.column_stack([pb[sel] - mb, np.ones(sel.sum())])
    coef, *_ = np.linalg.lstsq(A, xa[sel], rcond=None)
    R = np.array([[coef[0], coef[1], coef[2] - coef[:2] @ mb],
                  [-cd[0], -cd[1], cd @ mb]])
    if np.linalg.det(R[:, :2]) <= 0:
        raise ModelError("the right image would be mirrored in the rectified frame: the images "
                         "do not look at the same ground the same way round")
    xb = apply_affine(R, pb[:, 0], pb[:, 1])[0]
    d = xa - xb
    dh = d[hh == hi] - d[hh == lo]
    if np.median(np.abs(dh)) < 1e-3 * (hi - lo):
        raise ModelError("the pair has (almost) no stereo: parallax under 0.001 px per metre of height")
    if np.median(dh) < 0:             # disparity grows with height: turn both by 180°
        flip = np.diag([-1.0, -1.0])
        L, R = flip @ L, flip @ R
        d, ya, yb = -d, -ya, -yb
    err = float(np.abs(ya - yb).max())
    dlo, dhi = float(d.min()) - margin_px, float(d.max()) + margin_px
    # StereoSGBM: drops a disparity within a pixel of either end, and matches nothing in the
    # left image's first (min + num) columns
    d_min = int(np.floor(dlo)) - 1
    n_disp = int(np.ceil((dhi + 2 - d_min) / 16.0)) * 16
    # grid: the window's corners in the rectified frame, widened for SGBM's band
    x0, y0, w, hgt = (float(v) for v in window)
    cx, cy = apply_affine(L, np.array([x0, x0 + w, x0, x0 + w]), np.array([y0, y0, y0 + hgt, y0 + hgt]))
    left_pad = max(d_min + n_disp, 0) + EDGE_PAD_PX
    right_pad = max(-dlo, 0.0) + EDGE_PAD_PX
    gx0, gy0 = np.floor(cx.min() - left_pad), np.floor(cy.min())
    cols = int(np.ceil(cx.max() + right_pad - gx0))
    rows = int(np.ceil(cy.max() - gy0))
    shift = np.array([gx0, gy0])
    L[:, 2] -= shift
    R[:, 2] -= shift
    px_per_m = float(np.median(np.abs(dh))) / (hi - lo)
    return PairRectification(L, R, (rows, cols), (dlo, dhi), (d_min, n_disp), (lo, hi), err, px_per_m)


def warp(array: np.ndarray, origin, affine: np.ndarray, shape, *, interpolation=None) -> np.ndarray:
    """Resample an image array onto the rectified grid (float32, NaN outside the array).

    ``array`` holds image pixels whose top-left corner is at image point ``origin`` = (x, y)
    (a window read from the image); ``affine`` (2, 3) image → rectified; ``interpolation`` an
    OpenCV flag, default ``cv2.INTER_CUBIC``.
    """
    if interpolation is None:
        interpolation = cv2.INTER_CUBIC
    inv = invert_affine(affine)
    # rectified index (i, j) → coordinate (i + .5, j + .5) → image point → array index
    lin = inv[:, :2]
    off = lin @ np.array([0.5, 0.5]) + inv[:, 2] - 0.5 - np.asarray(origin, float)
    M = np.column_stack([lin, off]).astype(np.float64)
    return cv2.warpAffine(np.asarray(array, np.float32), M, (int(shape[1]), int(shape[0])),
                          flags=interpolation | cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=float("nan"))


def source_window(affine: np.ndarray, shape, pad: int = 3):
    """The image window (x0, y0, width, height), integer px, that the rectified grid of
    ``shape`` reads through ``affine`` (image → rectified), widened by ``pad``."""
    rows, cols = shape
    x, y = apply_affine(invert_affine(affine), np.array([0, cols, 0, cols]), np.array([0, 0, rows, rows]))
    x0, y0 = int(np.floor(x.min())) - pad, int(np.floor(y.min())) - pad
    return x0, y0, int(np.ceil(x.max())) + pad - x0, int(np.ceil(y.max())) + pad - y0


@dataclass(frozen=True)
class RayLattice:
    """Per lattice node of the rectified grid (every ``step`` px from index 0) and per height
    of ``heights`` (3,): the right image's rectified column ``xb`` and the ground's map
    position ``e``, ``n``, each (3, ny, nx); ``ok`` (ny, nx) where all three lifted."""

    step: int
    heights: np.ndarray
    xb: np.ndarray
    yb: np.ndarray
    e: np.ndarray
    n: np.ndarray
    ok: np.ndarray


def ray_lattice(model_a, model_b, rect: PairRectification, to_map, *, step: int = 16) -> RayLattice:
    """Lift the left rays of lattice nodes to three heights (the rectification's range and its
    middle) through the biased RPCs; ``to_map(lon°, lat°) → (E, N)`` metres."""
    a, b = as_biased(model_a), as_biased(model_b)
    rows, cols = rect.shape
    ix = np.arange(0, cols + step, step, dtype=float)
    iy = np.arange(0, rows + step, step, dtype=float)
    gx, gy = np.meshgrid(ix + 0.5, iy + 0.5)
    xa, ya = apply_affine(rect.inverse("left"), gx, gy)
    lo, hi = rect.heights
    hs = np.array([lo, 0.5 * (lo + hi), hi])
    out = {k: np.full((3,) + gx.shape, np.nan) for k in ("xb", "yb", "e", "n")}
    ok = np.ones(gx.shape, bool)
    d = a.bias_at(xa.ravel(), ya.ravel()).reshape(gx.shape + (2,))
    for k, h in enumerate(hs):
        lon, lat, good = a.rpc.localize_masked(xa - d[..., 0], ya - d[..., 1], np.full(gx.shape, h))
        ok &= good
        lon, lat = np.where(good, lon, a.rpc.lon_off), np.where(good, lat, a.rpc.lat_off)
        xb, yb = b.project(lon, lat, h)
        out["xb"][k], out["yb"][k] = apply_affine(rect.right, xb, yb)
        out["e"][k], out["n"][k] = to_map(lon, lat)
    return RayLattice(step, hs, out["xb"], out["yb"], out["e"], out["n"], ok)


def _quadratic(v: np.ndarray):
    """Coefficients ``c0, c1, c2`` of ``v(t) = c0 + c1 t + c2 t²`` through ``t = −1, 0, 1``."""
    return v[1], 0.5 * (v[2] - v[0]), 0.5 * (v[2] + v[0]) - v[1]


def _upsample(lat: np.ndarray, step: int, shape) -> np.ndarray:
    """Bilinear interpolation of lattice values (nodes at index 0, step, 2·step…) at every
    grid index (float32, rows × cols)."""
    rows, cols = shape
    mx = np.repeat((np.arange(cols, dtype=np.float32) / step)[None, :], rows, 0)
    my = np.repeat((np.arange(rows, dtype=np.float32) / step)[:, None], cols, 1)
    return cv2.remap(np.ascontiguousarray(lat, np.float32), mx, my, cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REPLICATE)


@dataclass(frozen=True)
class Triangulated:
    """On the rectified grid (rows, cols), float32, NaN where no disparity: ellipsoidal
    height ``h`` (m), map position ``e``, ``n`` (m), and ``m_per_px`` the height change per
    pixel of disparity (for the height's σ)."""

    h: np.ndarray
    e: np.ndarray
    n: np.ndarray
    m_per_px: np.ndarray


def triangulate(rect: PairRectification, lattice: RayLattice, disparity: np.ndarray) -> Triangulated:
    """Heights and map positions of the left pixels of a disparity map (rectified grid,
    ``x'_left − x'_right`` px, NaN where none), through the RPCs (see the module docstring).

    Per pixel, ``x'_right(t)`` is quadratic in ``t = (h − h_mid)/Δ`` (``Δ`` half the
    rectification's height range); Newton solves ``x'_right(t) = x' − d`` (three steps reach
    machine precision for the near-linear rays of a pushbroom image).
    """
    shape = rect.shape
    up = lambda v: _upsample(v, lattice.step, shape)  # noqa: E731
    c0, c1, c2 = (up(c) for c in _quadratic(lattice.xb))
    x = (np.arange(shape[1], dtype=np.float32) + 0.5)[None, :]
    target = x - disparity.astype(np.float32)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = (target - c0) / c1
        for _ in range(3):
            t = t - (c0 + c1 * t + c2 * t * t - target) / (c1 + 2 * c2 * t)
        half = 0.5 * float(lattice.heights[2] - lattice.heights[0])
        h = (lattice.heights[1] + half * t).astype(np.float32)
        m_per_px = (half / np.abs(c1 + 2 * c2 * t)).astype(np.float32)
    ok = np.isfinite(h) & (up(lattice.ok.astype(np.float32)) > 0.999)
    h[~ok] = np.nan
    en = []
    for v in (lattice.e, lattice.n):
        q0, q1, q2 = _quadratic(v)
        # large map coordinates: interpolate relative to the lattice's first node
        ref = float(q0.flat[0])
        # (float64 before the large offset is added: float32 holds 4,900 km to 0.5 m only)
        en.append(ref + (up(q0 - ref) + t * up(q1) + t * t * up(q2)).astype(np.float64))
    e, n = (np.where(ok, v, np.nan) for v in en)
    return Triangulated(h, e, n, np.where(ok, m_per_px, np.nan).astype(np.float32))


def grid_heights(e, n, h, transform, shape, extra=None, sigma_cells: float = 0.0):
    """Bin points (map ``e``, ``n`` m, height ``h``; any shape, NaN skipped) into the
    north-up grid ``transform`` (rasterio order a, b, c, d, e, f; b = d = 0), ``shape``:
    ``(mean height, samples, mean of extra)`` per cell (float32, float32, float32), NaN / 0
    where none (the third is None without ``extra``, an array like ``h``).

    ``sigma_cells`` 0: each point counts in the cell it falls in (plain means, integer counts).
    Above 0: each point counts in the 3 × 3 cells around the nearest one with the Gaussian
    weight ``exp(−r²/2σ²)`` of its distance ``r`` (cells) to their centres — points scattered
    about as densely as the cells (a posting at the images' pixel) leave no holes and every
    cell averages its neighbourhood's samples; a cell is kept where some point lies within
    one cell of its centre, its samples the weights' effective number ``(Σw)²/Σw²``."""
    a, _, c, _, ee, f = (float(v) for v in tuple(transform)[:6])
    ok = np.isfinite(h) & np.isfinite(e) & np.isfinite(n)
    u = (np.asarray(e)[ok] - c) / a - 0.5          # cell-centre coordinates
    v = (np.asarray(n)[ok] - f) / ee - 0.5
    hv = np.asarray(h)[ok]
    xv = None if extra is None else np.asarray(extra)[ok]
    size = shape[0] * shape[1]
    if sigma_cells <= 0:
        offsets, ci0, ri0 = [(0, 0)], np.floor(u + 0.5).astype(np.int64), np.floor(v + 0.5).astype(np.int64)
    else:
        offsets = [(dr, dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1)]
        ci0, ri0 = np.rint(u).astype(np.int64), np.rint(v).astype(np.int64)
    sw = np.zeros(size)
    sw2 = np.zeros(size)
    sh = np.zeros(size)
    sx = None if xv is None else np.zeros(size)
    near = np.zeros(size, bool)
    for dr, dc in offsets:
        ci, ri = ci0 + dc, ri0 + dr
        inside = (ci >= 0) & (ci < shape[1]) & (ri >= 0) & (ri < shape[0])
        k = ri[inside] * shape[1] + ci[inside]
        if sigma_cells <= 0:
            w = np.ones(k.size)
        else:
            r2 = (u[inside] - ci[inside]) ** 2 + (v[inside] - ri[inside]) ** 2
            w = np.exp(-0.5 * r2 / sigma_cells ** 2)
            near[k[r2 <= 1.0]] = True
        sw += np.bincount(k, weights=w, minlength=size)
        sw2 += np.bincount(k, weights=w * w, minlength=size)
        sh += np.bincount(k, weights=w * hv[inside], minlength=size)
        if sx is not None:
            sx += np.bincount(k, weights=w * xv[inside], minlength=size)
    keep = sw > 0 if sigma_cells <= 0 else near & (sw > 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = lambda s: np.where(keep, s / np.where(keep, sw, 1.0), np.nan).reshape(shape).astype(np.float32)  # noqa: E731
        cnt = np.where(keep, sw * sw / np.where(keep, sw2, 1.0), 0.0).reshape(shape).astype(np.float32)
    return mean(sh), cnt, None if sx is None else mean(sx)
