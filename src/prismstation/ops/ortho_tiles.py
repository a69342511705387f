"""An orthoimage's tiles: what one tile needs (:class:`OrthoTile`, picklable, so that it runs in a
thread, a process or on a ``dask.distributed`` worker that can read the files) and its work
(:func:`run_ortho_tile`): the DEM read onto the tile's cells, the positions of the cells in the
image through the fitted model (:mod:`prismstation.core.surfaces.ortho`), only the image window they need
read, and the image resampled there. The tiles run through the DSM's machinery
(:func:`prismstation.ops.dsm_tiles.run_tiles`: Dask, batches, progress and cancel).

:class:`Heights` is where a tile's ellipsoidal heights come from: a DEM file (its own heights,
orthometric ones made ellipsoidal through the project's geoid) or a constant.
"""
from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

from prismstation.core.lazy_cv2 import cv2  # imported at first use: start-up saving
import numpy as np

from prismstation.core.surfaces.ortho import KERNEL_REACH, fit_lattice, positions, resample
from prismstation.errors import RasterReadError
from prismstation.io.dem import read_dem_cells, read_dem_window
from prismstation.io.raster import gdal_env
from prismstation.io.windows import ImageWindows


@dataclass(frozen=True, eq=False)
class Heights:
    """Ellipsoidal heights on the scene's grids: the DEM file ``path`` (heights of ``kind``
    ``"orthometric"`` or ``"ellipsoidal"``) or the ``constant`` (m, of ``kind``), in ``crs``.
    Orthometric heights get the geoid undulation ``undulation``: a number (m), or a coarse
    north-up grid ``(array, transform)`` over the area sampled bilinearly (a geoid varies over
    kilometres: at a grid of 500 m, a 15′ geoid's bilinear kinks leave ~1 cm)."""

    crs: str
    kind: str
    path: str | None = None
    constant: float | None = None
    undulation: object = 0.0

    def on_grid(self, transform, shape) -> np.ndarray:
        """``(rows, cols)`` float32 ellipsoidal heights at the cell centres of a north-up grid,
        NaN in voids (bilinear in the DEM's cells: :func:`~prismstation.io.dem.read_dem_cells`)."""
        a, _, c, _, e, f = tuple(transform)[:6]
        rows, cols = shape
        x = c + a * (np.arange(cols) + 0.5)
        y = f + e * (np.arange(rows) + 0.5)
        return self._sample(x[None, :], y[:, None], (min(x[0], x[-1]), min(y[0], y[-1]),
                                                     max(x[0], x[-1]), max(y[0], y[-1])), abs(a))

    def at(self, en) -> np.ndarray:
        """``(n,)`` ellipsoidal heights at map points ``en`` ``(n, 2)`` (bilinear; NaN in voids
        and outside)."""
        en = np.asarray(en, float).reshape(-1, 2)
        ok = np.isfinite(en).all(axis=1)
        out = np.full(len(en), np.nan)
        if ok.any():
            x, y = en[ok, 0][None, :], en[ok, 1][None, :]
            out[ok] = self._sample(x, y, (x.min(), y.min(), x.max(), y.max()), 0.0)[0]
        return out

    def range_over(self, bounds, cells: int = 256) -> tuple[float, float]:
        """Lowest and highest ellipsoidal height over ``bounds`` ``(x0, y0, x1, y1)``: the DEM's
        extremes over a grid of at most ``cells`` per side (each cell the min or max of the
        file's cells in it); NaN, NaN where the DEM has none there."""
        x0, y0, x1, y1 = bounds
        cell = max((x1 - x0) / cells, (y1 - y0) / cells, 1.0)
        shape = (max(1, int(np.ceil((y1 - y0) / cell))), max(1, int(np.ceil((x1 - x0) / cell))))
        t = (cell, 0.0, x0, 0.0, -cell, y1)
        x = (x0 + cell * (np.arange(shape[1]) + 0.5))[None, :]
        y = (y1 - cell * (np.arange(shape[0]) + 0.5))[:, None]
        ext = []
        for how in ("min", "max"):
            h = (np.full(shape, self.constant, np.float32) if self.path is None
                 else read_dem_window(self.path, self.crs, t, shape, resampling=how))
            if self.kind == "orthometric":
                h = h + (_bilinear(self.undulation[0], self.undulation[1], x, y, shape, edge=True)
                         if isinstance(self.undulation, tuple) else np.float32(self.undulation))
            ext.append(h)
        if not np.isfinite(ext[0]).any():
            return np.nan, np.nan
        return float(np.nanmin(ext[0])), float(np.nanmax(ext[1]))

    def _sample(self, x, y, bounds, cell) -> np.ndarray:
        """Heights at the points ``(x, y)`` (broadcast to one 2-D shape) within ``bounds``."""
        shape = np.broadcast_shapes(np.shape(x), np.shape(y))
        if self.path is None:
            h = np.full(shape, self.constant, np.float32)
        else:
            grid, t = read_dem_cells(self.path, self.crs, bounds, min_cell=cell)
            h = _bilinear(grid, t, x, y, shape)
        if self.kind == "orthometric":
            if isinstance(self.undulation, tuple):
                h += _bilinear(self.undulation[0], self.undulation[1], x, y, shape, edge=True)
            else:
                h += np.float32(self.undulation)
        return h

    def describe(self) -> str:
        """The heights in words (the ortho's metadata, the report)."""
        what = (f"{self.path}" if self.path is not None else f"constant {self.constant:g} m")
        return f"{what} ({self.kind}" + (", through the project's geoid)" if self.kind == "orthometric" else ")")


def _bilinear(grid, transform, x, y, shape, edge: bool = False) -> np.ndarray:
    """``grid`` (north-up, ``transform``) sampled bilinearly at map points ``(x, y)`` broadcast
    to ``shape`` (float32; NaN beyond the grid and next to its NaN cells, or the edge value
    with ``edge``). ``cv2.remap`` takes float maps at exact weights."""
    a, _, c, _, e, f = tuple(transform)[:6]
    mx = np.broadcast_to(((np.asarray(x, float) - c) / a - 0.5).astype(np.float32), shape)
    my = np.broadcast_to(((np.asarray(y, float) - f) / e - 0.5).astype(np.float32), shape)
    return cv2.remap(np.asarray(grid, np.float32), np.ascontiguousarray(mx), np.ascontiguousarray(my),
                     cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE if edge else cv2.BORDER_CONSTANT,
                     borderValue=float("nan"))


@dataclass(frozen=True, eq=False)
class OrthoTile:
    """One tile: the output cells ``window`` = (row0, col0, rows, cols) of the ortho grid
    ``transform`` (north-up, rasterio order), view ``view`` of the fitted sensor ``model``
    (:mod:`prismstation.core.models.sensor`), its image file ``image`` of ``image_shape`` (rows, cols),
    read reduced by ``factor`` (the ortho's posting over the image's pixel, whole), the tile's
    ``heights`` (:class:`Heights`) and the ``resampling`` kernel."""

    model: object
    view: str
    image: str
    image_shape: tuple
    window: tuple
    transform: tuple
    heights: Heights
    resampling: str = "bilinear"
    factor: int = 1


@dataclass(frozen=True)
class TileOut:
    """A tile's result: ``values`` float32 ``(rows, cols)`` (NaN: no data), the largest
    interpolation error of its positions (px) and whether its image window was read."""

    values: np.ndarray
    max_error_px: float
    read: bool


def tile_grid(spec: OrthoTile) -> tuple:
    """The tile's own transform."""
    a, _, c, _, e, f = tuple(spec.transform)[:6]
    r0, c0 = spec.window[:2]
    return (a, 0.0, c + a * c0, 0.0, e, f + e * r0)


def run_ortho_tile(spec: OrthoTile) -> TileOut:
    """The tile's image values (:class:`TileOut`)."""
    cv2.setNumThreads(1)
    t = tile_grid(spec)
    # a worker may be another process: its own bounded GDAL cache
    with gdal_env():
        h = spec.heights.on_grid(t, tuple(spec.window[2:]))
        try:
            return sample_view(lambda en, hh: spec.model.ground_to_image(spec.view, en, hh), spec.view,
                               spec.image, spec.image_shape, t, h, spec.resampling, spec.factor)
        except RasterReadError as exc:  # which tile, beside the file and the window
            r, c, rows, cols = spec.window
            raise RasterReadError(f"{exc}, for the ortho tile of cells rows {r}–{r + rows}, "
                                  f"columns {c}–{c + cols}") from None


def _edge(transform, shape, every: int = 8) -> np.ndarray:
    """Map ``(E, N)`` of the cell centres along a grid's edge, every ``every`` cells and at its
    corners."""
    a, _, c, _, e, f = tuple(transform)[:6]
    rows, cols = shape
    i = np.unique(np.r_[np.arange(0, cols, every), cols - 1]) + 0.5
    j = np.unique(np.r_[np.arange(0, rows, every), rows - 1]) + 0.5
    cx = np.r_[i, i, np.full(len(j), 0.5), np.full(len(j), cols - 0.5)]
    cy = np.r_[np.full(len(i), 0.5), np.full(len(i), rows - 0.5), j, j]
    return np.column_stack([c + a * cx, f + e * cy])


def sample_view(ground_to_image, view: str, image: str, image_shape, transform, heights,
                resampling: str = "bilinear", factor: int = 1) -> TileOut:
    """The image ``image`` (view ``view``, ``image_shape`` (rows, cols)) resampled at
    ``ground_to_image(en, h)`` of the cells of the grid ``transform`` at their ``heights``
    (ellipsoidal, NaN: no data), reading only the window they need, reduced by ``factor``."""
    shape = heights.shape
    empty = TileOut(np.full(shape, np.nan, np.float32), 0.0, False)
    finite = np.isfinite(heights)
    if not finite.any():
        return empty
    h_lo, h_hi = float(heights[finite].min()), float(heights[finite].max())
    lat = fit_lattice(ground_to_image, transform, shape, h_lo, h_hi)
    # the window: the grid's edge at the lowest, middle and highest heights (a smooth map's
    # extremes over a rectangle and a height range lie there)
    edge = _edge(transform, shape)
    xy = np.concatenate([np.asarray(ground_to_image(edge, np.full(len(edge), hh)), float)
                         for hh in (h_lo, 0.5 * (h_lo + h_hi), h_hi)])
    xy = xy[np.isfinite(xy).all(axis=1)]
    if not len(xy):
        return empty
    reach = KERNEL_REACH[resampling] * factor + 1
    lo, hi = np.floor(xy.min(axis=0)) - reach, np.ceil(xy.max(axis=0)) + reach
    rows, cols = image_shape
    if hi[0] <= 0 or hi[1] <= 0 or lo[0] >= cols or lo[1] >= rows:
        return TileOut(empty.values, lat.max_error_px, False)
    scene = SimpleNamespace(views={view: SimpleNamespace(image=image)})
    with ImageWindows(scene) as images:
        arr, c0, r0 = images.read_reduced(view, lo[0], lo[1], hi[0] - lo[0], hi[1] - lo[1], factor)
    if arr is None:
        return TileOut(empty.values, lat.max_error_px, False)
    mx, my = positions(lat, heights, (c0, r0), factor)
    return TileOut(resample(arr, mx, my, resampling), lat.max_error_px, True)
