"""The window's one way to run work off the GUI thread, and its one way back.

Threads
    :class:`Jobs` is a group of Python worker threads owned by one object (the solver, a view,
    an image loader, a tool job). The owner calls :meth:`Jobs.close` before it releases what the
    jobs read (a project, a raster's file handles): close cancels the group and joins its
    threads. :func:`live` lists every worker thread of the process still running, which is how
    tests check that no job outlives its owner.

Back to the GUI thread
    :func:`post` (from any thread) queues ``callback(*args)`` for the GUI thread. A worker never
    touches a Qt object — no signal emission, no posted event — so no worker can hold the
    interpreter lock while it waits for a Qt lock the GUI thread holds while it waits for the
    interpreter lock. It appends to a Python queue and writes one byte to a socket that a
    ``QSocketNotifier`` on the GUI thread watches. A bound-method callback is held weakly: when
    its object is gone (or its Qt object deleted) ``orphan()`` runs instead (to close a file
    the result holds, say).

Garbage
    Python's cyclic collector runs in whichever thread happens to allocate; a cycle holding a
    Qt widget collected in a worker deletes the widget from that thread, which crashes Qt.
    :func:`collect_on_gui_thread` turns automatic collection off and runs it from a GUI-thread
    timer (and :func:`collect_if_due` at safe points), with the interpreter's own thresholds.
"""
from __future__ import annotations

import collections
import gc
import itertools
import socket
import sys
import threading
import weakref

import shiboken6
from PySide6.QtCore import QCoreApplication, QObject, QSocketNotifier, QTimer

_LIVE: "weakref.WeakSet[threading.Thread]" = weakref.WeakSet()
_COUNT = itertools.count(1)


def live() -> list[threading.Thread]:
    """The worker threads started by any :class:`Jobs` that are still running."""
    return [t for t in list(_LIVE) if t.is_alive()]


class Jobs:
    """Worker threads owned by one object; :meth:`close` before releasing what they read.

    ``cancelled`` is a ``threading.Event`` the jobs may poll (set by :meth:`cancel` and
    :meth:`close`). Starting after :meth:`close` raises RuntimeError.
    """

    def __init__(self, name: str):
        relay()  # made on the GUI thread, before any worker posts to it
        self.name = name
        self.cancelled = threading.Event()
        self.closed = False
        self._threads: list[threading.Thread] = []

    def start(self, fn, *args) -> threading.Thread:
        """Run ``fn(*args)`` in a new worker thread of this group (call on the GUI thread)."""
        if self.closed:
            raise RuntimeError(f"{self.name}: the jobs are closed")
        self._threads = [t for t in self._threads if t.is_alive()]
        t = threading.Thread(target=fn, args=args, daemon=True, name=f"{self.name}-{next(_COUNT)}")
        self._threads.append(t)
        _LIVE.add(t)
        t.start()
        return t

    def busy(self) -> bool:
        return any(t.is_alive() for t in self._threads)

    def cancel(self) -> None:
        self.cancelled.set()

    def wait(self, timeout: float | None = None) -> bool:
        """Join the threads (``timeout`` seconds in all, None: no limit); True when none runs."""
        import time
        end = None if timeout is None else time.monotonic() + timeout
        for t in list(self._threads):
            if t is threading.current_thread():
                continue
            t.join(None if end is None else max(0.0, end - time.monotonic()))
        return not any(t.is_alive() and t is not threading.current_thread() for t in self._threads)

    def close(self, timeout: float | None = None) -> bool:
        """Cancel, refuse new jobs and join the running ones (see :meth:`wait`)."""
        self.closed = True
        self.cancel()
        return self.wait(timeout)


# ---------------------------------------------------------------------- back to the GUI thread
class _Relay(QObject):
    """Process-wide, made on the GUI thread and never deleted."""

    def __init__(self):
        super().__init__()
        self._items: collections.deque = collections.deque()
        self._rsock, self._wsock = socket.socketpair()
        self._rsock.setblocking(False)
        self._wsock.setblocking(False)
        self._notifier = QSocketNotifier(self._rsock.fileno(), QSocketNotifier.Type.Read, self)
        self._notifier.activated.connect(self.deliver)

    def post(self, item) -> None:  # any thread
        self._items.append(item)
        try:
            self._wsock.send(b"\0")
        except (BlockingIOError, OSError):
            pass  # the socket is full of wake-ups already: the GUI thread will come

    def deliver(self, *_) -> None:  # GUI thread
        try:
            while self._rsock.recv(4096):
                pass
        except (BlockingIOError, OSError):
            pass
        while self._items:
            ref, args, orphan = self._items.popleft()
            fn = ref()
            owner = getattr(fn, "__self__", None)
            try:
                if fn is not None and (not isinstance(owner, QObject) or shiboken6.isValid(owner)):
                    fn(*args)
                elif orphan is not None:
                    orphan()
            except Exception:  # one receiver's bug must not stop the others' deliveries
                sys.excepthook(*sys.exc_info())


_RELAY: _Relay | None = None


def relay() -> _Relay:
    """The process-wide relay (made on first call, which must be on the GUI thread)."""
    global _RELAY
    if _RELAY is None:
        _RELAY = _Relay()
    return _RELAY


def post(callback, *args, orphan=None) -> None:
    """Call ``callback(*args)`` on the GUI thread (from any thread); see the module doc."""
    if hasattr(callback, "__self__") and hasattr(callback, "__func__"):
        ref = weakref.WeakMethod(callback)
    else:
        ref = (lambda fn=callback: fn)
    _RELAY.post((ref, args, orphan))


def deliver_now() -> None:
    """Run the queued calls at once (GUI thread; wait loops of scripts and tests)."""
    if _RELAY is not None:
        _RELAY.deliver()


# ---------------------------------------------------------------------- garbage
_GC_TIMER: QTimer | None = None


def collect_if_due() -> None:
    """Collect the generations whose allocation counts passed the interpreter's thresholds.

    The survivors of a full collection are frozen (``gc.freeze``: left out of the next ones),
    so that a full collection scans what was made since the last, not every object of the
    window and its project: at 1,000 points ~160,000 objects, 100–175 ms on the GUI thread
    about every hundred clicks, now ~10 ms. What frozen objects leave in reference cycles is
    reclaimed by :func:`collect_everything`."""
    counts, thresholds = gc.get_count(), gc.get_threshold()
    for gen in (2, 1, 0):
        if counts[gen] > thresholds[gen]:
            gc.collect(gen)
            if gen == 2:
                gc.freeze()
            return


def collect_everything() -> None:
    """A full collection of every object, the frozen included, its survivors frozen again
    (~100 ms with a project open: after a large computation, and where tests free windows)."""
    gc.unfreeze()
    gc.collect()
    gc.freeze()


def collect_on_gui_thread(interval_ms: int = 500) -> None:
    """Disable automatic collection; collect from a GUI-thread timer instead (idempotent)."""
    global _GC_TIMER
    if _GC_TIMER is not None:
        return
    app = QCoreApplication.instance()
    _GC_TIMER = QTimer(app)
    _GC_TIMER.setInterval(int(interval_ms))
    _GC_TIMER.timeout.connect(collect_if_due)
    _GC_TIMER.start()
    gc.disable()
