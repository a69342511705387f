"""Raster source for display: windowed, decimated, tiled and cached reads through rasterio.

A :class:`RasterSource` never needs a whole image at full resolution. It reads a window at the
overview level that matches the requested decimation (rasterio's ``out_shape`` lets GDAL pick the
overview), keeps an LRU cache of display tiles bounded in megabytes, and gives display statistics
from a coarse overview read. It is safe to call from several threads: each thread gets its own
rasterio handle (rasterio datasets must not be shared between threads).

Coordinates follow docs/model.md §1: image ``x`` = column, ``y`` = row, in full-resolution pixels, origin
at the top-left corner of the top-left pixel. Arrays are row-major ``(rows, cols)``.
"""
from __future__ import annotations

import math
import os
import threading
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import rasterio
from rasterio._err import CPLE_BaseError
from rasterio.enums import Resampling
from rasterio.errors import RasterioError
from rasterio.windows import Window

from prismstation.errors import InputError, RasterReadError
from prismstation.io.inputs import GDAL_SAFE_OPTIONS, open_raster_file
from prismstation.io.windows import describe_window, read_error

TILE_SIZE = 512
"""Side of a display tile, in pixels of its own overview level."""

COARSE_MAX = 1024
"""Longest side, in pixels, of the coarse whole-image overview read for display and statistics."""

GDAL_CACHE_MB = 32
"""GDAL's block cache (process-wide) while an entry point's :func:`gdal_env` is active, unless
GDAL_CACHEMAX is set in the environment. GDAL's default (5 % of RAM, 1.2 GB here) duplicates the
tile cache, fills with blocks a windowed reader reads once (a 14,000 px DSM: peak RSS 2.19 GB with
it), and alone takes the workstation past its memory budget."""


def gdal_env(**options) -> rasterio.Env:
    """The GDAL configuration of an entry point, scoped (``with gdal_env(): ...``): the block
    cache bounded to :data:`GDAL_CACHE_MB` unless ``GDAL_CACHEMAX`` is set in the environment,
    and ``options``. Entered by the command line's ``main``, the window's ``run`` and each DSM
    tile (a Dask worker may be another process); reading a raster changes no setting. GDAL is
    kept off the network and from running code a file holds
    (:data:`prismstation.io.inputs.GDAL_SAFE_OPTIONS`, each unless set in the environment)."""
    if "GDAL_CACHEMAX" not in os.environ:
        options.setdefault("GDAL_CACHEMAX", GDAL_CACHE_MB * 1024 * 1024)
    for key, value in GDAL_SAFE_OPTIONS.items():
        if key not in os.environ:
            options.setdefault(key, value)
    return rasterio.Env(**options)


@dataclass(frozen=True)
class RasterStatistics:
    """Display statistics of band 1, estimated from a coarse overview read.

    Attributes
    ----------
    minimum, maximum : float
        Extreme valid values (nodata excluded) in the coarse read.
    percentiles : dict[float, float]
        ``{p: value}`` for each requested percentile ``p`` in [0, 100].
    histogram : np.ndarray, shape (n,)
        Counts of valid values per bin.
    bin_edges : np.ndarray, shape (n + 1,)
        Bin edges in data units.
    decimation : int
        Full-resolution pixels per pixel of the read the statistics come from.
    """

    minimum: float
    maximum: float
    percentiles: dict
    histogram: np.ndarray
    bin_edges: np.ndarray
    decimation: int


def _integer_statistics(vals: np.ndarray, percentiles, bins: int):
    """Percentiles (numpy's linear interpolation), extremes and histogram of 8/16-bit unsigned
    values from one ``bincount``: several times faster than sorting for display statistics."""
    counts = np.bincount(vals.astype(np.intp, copy=False))
    cdf = np.cumsum(counts)
    n = int(cdf[-1])

    def kth(k):  # value of the k-th smallest (0-based)
        return np.searchsorted(cdf, np.asarray(k) + 1, side="left")

    ranks = np.asarray(list(percentiles), float) / 100.0 * (n - 1)
    k0 = np.floor(ranks).astype(np.int64)
    k1 = np.minimum(k0 + 1, n - 1)
    v0, v1 = kth(k0).astype(float), kth(k1).astype(float)
    pct = v0 + (ranks - k0) * (v1 - v0)
    nz = np.flatnonzero(counts)
    lo, hi = float(nz[0]), float(nz[-1])
    edges = np.linspace(lo, hi if hi > lo else lo + 1, bins + 1)
    idx = np.minimum(np.searchsorted(edges, np.arange(int(lo), int(hi) + 1), side="right") - 1,
                     bins - 1)
    hist = np.bincount(idx, weights=counts[int(lo):int(hi) + 1], minlength=bins).astype(np.int64)
    return pct, lo, hi, hist, edges


def _writable(path: Path) -> bool:
    """Writable by its mode bits too: root passes ``os.access``, but a file or folder marked
    read-only (shared test data, a mounted archive) must stay untouched."""
    try:
        return os.access(path, os.W_OK) and bool(path.stat().st_mode & 0o222)
    except OSError:
        return False


class _TileCache:
    """Thread-safe LRU cache of arrays, bounded by their total size in bytes."""

    def __init__(self, max_bytes: int):
        self.max_bytes = int(max_bytes)
        self.nbytes = 0
        self._items: OrderedDict = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key):
        with self._lock:
            arr = self._items.get(key)
            if arr is not None:
                self._items.move_to_end(key)
            return arr

    def put(self, key, arr: np.ndarray) -> None:
        with self._lock:
            old = self._items.pop(key, None)
            if old is not None:
                self.nbytes -= old.nbytes
            self._items[key] = arr
            self.nbytes += arr.nbytes
            while self.nbytes > self.max_bytes and len(self._items) > 1:
                _, dropped = self._items.popitem(last=False)
                self.nbytes -= dropped.nbytes

    def clear(self) -> None:
        with self._lock:
            self._items.clear()
            self.nbytes = 0

    def __contains__(self, key) -> bool:
        with self._lock:
            return key in self._items

    def __len__(self) -> int:
        return len(self._items)


class RasterSource:
    """A raster file opened for display (band 1).

    Parameters
    ----------
    path : str or Path
        Anything rasterio opens (GeoTIFF with or without overviews, uint8, uint16, ...).
    cache_mb : float
        Bound of the tile cache in megabytes.
    band : int
        1-based band to display.

    Raises
    ------
    RasterReadError
        The file is missing or rasterio cannot open it; the message names the file.
    """

    def __init__(self, path, cache_mb: float = 64, band: int = 1):
        self._name = str(path)  # what rasterio opens: a file, or a /vsi... or URL path
        self.path = Path(path)
        self.band = int(band)
        local = "://" not in self._name and not self._name.startswith("/vsi")
        if local and not self.path.exists():
            raise RasterReadError(f"{self.path}: no such file")
        self._local = threading.local()
        self._handles: list = []
        self._handles_lock = threading.Lock()
        self._generation = 0
        self.cache = _TileCache(int(cache_mb * 1024 * 1024))
        self._coarse = None
        self._coarse_lock = threading.Lock()
        ds = self._dataset()
        if not 1 <= self.band <= ds.count:
            raise RasterReadError(f"{self.path}: has {ds.count} band(s), band {self.band} asked")
        self.width = int(ds.width)
        self.height = int(ds.height)
        self.dtype = np.dtype(ds.dtypes[self.band - 1])
        self.nodata = ds.nodata
        self.crs = ds.crs
        self.transform = ds.transform
        self.block_shape = ds.block_shapes[self.band - 1]
        self._read_overviews(ds)

    # ------------------------------------------------------------------ handles
    def _dataset(self):
        """This thread's rasterio handle (opened on first use, reopened after overviews change)."""
        ds = getattr(self._local, "ds", None)
        if ds is None or getattr(self._local, "generation", -1) != self._generation:
            if ds is not None:
                ds.close()
            try:
                ds = open_raster_file(self._name, "image")
            except InputError as exc:  # not a local file: as a file that cannot be opened
                raise RasterReadError(str(exc)) from None
            self._local.ds = ds
            self._local.generation = self._generation
            with self._handles_lock:
                self._handles.append(ds)
        return ds

    def _read_overviews(self, ds) -> None:
        self.overview_factors = tuple(int(f) for f in ds.overviews(self.band))

    def release_thread(self) -> None:
        """Close the calling thread's handle (a worker about to end calls this)."""
        ds = getattr(self._local, "ds", None)
        if ds is not None:
            ds.close()
            self._local.ds = None
            with self._handles_lock:
                self._handles = [d for d in self._handles if d is not ds]

    def close(self) -> None:
        """Close every thread's handle and drop the cache."""
        with self._handles_lock:
            for ds in self._handles:
                ds.close()
            self._handles.clear()
        self._generation += 1
        self.cache.clear()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # ------------------------------------------------------------------ geometry
    @property
    def shape(self) -> tuple[int, int]:
        """``(rows, cols)`` at full resolution."""
        return self.height, self.width

    @property
    def levels(self) -> tuple[int, ...]:
        """Decimation factors available for display: 1 (full resolution) and the overviews."""
        return (1,) + self.overview_factors

    def level_for(self, decimation: float) -> int:
        """Display level for a decimation (image pixels per screen pixel).

        The coarsest power-of-two factor not coarser than ``decimation``, so that a tile has at
        least one of its pixels per screen pixel. Without overviews GDAL decimates on the fly.
        """
        if decimation < 2:
            return 1
        f = 2 ** int(math.floor(math.log2(decimation)))
        longest = max(self.width, self.height)
        while f > 1 and longest / f < 1:
            f //= 2
        return int(f)

    def has_overviews(self) -> bool:
        return bool(self.overview_factors)

    def needs_overviews(self, min_size: int = 4096) -> bool:
        """True when the image is large (longest side > ``min_size``) and has no overviews."""
        return max(self.width, self.height) > min_size and not self.overview_factors

    # ------------------------------------------------------------------ reads
    def read(self, window_xywh: Sequence[float], out_shape: Sequence[int] | None = None,
             resampling: Resampling = Resampling.nearest) -> np.ndarray:
        """Read a window of band 1, decimated to ``out_shape``.

        Parameters
        ----------
        window_xywh : (x, y, w, h)
            Window in full-resolution pixels (x = column, y = row, origin top-left corner);
            it is clipped to the image.
        out_shape : (rows, cols), optional
            Shape of the result; GDAL reads from the overview matching the decimation.
            Defaults to the window's own shape (full resolution).

        Returns
        -------
        np.ndarray, shape out_shape, the file's dtype
        """
        x, y, w, h = (float(v) for v in window_xywh)
        x0, y0 = max(0.0, x), max(0.0, y)
        x1, y1 = min(float(self.width), x + w), min(float(self.height), y + h)
        if x1 <= x0 or y1 <= y0:
            raise RasterReadError(f"{self.path}: window {tuple(window_xywh)} is outside the image")
        if out_shape is None:
            out_shape = (max(1, int(round(y1 - y0))), max(1, int(round(x1 - x0))))
        out_shape = (int(out_shape[0]), int(out_shape[1]))
        try:
            return self._dataset().read(self.band, window=Window(x0, y0, x1 - x0, y1 - y0),
                                        out_shape=out_shape, resampling=resampling)
        except RasterReadError:
            raise
        except (RasterioError, CPLE_BaseError, OSError, ValueError) as exc:
            raise read_error(self.path, describe_window((x0, y0, x1 - x0, y1 - y0)), exc) from None

    def tile_rect(self, level: int, col: int, row: int) -> tuple[int, int, int, int]:
        """Full-resolution rectangle ``(x, y, w, h)`` covered by a tile (clipped to the image)."""
        span = TILE_SIZE * level
        x, y = col * span, row * span
        return x, y, min(span, self.width - x), min(span, self.height - y)

    def tile_grid(self, level: int) -> tuple[int, int]:
        """Number of tile ``(cols, rows)`` at a level."""
        span = TILE_SIZE * level
        return math.ceil(self.width / span), math.ceil(self.height / span)

    def cached_tile(self, level: int, col: int, row: int) -> np.ndarray | None:
        """The tile if it is in the cache, else None (never reads)."""
        return self.cache.get((level, col, row))

    def read_tile(self, level: int, col: int, row: int) -> np.ndarray:
        """Tile ``(col, row)`` of a level, through the LRU cache.

        Returns
        -------
        np.ndarray, shape (ceil(h / level), ceil(w / level))
            The tile's pixels for the rectangle :meth:`tile_rect` gives.
        """
        key = (level, col, row)
        arr = self.cache.get(key)
        if arr is None:
            x, y, w, h = self.tile_rect(level, col, row)
            arr = self.read((x, y, w, h), (math.ceil(h / level), math.ceil(w / level)))
            self.cache.put(key, arr)
        return arr

    def read_pixels(self, x0: int, y0: int, w: int, h: int, fill=0) -> np.ndarray:
        """Full-resolution pixels ``[y0:y0+h, x0:x0+w]``; parts outside the image are ``fill``.

        Served from cached full-resolution tiles when they cover the window, else by one small
        direct read (which does not fill the cache).
        """
        out = np.full((h, w), fill, dtype=self.dtype)
        cx0, cy0 = max(0, x0), max(0, y0)
        cx1, cy1 = min(self.width, x0 + w), min(self.height, y0 + h)
        if cx1 <= cx0 or cy1 <= cy0:
            return out
        c0, c1 = cx0 // TILE_SIZE, (cx1 - 1) // TILE_SIZE
        r0, r1 = cy0 // TILE_SIZE, (cy1 - 1) // TILE_SIZE
        tiles = {(c, r): self.cached_tile(1, c, r) for c in range(c0, c1 + 1)
                 for r in range(r0, r1 + 1)}
        if all(t is not None for t in tiles.values()):
            for (c, r), t in tiles.items():
                tx, ty = c * TILE_SIZE, r * TILE_SIZE
                ax0, ay0 = max(cx0, tx), max(cy0, ty)
                ax1, ay1 = min(cx1, tx + t.shape[1]), min(cy1, ty + t.shape[0])
                out[ay0 - y0:ay1 - y0, ax0 - x0:ax1 - x0] = t[ay0 - ty:ay1 - ty, ax0 - tx:ax1 - tx]
        else:
            out[cy0 - y0:cy1 - y0, cx0 - x0:cx1 - x0] = self.read((cx0, cy0, cx1 - cx0, cy1 - cy0))
        return out

    def coarse_level(self, max_size: int = COARSE_MAX) -> int:
        """Power-of-two decimation giving a whole-image read with longest side ≤ ``max_size``."""
        f = 1
        while max(self.width, self.height) / f > max_size:
            f *= 2
        return f

    def coarse(self) -> tuple[np.ndarray, int]:
        """Whole image at :meth:`coarse_level` (cached): ``(array, decimation)``.

        The array has shape ``(ceil(height / f), ceil(width / f))``; pixel ``(i, j)`` covers full
        resolution pixels ``[i*f, (i+1)*f)`` in both directions (the last ones partly outside).
        """
        with self._coarse_lock:
            if self._coarse is None:
                f = self.coarse_level()
                arr = self.read((0, 0, self.width, self.height),
                                (math.ceil(self.height / f), math.ceil(self.width / f)))
                self._coarse = (arr, f)
            return self._coarse

    def statistics(self, percentiles: Sequence[float] = (0.5, 2, 98, 99.5),
                   bins: int = 256) -> RasterStatistics:
        """Display statistics from the coarse overview read (never a full-resolution read).

        Parameters
        ----------
        percentiles : sequence of float in [0, 100]
        bins : int
            Histogram bins between the minimum and the maximum.
        """
        arr, f = self.coarse()
        vals = arr.ravel()
        if self.nodata is not None:
            vals = vals[vals != self.nodata]
        if vals.size == 0:
            raise RasterReadError(f"{self.path}: no valid pixel for display statistics")
        if vals.dtype.kind in "ub" and vals.dtype.itemsize <= 2:
            pct, lo, hi, hist, edges = _integer_statistics(vals, percentiles, bins)
        else:
            pct = np.percentile(vals, list(percentiles)) if len(percentiles) else []
            lo, hi = float(vals.min()), float(vals.max())
            hist, edges = np.histogram(vals, bins=bins, range=(lo, hi if hi > lo else lo + 1))
        return RasterStatistics(lo, hi, {float(p): float(v) for p, v in zip(percentiles, pct)},
                                hist, edges, f)

    # ------------------------------------------------------------------ overviews
    def build_overviews(self, progress: Callable[[float], bool] | None = None,
                        factors: Sequence[int] | None = None, external: bool = True,
                        resampling: Resampling = Resampling.average) -> bool:
        """Build overviews (external ``.ovr`` beside the file, or internal), level by level.

        Parameters
        ----------
        progress : callable(fraction) -> bool, optional
            Called with the fraction done in [0, 1] before each level and at the end; returning
            False cancels (an external ``.ovr`` begun by this call is then removed).
        factors : sequence of int, optional
            Decimation factors; default powers of two down to ~256 px.
        external : bool
            True writes ``<file>.ovr`` (the image itself is untouched), False writes into the file.

        Returns
        -------
        bool
            True when complete, False when cancelled.

        Raises
        ------
        RasterReadError
            The folder (external) or the file (internal) is read-only, or GDAL failed.
        """
        if factors is None:
            factors, f = [], 2
            while max(self.width, self.height) / f >= 256:
                factors.append(f)
                f *= 2
            factors = factors or [2]
        ovr = Path(str(self.path) + ".ovr")
        had_ovr = ovr.exists()
        target = (self.path.parent if external and not had_ovr else
                  ovr if external else self.path)
        if not _writable(target):
            raise RasterReadError(f"{self.path}: cannot build overviews, {target} is read-only")
        env = rasterio.Env(TIFF_USE_OVR=True) if external else rasterio.Env()
        n = len(factors)
        try:
            for i, fac in enumerate(factors):
                if progress is not None and progress(i / n) is False:
                    if external and not had_ovr and ovr.exists():
                        os.remove(ovr)
                    return False
                with env, rasterio.open(self.path, "r+") as ds:
                    ds.build_overviews([int(fac)], resampling)
        except (RasterioError, OSError) as exc:
            raise RasterReadError(f"{self.path}: cannot build overviews ({exc})") from None
        finally:
            self._generation += 1  # every thread reopens its handle and sees the new levels
            self.cache.clear()
            with self._coarse_lock:
                self._coarse = None
            self._read_overviews(self._dataset())
        if progress is not None:
            progress(1.0)
        return True
