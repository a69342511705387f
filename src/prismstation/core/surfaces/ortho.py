"""An orthoimage tile, arrays only: where each cell of a north-up grid falls in a view's image
through a fitted sensor model and the DEM's heights, and the image resampled there.

A tile is ``(transform, shape)`` (rasterio order ``(a, 0, c, 0, e, f)``, north-up, metres of the
scene's CRS; cell ``(row, col)`` centred at ``(c + a·(col + 0.5), f + e·(row + 0.5))``) with an
ellipsoidal height per cell (NaN: a void of the DEM). The model is called only through
``ground_to_image(en, h)`` (the sensor-model seam, :mod:`prismstation.core.models.sensor`).

**Positions** (:func:`fit_lattice`, :func:`positions`). The model is evaluated exactly on a
lattice every ``step`` cells at ``L`` heights spanning the tile's range (Chebyshev nodes), and
each image coordinate is taken as a polynomial of degree ``L − 1`` in height whose coefficients
are interpolated bilinearly between the lattice nodes (the model is smooth: a pushbroom or
rational function over tens of metres). The interpolation is *checked*, not assumed: the exact
model at the lattice cells' centres, at heights between the nodes, must agree with it to
:data:`TOLERANCE_PX`; where it does not, the lattice is made finer or the degree higher, and the
largest error found is returned with the lattice (it goes into the ortho's metadata).
GDAL's warper does the like with a linear interpolation per row checked to 0.125 px by default.

**Resampling** (:func:`resample`). Bilinear through ``cv2.remap`` on float32 (its weights are
exact in floating point for float maps: a ramp comes back to 1e-7 px), or cubic convolution with
``a = −0.5`` (Keys 1981; GDAL's ``cubic``: it reproduces straight lines and parabolas, so it
moves no edge), its sixteen taps read as nine bilinear ones. A cell whose kernel reaches outside the image window is
NaN, as is a cell of NaN height.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from prismstation.core.lazy_cv2 import cv2  # imported at first use: start-up saving
import numpy as np

#: the largest error (image pixels) the interpolated positions may have against the model
TOLERANCE_PX = 0.005
#: lattice spacing (cells) tried first, and the finest before giving up on spacing
STEP = 16
MIN_STEP = 2
#: heights (polynomial degree + 1) tried first and at most
LEVELS = 3
MAX_LEVELS = 6
#: a tile's height range is at least this (m), so that a flat tile still has a slope in h
MIN_HALF_RANGE_M = 1.0

RESAMPLINGS = ("bilinear", "cubic")
#: cells beyond a position's own pixel the kernel reads (bilinear 1, cubic 2)
KERNEL_REACH = {"bilinear": 1, "cubic": 2}


@dataclass(frozen=True)
class Lattice:
    """Image positions on a tile as polynomials in height on a lattice of nodes.

    ``coef`` ``(L, 2, nr, nc)`` float64: coefficient ``k`` of ``t**k`` of x and y (image pixels)
    at node ``(i, j)``, which lies at the tile's continuous cell coordinate
    ``((j − 0.5)·step, (i − 0.5)·step)`` (one node beyond each edge); ``t = (h − h_mid) / h_half``.
    ``max_error_px`` the largest difference to the model found at the check points."""

    coef: np.ndarray
    step: int
    shape: tuple
    h_mid: float
    h_half: float
    max_error_px: float

    @property
    def levels(self) -> int:
        return self.coef.shape[0]


def _nodes(transform, shape, step):
    """Map ``(E, N)`` ``(nr, nc, 2)`` of the lattice nodes of a tile."""
    a, _, c, _, e, f = tuple(transform)[:6]
    rows, cols = shape
    nr, nc = -(-rows // step) + 2, -(-cols // step) + 2
    X = (np.arange(nc) - 0.5) * step
    Y = (np.arange(nr) - 0.5) * step
    E, N = np.meshgrid(c + a * X, f + e * Y)
    return np.stack([E, N], axis=-1)


def _chebyshev(levels: int) -> np.ndarray:
    k = np.arange(levels)
    return np.cos(np.pi * (2 * k + 1) / (2 * levels))[::-1].copy()


def _horner(coef, t):
    v = np.zeros(coef.shape[1:] if np.ndim(t) == 0 else np.broadcast_shapes(coef.shape[1:], np.shape(t)))
    for k in range(coef.shape[0] - 1, -1, -1):
        v = v * t + coef[k]
    return v


def fit_lattice(ground_to_image: Callable, transform, shape, h_lo: float, h_hi: float, *,
                tolerance_px: float = TOLERANCE_PX, step: int = STEP, levels: int = LEVELS) -> Lattice:
    """The :class:`Lattice` of a tile of ``shape`` ``(rows, cols)`` on ``transform`` for heights
    in ``[h_lo, h_hi]`` (ellipsoidal m), within ``tolerance_px`` of ``ground_to_image(en, h)``
    (``en`` ``(..., 2)``, ``h`` broadcastable → ``(..., 2)`` px) where that can be reached with
    ``step ≥`` :data:`MIN_STEP` and at most :data:`MAX_LEVELS` heights (else the finest lattice,
    its ``max_error_px`` saying how far it is off)."""
    h_mid = 0.5 * (h_lo + h_hi)
    h_half = max(0.5 * (h_hi - h_lo), MIN_HALF_RANGE_M)
    while True:
        lat = _lattice(ground_to_image, transform, shape, h_mid, h_half, step, levels)
        err_h, err_plan = _check(ground_to_image, transform, lat)
        lat = Lattice(lat.coef, lat.step, lat.shape, lat.h_mid, lat.h_half, max(err_h, err_plan))
        if not lat.max_error_px > tolerance_px:     # NaN (the model failed) ends the search too
            return lat
        if err_h > tolerance_px and levels < MAX_LEVELS:
            levels += 1
        elif err_plan > tolerance_px and step > MIN_STEP:
            step = max(step // 2, MIN_STEP)
        else:
            return lat


def _lattice(g2i, transform, shape, h_mid, h_half, step, levels) -> Lattice:
    en = _nodes(transform, shape, step)
    t = _chebyshev(levels)
    xy = np.stack([np.asarray(g2i(en, np.full(en.shape[:2], h_mid + h_half * tk)), float) for tk in t])
    # values at the nodes → coefficients of the power basis in t (a small Vandermonde system)
    V = np.vander(t, levels, increasing=True)
    coef = np.linalg.solve(V, xy.reshape(levels, -1)).reshape(xy.shape)       # (L, nr, nc, 2)
    return Lattice(np.moveaxis(coef, -1, 1).copy(), step, tuple(shape), h_mid, h_half, np.nan)


#: check points per tile, at most (a subset of the lattice cells)
CHECK_CELLS = 64


def _check(g2i, transform, lat: Lattice) -> tuple[float, float]:
    """Largest interpolation error (px) in height (at nodes, between the Chebyshev heights and
    at the range's ends) and in plan (at cell centres, at those heights)."""
    nr, nc = lat.coef.shape[2:]
    en = _nodes(transform, lat.shape, lat.step)
    levels = lat.levels
    t_nodes = _chebyshev(levels)
    t_check = np.concatenate([[-1.0, 1.0], 0.5 * (t_nodes[1:] + t_nodes[:-1])])
    rng = np.random.default_rng(nr * 1000 + nc)
    # the node's cells: the four nodes around each cell centre
    i = rng.integers(0, nr - 1, CHECK_CELLS)
    j = rng.integers(0, nc - 1, CHECK_CELLS)
    t = rng.choice(t_check, CHECK_CELLS)
    h = lat.h_mid + lat.h_half * t
    # in height only: at the nodes themselves
    exact = np.asarray(g2i(en[i, j], h), float)
    interp = np.stack([_horner(lat.coef[:, 0, i, j], t), _horner(lat.coef[:, 1, i, j], t)], axis=-1)
    err_h = float(np.max(np.hypot(*(exact - interp).T)))
    # in plan too: at the cells' centres
    centre = 0.25 * (en[i, j] + en[i + 1, j] + en[i, j + 1] + en[i + 1, j + 1])
    exact = np.asarray(g2i(centre, h), float)
    c4 = 0.25 * (lat.coef[:, :, i, j] + lat.coef[:, :, i + 1, j] + lat.coef[:, :, i, j + 1]
                 + lat.coef[:, :, i + 1, j + 1])
    interp = np.stack([_horner(c4[:, 0], t), _horner(c4[:, 1], t)], axis=-1)
    err_plan = float(np.max(np.hypot(*(exact - interp).T)))
    return err_h, err_plan


def positions(lat: Lattice, heights: np.ndarray, origin=(0.0, 0.0), factor: float = 1.0):
    """Array indices ``(mx, my)`` (float32, each ``heights.shape``) of every cell's image position
    in an image window whose top-left corner is image pixel ``origin`` (x, y) read reduced by
    ``factor`` (a window array's element ``[r, c]`` centred at image
    ``origin + factor·(c + 0.5, r + 0.5)``): what ``cv2.remap`` and :func:`resample` take. NaN
    where the height is NaN. The coefficients are brought to the cells by ``cv2.resize``
    (bilinear, exact weights in float32), relative to ``origin`` so float32 keeps 1e-4 px."""
    rows, cols = lat.shape
    s = lat.step
    nr, nc = lat.coef.shape[2:]
    t = ((np.asarray(heights, np.float32) - np.float32(lat.h_mid)) / np.float32(lat.h_half))
    out = []
    for axis in (0, 1):
        acc = None
        for k in range(lat.levels - 1, -1, -1):
            c = lat.coef[k, axis]
            if k == 0:   # the constant term: to window array indices
                c = (c - origin[axis]) / factor - 0.5
            else:
                c = c / factor
            up = cv2.resize(c.astype(np.float32), (nc * s, nr * s), interpolation=cv2.INTER_LINEAR)
            up = up[s:s + rows, s:s + cols]
            if acc is None:
                acc = np.array(up)
            else:
                acc *= t
                acc += up
        out.append(acc)
    return out[0], out[1]


def resample(window: np.ndarray, mx: np.ndarray, my: np.ndarray, kernel: str = "bilinear") -> np.ndarray:
    """``window`` (float32 2-D) at array indices ``(mx, my)`` (element ``[r, c]`` at ``(c, r)``),
    ``kernel`` :data:`RESAMPLINGS`; float32, NaN where the kernel leaves the window or the
    position is NaN."""
    img = np.ascontiguousarray(window, np.float32)
    nan = float("nan")
    if kernel == "bilinear":
        return cv2.remap(img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=nan)
    if kernel != "cubic":
        raise ValueError(f"resampling {kernel!r}: expected one of {', '.join(RESAMPLINGS)}")
    # each axis's four taps as three: the outer two, and the middle two (both weights ≥ 0, their
    # sum ≥ 1) as one linear tap between them — nine bilinear reads instead of sixteen
    taps = []
    for m in (mx, my):
        i = np.floor(m)
        w = _keys(m - i)
        mid = w[1] + w[2]
        taps.append(((i - np.float32(1.0), w[0]), (i + w[2] / mid, mid), (i + np.float32(2.0), w[3])))
    out = np.zeros(mx.shape, np.float32)
    for ys, wy in taps[1]:
        row = np.zeros(mx.shape, np.float32)
        for xs, wx in taps[0]:
            tap = cv2.remap(img, xs, ys, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=nan)
            tap *= wx
            row += tap
        row *= wy
        out += row
    return out


def _keys(f: np.ndarray) -> tuple:
    """The four weights of cubic convolution (a = −0.5) at fractional offsets ``f`` in [0, 1)
    for the taps at −1, 0, 1, 2."""
    f2 = f * f
    f3 = f2 * f
    return (np.float32(-0.5) * f3 + f2 - np.float32(0.5) * f,
            np.float32(1.5) * f3 - np.float32(2.5) * f2 + np.float32(1.0),
            np.float32(-1.5) * f3 + np.float32(2.0) * f2 + np.float32(0.5) * f,
            np.float32(0.5) * f3 - np.float32(0.5) * f2)
