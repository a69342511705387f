"""Tile planning and background tile reads for :class:`~prismstation.gui.image_view.ImageView`.

A tile key is ``(level, col, row)``: ``level`` is the decimation factor (1 = full resolution),
and the tile covers the full-resolution rectangle ``RasterSource.tile_rect(level, col, row)``.
Reads run in worker threads fed by one queue; results come back to the GUI thread by a queued
signal. A request that is no longer wanted is dropped before a worker picks it up.
"""
from __future__ import annotations

import math
import threading

from PySide6.QtCore import QObject, Signal

from prismstation.errors import RasterReadError
from prismstation.io.raster import TILE_SIZE, RasterSource


COARSE_KEY = "coarse"
"""Key of the request for the source's coarse whole-image read (``RasterSource.coarse``)."""


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


class TileLoader(QObject):
    """Reads tiles of one :class:`RasterSource` in worker threads.

    The workers take keys from one queue that each :meth:`request` replaces: reads the view no
    longer wants are dropped before they start (a read already running completes and only fills
    the cache). Each worker thread has its own rasterio handle (``RasterSource`` sees to it).

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
        self._cond = threading.Condition()
        self._queue: list = []  # keys to read, most wanted first
        self._running: set = set()
        self._stop = False
        self._threads = [threading.Thread(target=self._work, daemon=True,
                                          name=f"tiles-{source.path.name}-{i}")
                         for i in range(max(1, threads))]
        for t in self._threads:
            t.start()

    def request(self, keys) -> None:
        """Make ``keys`` (most wanted first) the queue; queued keys not among them are dropped."""
        with self._cond:
            self._queue = [k for k in keys if k not in self._running]
            self._cond.notify_all()

    def pending(self) -> int:
        """Number of tile reads queued or running."""
        with self._cond:
            return len(self._queue) + len(self._running)

    def _work(self) -> None:  # worker thread
        try:
            self._loop()
        finally:
            self.source.release_thread()

    def _loop(self) -> None:
        while True:
            with self._cond:
                while not self._queue and not self._stop:
                    self._cond.wait()
                if self._stop:
                    return
                key = self._queue.pop(0)
                self._running.add(key)
            try:
                arr = self.source.coarse()[0] if key == COARSE_KEY else self.source.read_tile(*key)
                error = None
            except RasterReadError as exc:
                arr, error = None, str(exc)
            with self._cond:
                self._running.discard(key)
                if self._stop:
                    return
            try:  # the loader may have been deleted meanwhile
                if error is None:
                    self.tile_loaded.emit(self.source, key, arr)
                else:
                    self.tile_failed.emit(key, error)
            except RuntimeError:
                return

    def shutdown(self, wait: bool = False) -> None:
        """Drop queued reads and end the workers after their running read (emitting nothing).

        With ``wait`` the call blocks until they have ended; without, it returns at once (a
        running read of a large file must not freeze the GUI).
        """
        with self._cond:
            self._stop = True
            self._queue = []
            self._cond.notify_all()
        if wait:
            for t in self._threads:
                t.join(timeout=30)
