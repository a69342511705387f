"""Tile planning and background tile reads for :class:`~prismstation.gui.image_view.ImageView`.

A tile key is ``(level, col, row)``: ``level`` is the decimation factor (1 = full resolution),
and the tile covers the full-resolution rectangle ``RasterSource.tile_rect(level, col, row)``.
Reads run in worker threads (:mod:`.workers`) fed by one queue; results come back to the GUI
thread through :func:`workers.post`. A request no longer wanted is dropped before a worker picks
it up.
"""
from __future__ import annotations

import math
import threading

from prismstation.errors import RasterReadError
from prismstation.gui import workers
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


class _Queue:
    """The state shared with the worker threads (never a Qt object)."""

    def __init__(self, source: RasterSource, on_loaded, on_failed):
        self.source, self.on_loaded, self.on_failed = source, on_loaded, on_failed
        self.cond = threading.Condition(threading.Lock())
        self.keys: list = []  # keys to read, most wanted first
        self.running: set = set()
        self.failed: set = set()  # keys whose read failed: drawn as missing, never asked again
        self.reported = False     # the first failure was reported (one message, not one a tile)
        self.stopped = False

    def stop(self) -> None:
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
                    first = error is not None and not self.reported
                    if error is not None:
                        self.failed.add(key)
                        self.reported = True
                if error is None:
                    workers.post(self.on_loaded, self.source, key, arr)
                elif first:
                    workers.post(self.on_failed, self.source, key, error)
        finally:
            self.source.release_thread()  # this thread's handle, closed by this thread


class TileLoader:
    """Reads tiles of one :class:`RasterSource` in worker threads.

    The workers take keys from one queue that each :meth:`request` replaces: reads the view no
    longer wants are dropped before they start (a read already running completes and only fills
    the cache). Each worker thread has its own rasterio handle (``RasterSource`` sees to it) and
    closes it as it ends. Results go to ``on_loaded(source, key, array)`` or
    ``on_failed(source, key, message)`` on the GUI thread (:func:`workers.post`: a bound method
    of a deleted view is not called). A tile whose read fails (a truncated or corrupt file, a
    file gone: :class:`RasterReadError` naming the file and the window) is drawn as missing
    and never asked for again; only the first failure is reported, so a broken file gives one
    message, not one a tile. The owner calls :meth:`shutdown` (``wait=True``) before it closes
    the source.
    """

    def __init__(self, source: RasterSource, threads: int = 2, on_loaded=None, on_failed=None):
        self.source = source
        self._q = _Queue(source, on_loaded or _ignore, on_failed or _ignore)
        self.jobs = workers.Jobs(f"tiles-{source.path.name}")
        self._threads = [self.jobs.start(self._q.work) for _ in range(max(1, threads))]

    def request(self, keys) -> None:
        """Make ``keys`` (most wanted first) the queue; queued keys not among them are dropped."""
        q = self._q
        with q.cond:
            if not q.stopped:
                q.keys = [k for k in keys if k not in q.running and k not in q.failed]
                q.cond.notify_all()

    def failed(self) -> set:
        """Keys whose read failed (drawn as missing)."""
        with self._q.cond:
            return set(self._q.failed)

    def pending(self) -> int:
        """Number of tile reads queued or running."""
        with self._q.cond:
            return len(self._q.keys) + len(self._q.running)

    def stop(self, *_) -> None:
        """Drop queued reads and let the workers end after their running read (no wait)."""
        self._q.stop()

    def shutdown(self, wait: bool = True) -> bool:
        """Drop queued reads and end the workers after their running read (nothing delivered
        after this call). With ``wait`` (the default) block until they have ended, which the
        owner must do before it closes the source. True when no worker runs."""
        self._q.stop()
        self.jobs.closed = True
        return self.jobs.wait() if wait else not self.jobs.busy()


def _ignore(*_) -> None:
    pass
