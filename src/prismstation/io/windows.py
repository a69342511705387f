"""Window reads of a scene's images: one rasterio handle per view, opened for one thread.

Image pixels ``(x, y)`` = (column, row), origin at the top-left corner of the top-left pixel
(docs/model.md §1). A window is returned with the image pixel ``(col0, row0)`` of its own top-left
corner; :func:`shift` and :func:`scaling` build the affine maps between window, decimated and
image pixels.

Every read of an image's pixels by the engine goes through :class:`CheckedRaster`
(:func:`open_image`): a file that cannot be opened, or a window that cannot be read (a
truncated or corrupt file, a file gone), is a :class:`~prismstation.errors.RasterReadError`
naming the file, what it is (``view N``), the window in image pixels and GDAL's cause.
"""
from __future__ import annotations

import numpy as np
from rasterio.windows import Window

from prismstation.core.adjustment.affine import Affine2D
from prismstation.errors import InputError, RasterReadError
from prismstation.io.atomic import cause_text
from prismstation.io.inputs import open_raster_file


def describe_window(window) -> str:
    """``window x 0–512, y 1024–1536`` (image pixels, x = column, y = row) of a rasterio
    ``Window`` or ``(x, y, w, h)``."""
    if window is None:
        return "the whole image"
    if isinstance(window, Window):
        x, y, w, h = window.col_off, window.row_off, window.width, window.height
    else:
        x, y, w, h = window
    return f"window x {x:g}–{x + w:g}, y {y:g}–{y + h:g}"


def read_error(path, where: str, exc: BaseException) -> RasterReadError:
    """The :class:`RasterReadError` of a read of ``path`` at ``where`` that raised ``exc``."""
    return RasterReadError(f"{path}: cannot read {where} ({cause_text(exc, str(path))})")


class CheckedRaster:
    """A raster opened for reading (``with open_image(path, "view N") as ds:``) whose
    ``read`` raises :class:`RasterReadError` naming the file, ``what`` and the window; every
    other attribute is the rasterio dataset's. One thread's handle, like rasterio's."""

    def __init__(self, path, what: str = "raster"):
        self.name, self.what = str(path), what
        try:
            self._ds = open_raster_file(self.name, what)  # a local file only (io.inputs)
        except InputError as exc:
            raise RasterReadError(str(exc)) from None

    def read(self, indexes=None, *, window=None, **kw) -> np.ndarray:
        try:
            return self._ds.read(indexes, window=window, **kw)
        except Exception as exc:
            raise read_error(self.name, f"{self.what}, {describe_window(window)}", exc) from None

    def read_bands(self, c0: int, r0: int, w: int, h: int) -> np.ndarray:
        """Every band of the window ``[c0, c0 + w) × [r0, r0 + h)`` px (inside the image):
        ``(count, h, w)`` in the file's type."""
        return self.read(window=Window(c0, r0, w, h))

    def read_padded(self, c0: int, r0: int, w: int, h: int) -> np.ndarray:
        """Band 1 of the window ``[c0, c0 + w) × [r0, r0 + h)`` px as float32 ``(h, w)``, NaN
        where it falls outside the image."""
        out = np.full((h, w), np.nan, np.float32)
        a0, b0 = max(c0, 0), max(r0, 0)
        a1, b1 = min(c0 + w, self.width), min(r0 + h, self.height)
        if a1 > a0 and b1 > b0:
            out[b0 - r0:b1 - r0, a0 - c0:a1 - c0] = self.read(1, window=Window(a0, b0, a1 - a0, b1 - b0),
                                                              out_dtype="float32")
        return out

    @property
    def dataset(self):
        """The rasterio dataset itself, for GDAL calls that need one (a warp)."""
        return self._ds

    def __getattr__(self, name):
        if name == "_ds":  # not opened
            raise AttributeError(name)
        return getattr(self._ds, name)

    def close(self) -> None:
        self._ds.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def open_image(path, what: str = "raster") -> CheckedRaster:
    """``path`` opened for checked reads (:class:`CheckedRaster`)."""
    return CheckedRaster(path, what)


def raster_header(path, what: str = "image") -> tuple[int, int, str | None]:
    """``(width, height, CRS as WKT or None)`` of the raster ``path``, its pixels unread
    (opened through :func:`~prismstation.io.inputs.open_raster_file`: a local file only); a
    file that fails the checks or does not open as a raster is an :class:`InputError` naming it."""
    try:
        with open_raster_file(path, what) as ds:
            return ds.width, ds.height, (ds.crs.to_wkt() if ds.crs is not None else None)
    except RasterReadError as exc:
        raise InputError(str(exc).removeprefix(f"{path}: "), file=path) from None


#: full-resolution rows read at a time by :meth:`ImageWindows.read_reduced`
READ_STRIP_ROWS = 1024


class ImageWindows:
    """Float32 windows of band 1 of every view with an image (``with ImageWindows(scene) as w:``).

    The handles belong to the thread that opened them: open one per worker.
    """

    def __init__(self, scene):
        self._ds = {}
        try:
            for v, view in scene.views.items():
                if view.image:
                    self._ds[v] = open_image(view.image, f"view {v}")
        except RasterReadError:
            self.close()
            raise

    def read(self, view: str, c0: float, r0: float, w: float, h: float, min_px: int = 1):
        """Pixels ``[c0, c0 + w) × [r0, r0 + h)`` clipped to the image → ``(array, col0, row0)``;
        ``(None, col0, row0)`` when fewer than ``min_px`` columns or rows remain."""
        ds = self._ds[view]
        a0, b0 = max(int(np.floor(c0)), 0), max(int(np.floor(r0)), 0)
        a1, b1 = min(int(np.ceil(c0 + w)), ds.width), min(int(np.ceil(r0 + h)), ds.height)
        if a1 - a0 < min_px or b1 - b0 < min_px:
            return None, a0, b0
        return ds.read(1, window=Window(a0, b0, a1 - a0, b1 - b0)).astype(np.float32), a0, b0

    def read_reduced(self, view: str, c0: float, r0: float, w: float, h: float, factor: int):
        """:meth:`read` averaged over whole ``factor × factor`` blocks (the window cropped to
        them), read in strips of rows so that the full-resolution window is never held (a
        14,000 px image is 0.8 GB as float32) → ``(array, col0, row0)``; ``(None, …)`` when
        less than one block remains."""
        import cv2  # start-up: OpenCV loads with the first reduced read

        if factor <= 1:
            return self.read(view, c0, r0, w, h)
        ds = self._ds[view]
        a0, b0 = max(int(np.floor(c0)), 0), max(int(np.floor(r0)), 0)
        a1, b1 = min(int(np.ceil(c0 + w)), ds.width), min(int(np.ceil(r0 + h)), ds.height)
        cols, rows = (a1 - a0) // factor, (b1 - b0) // factor
        if cols < 1 or rows < 1:
            return None, a0, b0
        out = np.empty((rows, cols), np.float32)
        step = max(1, READ_STRIP_ROWS // factor)          # output rows per strip
        for k in range(0, rows, step):
            n = min(step, rows - k)
            block = ds.read(1, window=Window(a0, b0 + k * factor, cols * factor, n * factor)).astype(np.float32)
            out[k:k + n] = cv2.resize(block, (cols, n), interpolation=cv2.INTER_AREA)
        return out, a0, b0

    def around(self, view: str, cx: float, cy: float, half: int):
        """Window of ``2·half`` px around ``(int(cx), int(cy))``, clipped; ``None`` when fewer
        than 8 columns or rows remain."""
        return self.read(view, int(cx) - half, int(cy) - half, 2 * half, 2 * half, min_px=8)

    def close(self) -> None:
        for ds in self._ds.values():
            ds.close()
        self._ds = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def shift(c0: float, r0: float) -> Affine2D:
    """Window pixels → image pixels of a window whose top-left corner is image pixel ``(c0, r0)``."""
    return Affine2D([[1, 0, c0], [0, 1, r0]])


def scaling(f: float) -> Affine2D:
    """Pixels of an image decimated by ``f`` → pixels of the full image (``x·f``)."""
    return Affine2D([[f, 0, 0], [0, f, 0]])
