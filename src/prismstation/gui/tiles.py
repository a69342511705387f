"""Tile planning and background tile reads for :class:`~prismstation.gui.image_view.ImageView`.

A tile key is ``(level, col, row)``: ``level`` is the decimation factor (1 = full resolution),
and the tile covers the full-resolution rectangle ``RasterSource.tile_rect(level, col, row)``.
Reads run in a private ``QThreadPool``; results come back to the GUI thread by a queued signal.
A request that is no longer wanted when a worker picks it up is dropped without reading.
"""
from __future__ import annotations

import math
import threading

from PySide6.QtCore import QObject, QRunnable, QThreadPool, Signal

from prismstation.errors import RasterReadError
from prismstation.io.raster import TILE_SIZE, RasterSource


def tiles_for_rect(source: RasterSource, level: int, rect_xywh) -> list[tuple[int, int, int]]:
    """Keys of the tiles of ``level`` that intersect a full-resolution rectangle.

    Parameters
    ----------
    rect_xywh : (x, y, w, h)
        Rectangle in image pixels (x = column, y = row); clipped to the image.

    Returns
    -------
    list of (level, col, row), ordered from the rectangle's centre outwards.
    """
    x, y, w, h = rect_xywh
    span = TILE_SIZE * level
    ncols, nrows = source.tile_grid(level)
    c0 = max(0, int(math.floor(x / span)))
    r0 = max(0, int(math.floor(y / span)))
    c1 = min(ncols - 1, int(math.floor((x + w) / span)))
    r1 = min(nrows - 1, int(math.floor((y + h) / span)))
    if c1 < c0 or r1 < r0:
        return []
    cx, cy = (x + w / 2) / span - 0.5, (y + h / 2) / span - 0.5
    keys = [(level, c, r) for r in range(r0, r1 + 1) for c in range(c0, c1 + 1)]
    keys.sort(key=lambda k: (k[1] - cx) ** 2 + (k[2] - cy) ** 2)
    return keys


class _TileJob(QRunnable):
    def __init__(self, loader: "TileLoader", key):
        super().__init__()
        self.loader = loader
        self.key = key
        self.setAutoDelete(True)

    def run(self) -> None:  # worker thread
        loader, key = self.loader, self.key
        if not loader._still_wanted(key):
            return
        try:
            arr = loader.source.read_tile(*key)
        except RasterReadError as exc:
            loader._done(key)
            try:
                loader.tile_failed.emit(key, str(exc))
            except RuntimeError:  # the loader was deleted meanwhile
                pass
            return
        loader._done(key)
        try:
            loader.tile_loaded.emit(loader.source, key, arr)
        except RuntimeError:
            pass


class TileLoader(QObject):
    """Reads tiles of one :class:`RasterSource` in worker threads.

    Signals
    -------
    tile_loaded(source, key, array)
        A tile was read (emitted from a worker, delivered queued in the loader's thread).
    tile_failed(key, message)
    """

    tile_loaded = Signal(object, object, object)
    tile_failed = Signal(object, str)

    def __init__(self, source: RasterSource, threads: int = 2, parent=None):
        super().__init__(parent)
        self.source = source
        self.pool = QThreadPool(self)
        self.pool.setMaxThreadCount(threads)
        self._lock = threading.Lock()
        self._wanted: set = set()
        self._pending: set = set()

    def request(self, keys) -> None:
        """Make ``keys`` the wanted set; queue reads for the ones not yet pending.

        Keys queued earlier and not in ``keys`` are dropped when a worker reaches them.
        """
        keys = list(keys)
        with self._lock:
            self._wanted = set(keys)
            new = [k for k in keys if k not in self._pending]
            self._pending.update(new)
        for key in new:
            self.pool.start(_TileJob(self, key))

    def pending(self) -> int:
        """Number of tile reads queued or running."""
        with self._lock:
            return len(self._pending)

    def _still_wanted(self, key) -> bool:
        with self._lock:
            if key in self._wanted:
                return True
            self._pending.discard(key)
            return False

    def _done(self, key) -> None:
        with self._lock:
            self._pending.discard(key)

    def shutdown(self) -> None:
        """Drop queued reads and wait for running ones."""
        with self._lock:
            self._wanted = set()
        self.pool.clear()
        self.pool.waitForDone()
        with self._lock:
            self._pending.clear()
