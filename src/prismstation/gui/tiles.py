"""Tile planning and background tile reads for :class:`~prismstation.gui.image_view.ImageView`.

A tile key is ``(level, col, row)``: ``level`` is the decimation factor (1 = full resolution),
and the tile covers the full-resolution rectangle ``RasterSource.tile_rect(level, col, row)``.
Reads run in worker threads fed by one queue; results come back to the GUI thread by a queued
signal. A request that is no longer wanted is dropped before a worker picks it up.
"""
from __future__ import annotations

import math
import threading
import weakref

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


class _Relay(QObject):
    """Carries results from the workers to the GUI thread. There is one for the process and it
    is never deleted, so a worker never emits on a dead object whatever happens to the views
    (a view deleted by Qt is disconnected, and deliveries queued for it are dropped)."""

    tile_loaded = Signal(object, object, object)  # source, key, array
    tile_failed = Signal(object, object, str)  # source, key, message


_RELAY: _Relay | None = None


def tile_relay() -> _Relay:
    """The process-wide relay of tile results (create it from the GUI thread first)."""
    global _RELAY
    if _RELAY is None:
        _RELAY = _Relay()
    return _RELAY


class _Queue:
    """The state shared with the worker threads (never a Qt object that Qt may delete)."""

    def __init__(self, source: RasterSource, relay: _Relay):
        self.source, self.relay = source, relay
        self.cond = threading.Condition()
        self.keys: list = []  # keys to read, most wanted first
        self.running: set = set()
        self.stopped = False

    def stop(self, *args) -> None:
        with self.cond:
            self.stopped = True
            self.keys = []
            self.cond.notify_all()

    def work(self) -> None:  # worker thread
        try:
            while True:
                with self.cond:
                    while not self.keys and not self.stopped:
                        self.cond.wait()
                    if self.stopped:
                        return
                    key = self.keys.pop(0)
                    self.running.add(key)
                try:
                    arr = (self.source.coarse()[0] if key == COARSE_KEY
                           else self.source.read_tile(*key))
                    error = None
                except RasterReadError as exc:
                    arr, error = None, str(exc)
                with self.cond:
                    self.running.discard(key)
                    if self.stopped:
                        return
                if error is None:
                    self.relay.tile_loaded.emit(self.source, key, arr)
                else:
                    self.relay.tile_failed.emit(self.source, key, error)
        finally:
            self.source.release_thread()


class TileLoader:
    """Reads tiles of one :class:`RasterSource` in worker threads.

    The workers take keys from one queue that each :meth:`request` replaces: reads the view no
    longer wants are dropped before they start (a read already running completes and only fills
    the cache). Each worker thread has its own rasterio handle (``RasterSource`` sees to it).
    The workers end on :meth:`shutdown`, when ``owner`` (a QObject) is destroyed, or when the
    loader is garbage-collected.

    Signals (attributes; the process-wide :func:`tile_relay`'s, so filter on ``source``)
    ------------------------------------------------------------------------------------
    tile_loaded(source, key, array)
        A tile was read (emitted from a worker, delivered queued to the GUI thread).
    tile_failed(source, key, message)
    """

    def __init__(self, source: RasterSource, threads: int = 2, owner: QObject | None = None):
        self.source = source
        relay = tile_relay()
        self.tile_loaded = relay.tile_loaded
        self.tile_failed = relay.tile_failed
        self._q = _Queue(source, relay)
        self._threads = [threading.Thread(target=self._q.work, daemon=True,
                                          name=f"tiles-{source.path.name}-{i}")
                         for i in range(max(1, threads))]
        for t in self._threads:
            t.start()
        weakref.finalize(self, self._q.stop)
        if owner is not None:
            owner.destroyed.connect(self._q.stop)

    def request(self, keys) -> None:
        """Make ``keys`` (most wanted first) the queue; queued keys not among them are dropped."""
        q = self._q
        with q.cond:
            if not q.stopped:
                q.keys = [k for k in keys if k not in q.running]
                q.cond.notify_all()

    def pending(self) -> int:
        """Number of tile reads queued or running."""
        with self._q.cond:
            return len(self._q.keys) + len(self._q.running)

    def shutdown(self, wait: bool = False) -> None:
        """Drop queued reads and end the workers after their running read (emitting nothing).

        With ``wait`` the call blocks until they have ended; without, it returns at once (a
        running read of a large file must not freeze the GUI).
        """
        self._q.stop()
        if wait:
            for t in self._threads:
                t.join(timeout=30)
