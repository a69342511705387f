"""The window's memory: one Dask thread pool for the process, and the heap's free memory handed
back to the system after large computations (Linux, glibc)."""
from __future__ import annotations

import os
import sys
import time

from PySide6.QtCore import QObject, QTimer

from prismstation.gui.workers import collect_everything


def one_dask_pool() -> None:
    """One pool of worker threads for every Dask computation of the process (the DSM's tiles).
    Dask keeps a pool per calling thread; a tool job runs in a thread of its own, so each DSM
    left a pool behind, with its threads' memory (a DSM of the demo: +50 to +125 MB resident
    per run, never given back)."""
    import dask
    if dask.config.get("pool", None) is None:
        from concurrent.futures import ThreadPoolExecutor

        from dask.system import CPU_COUNT
        dask.config.set(pool=ThreadPoolExecutor(CPU_COUNT, thread_name_prefix="dask"))


M_ARENA_MAX = -8  # mallopt parameter (glibc malloc.h)


class MemoryKeeper(QObject):
    """Hands the heap's free memory back to the system once the resident memory has grown by
    :attr:`STEP_MB` since the last time (checked every :attr:`INTERVAL_MS`; Linux, glibc).

    glibc keeps what a large computation freed (a DSM, its validation: arrays of 10–100 MB in
    worker threads' heaps) for the next allocation instead of returning it, and the window
    collects cyclic garbage rarely (gui/workers.py): the window stayed ~100 MB above what it
    used after the demo's tools. A full collection and ``malloc_trim`` take ~50–150 ms, only
    after such a growth."""

    INTERVAL_MS = 2000
    STEP_MB = 32
    AGAIN_S = 3.0

    ARENAS = 2
    """glibc heaps ("arenas") threads share: its default, 8 per core, let the tool jobs' and
    tile readers' threads each keep freed memory in heaps of their own (the demo's tools left
    the window at 500 MB with it, 420–440 MB with two; the DSM's time is the same within the
    run-to-run scatter). ``MALLOC_ARENA_MAX`` in the environment wins."""

    def __init__(self, parent=None, busy=None):
        super().__init__(parent)
        self.busy = busy  # callable: True while a job runs
        self.trims = 0
        self._libc = None
        if sys.platform.startswith("linux"):
            import ctypes
            try:
                self._libc = ctypes.CDLL("libc.so.6")
                self._libc.malloc_trim  # noqa: B018 (glibc only)
                if "MALLOC_ARENA_MAX" not in os.environ:
                    self._libc.mallopt(M_ARENA_MAX, self.ARENAS)  # (before the window's threads)
            except (OSError, AttributeError):
                self._libc = None
        self._floor = resident_mb()
        self._again = None
        if self._libc is not None:
            self._timer = QTimer(self)
            self._timer.setInterval(self.INTERVAL_MS)
            self._timer.timeout.connect(self.check)
            self._timer.start()

    def check(self) -> None:
        """Collect and trim when the memory grew, and once more :attr:`AGAIN_S` later (what a
        job still held at the first time, it has let go of by then); not while a tool's job
        runs (it is still using it, and the DSM trims its own heaps)."""
        if self.busy is not None and self.busy():
            return
        rss, now = resident_mb(), time.monotonic()
        due = self._again is not None and now >= self._again
        if rss > self._floor + self.STEP_MB or due:
            collect_everything()  # (GUI thread: arrays a large job left in reference cycles)
            self._libc.malloc_trim(0)
            self.trims += 1
            self._again = None if due else now + self.AGAIN_S
            self._floor = resident_mb()
        else:
            self._floor = min(self._floor, rss)


def resident_mb() -> float:
    """This process's resident memory (MB; NaN where /proc is not there)."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except (OSError, ValueError, IndexError):
        return float("nan")
