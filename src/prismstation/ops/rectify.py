"""Rectification of a single image through a fitted image→map transform into a GeoTIFF
(docs/model.md §4), by inverse mapping block by block.

Image coordinates ``(x, y)``: column, row in pixels, origin at the top-left corner of the
top-left pixel. Map coordinates ``(E, N)`` in metres of the points' CRS.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from prismstation.core.models.rectify import KINDS, TransformReport, compare_transforms, format_rmse_table
from prismstation.errors import InputError, ModelError
from prismstation.io.georef import Reprojection
from prismstation.io.geotiff import block_writer
from prismstation.io.windows import open_image
from prismstation.ops.progress import ProgressFn, checkpoint

__all__ = ["KINDS", "RectifyResult", "fit_transforms", "format_rmse_table", "rectify_raster"]


def fit_transforms(pairs) -> tuple[TransformReport, ...]:
    """Every image→map transform of :data:`KINDS` fitted to the GCPs of ``pairs``
    (:class:`~prismstation.io.rectify_io.PointPairs`) and checked on its ICPs, in that order."""
    return compare_transforms(pairs.xy, pairs.en, pairs.is_check)


@dataclass(frozen=True)
class RectifyResult:
    """What :func:`rectify_raster` wrote: path, CRS, size and grid (affine, GDAL order)."""

    path: str
    crs: str
    width: int
    height: int
    resolution: float
    geotransform: tuple


def _sample(src, x: np.ndarray, y: np.ndarray, nodata: float, resampling: str) -> np.ndarray:
    """Sample all bands of ``src`` (a :class:`~prismstation.io.windows.CheckedRaster`) at image
    points (x, y) (pixels, corner origin)."""
    import cv2  # start-up: OpenCV loads with the first rectified block

    count = src.count
    out = np.full((count,) + x.shape, nodata, dtype=np.float32)
    inside = np.isfinite(x) & np.isfinite(y) & (x >= 0) & (y >= 0) & (x <= src.width) & (y <= src.height)
    if not inside.any():
        return out
    c0 = int(max(0, math.floor(x[inside].min()) - 2))
    r0 = int(max(0, math.floor(y[inside].min()) - 2))
    c1 = int(min(src.width, math.ceil(x[inside].max()) + 2))
    r1 = int(min(src.height, math.ceil(y[inside].max()) + 2))
    # src is a CheckedRaster: a failed read names the file and the window
    data = src.read_bands(c0, r0, c1 - c0, r1 - r0).astype(np.float32)
    mx = np.where(inside, x - 0.5 - c0, -1e6).astype(np.float32)
    my = np.where(inside, y - 0.5 - r0, -1e6).astype(np.float32)
    interp = cv2.INTER_NEAREST if resampling == "nearest" else cv2.INTER_LINEAR
    for b in range(count):
        s = cv2.remap(data[b], mx, my, interp, borderMode=cv2.BORDER_REPLICATE)
        out[b] = np.where(inside, s, nodata)
    return out


def _inverse_map(exact, h: int, w: int, step: int = 16, tol_px: float = 0.02):
    """Image coordinates of every cell of an ``h`` × ``w`` output block.

    ``exact(rows, cols)`` maps block cell indices to image ``(x, y)``. It is evaluated on a
    lattice every ``step`` cells and interpolated bilinearly in between (exact for affine
    maps); the interpolation is checked at the lattice cell centres and the whole block is
    computed exactly when it is off by more than ``tol_px`` pixels or meets a NaN.
    """
    rn = np.unique(np.r_[np.arange(0, h, step), h - 1])
    cn = np.unique(np.r_[np.arange(0, w, step), w - 1])
    if len(rn) < 3 or len(cn) < 3:
        R, C = np.mgrid[0:h, 0:w]
        return exact(R, C)
    RN, CN = np.meshgrid(rn, cn, indexing="ij")
    xn, yn = exact(RN, CN)

    def interp(grid, rows, cols):
        i = np.clip(np.searchsorted(rn, rows, side="right") - 1, 0, len(rn) - 2)
        j = np.clip(np.searchsorted(cn, cols, side="right") - 1, 0, len(cn) - 2)
        ty = ((rows - rn[i]) / (rn[i + 1] - rn[i]))[:, None]
        tx = ((cols - cn[j]) / (cn[j + 1] - cn[j]))[None, :]
        I, J = i[:, None], j[None, :]
        return ((1 - ty) * ((1 - tx) * grid[I, J] + tx * grid[I, J + 1])
                + ty * ((1 - tx) * grid[I + 1, J] + tx * grid[I + 1, J + 1]))

    if np.all(np.isfinite(xn)) and np.all(np.isfinite(yn)):
        rm = (rn[:-1] + rn[1:]) / 2.0
        cm = (cn[:-1] + cn[1:]) / 2.0
        RM, CM = np.meshgrid(rm, cm, indexing="ij")
        xm, ym = exact(RM, CM)
        err = np.hypot(interp(xn, rm, cm) - xm, interp(yn, rm, cm) - ym)
        if np.all(err < tol_px):
            rows, cols = np.arange(h, dtype=float), np.arange(w, dtype=float)
            return interp(xn, rows, cols), interp(yn, rows, cols)
    R, C = np.mgrid[0:h, 0:w]
    return exact(R, C)


def rectify_raster(image, transform, out_path, *, points_crs, out_crs=None,
                   resolution: float | None = None, block: int = 512,
                   progress: ProgressFn | None = None,
                   resampling: str = "bilinear") -> RectifyResult:
    """Warp ``image`` through a fitted image→map ``transform`` into a GeoTIFF (inverse mapping).

    Parameters
    ----------
    image : path of any raster rasterio opens (its own georeferencing is ignored).
    transform : a :class:`prismstation.core.models.rectify.FittedTransform` (pixels → ``points_crs``).
    points_crs : CRS of the ground points the transform was fitted to.
    out_crs : output CRS (default ``points_crs``); pyproj converts between the two.
    resolution : output cell size in ``out_crs`` units (default: the image's own, mapped).
    block : output block size in pixels; ``progress(fraction, message)`` is called after each
        block (:mod:`prismstation.ops.progress`): when it returns ``False`` the work stops with
        :class:`~prismstation.errors.Cancelled` and no output file is left.
    resampling : ``"bilinear"`` or ``"nearest"``.
    """
    crs = Reprojection(points_crs, out_crs)
    src = open_image(image, "the image")
    out_path = str(out_path)
    with src:
        W, H = src.width, src.height
        t = np.linspace(0, 1, 65)
        border = np.concatenate([np.column_stack([t * W, 0 * t]), np.column_stack([t * W, H + 0 * t]),
                                 np.column_stack([0 * t, t * H]), np.column_stack([W + 0 * t, t * H])])
        e, n = crs.forward(*transform(border).T)
        if not (np.all(np.isfinite(e)) and np.all(np.isfinite(n))):
            raise ModelError("the transform maps part of the image outside the output CRS")
        if resolution is None:
            c = np.array([[W / 2, H / 2], [W / 2 + 1, H / 2], [W / 2, H / 2 + 1]])
            ce, cn = crs.forward(*transform(c).T)
            dx = math.hypot(ce[1] - ce[0], cn[1] - cn[0])
            dy = math.hypot(ce[2] - ce[0], cn[2] - cn[0])
            resolution = math.sqrt(dx * dy)
        if not (resolution > 0 and math.isfinite(resolution)):
            raise InputError(f"resolution must be a positive number, got {resolution}")
        r = float(resolution)
        left, top = math.floor(e.min() / r) * r, math.ceil(n.max() / r) * r
        width = int(math.ceil((e.max() - left) / r))
        height = int(math.ceil((top - n.min()) / r))
        if width * height > 2_000_000_000 or width < 1 or height < 1:
            raise InputError(f"output of {width} × {height} cells at resolution {r}: "
                             f"check --resolution and the CRS units")
        nodata = src.nodata if src.nodata is not None else 0
        dtype = src.dtypes[0]
        bs = int(block)
        windows = [(r0, c0) for r0 in range(0, height, bs) for c0 in range(0, width, bs)]
        with block_writer(out_path, width=width, height=height, count=src.count, dtype=dtype,
                          crs_wkt=crs.target_wkt, transform=(r, 0.0, left, 0.0, -r, top), nodata=nodata) as write:
            for k, (r0, c0) in enumerate(windows):
                h, w = min(bs, height - r0), min(bs, width - c0)
                def exact(rr, cc):
                    """Image (x, y) of output cells at block rows rr, columns cc (same shape)."""
                    oe, on = left + (c0 + cc + 0.5) * r, top - (r0 + rr + 0.5) * r
                    if not crs.same:
                        oe, on = crs.backward(oe, on)
                    xy = transform.inverse(np.column_stack([np.ravel(oe), np.ravel(on)]))
                    return xy[:, 0].reshape(np.shape(rr)), xy[:, 1].reshape(np.shape(rr))

                x, y = _inverse_map(exact, h, w)
                vals = _sample(src, x, y, nodata, resampling)
                if np.issubdtype(np.dtype(dtype), np.integer):
                    info = np.iinfo(dtype)
                    vals = np.clip(np.rint(vals), info.min, info.max)
                write(vals.astype(dtype), c0, r0)
                checkpoint(progress, (k + 1) / len(windows), f"block {k + 1} of {len(windows)}")
    return RectifyResult(out_path, crs.target_text, width, height, r, (left, r, 0.0, top, 0.0, -r))
