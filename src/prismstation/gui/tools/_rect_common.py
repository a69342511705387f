"""Shared pieces of the rectification / resection / DSM tools: the project's points of one view,
a worker thread with progress and cancel, and a refresh coalescer."""
from __future__ import annotations

import numpy as np
from PySide6.QtCore import QEvent, QObject, QThread, QTimer, Signal

from prismstation.errors import PrismError


def view_points(project, view: str):
    """GCPs and ICPs of ``project`` measured in ``view``.

    Returns ``(ids, xy, ground, is_check)``: ids (n,), image ``xy`` (n, 2) pixels, ``ground``
    (n, 3) ``E, N, H`` (metres, project CRS; H of the point's own height kind) and ``is_check``
    (n,) True for ICPs. Tie points are left out (no ground coordinates).
    """
    ids, xy, g, chk = [], [], [], []
    for pid, p in project.points.items():
        if p.kind not in ("GCP", "ICP"):
            continue
        m = project.measurement(pid, view)
        if m is None:
            continue
        ids.append(pid)
        xy.append((m.x, m.y))
        g.append((p.E, p.N, p.H))
        chk.append(p.kind == "ICP")
    return (tuple(ids), np.array(xy, float).reshape(-1, 2), np.array(g, float).reshape(-1, 3),
            np.array(chk, bool))


class Worker(QThread):
    """Run ``fn(progress)`` in a thread; ``progress(fraction) -> bool`` returns False once
    :meth:`cancel` was called. Emits ``progressed(int percent)`` and ``done(result, error)``
    (``error`` a one-line message, ``""`` on success)."""

    progressed = Signal(int)
    done = Signal(object, str)

    def __init__(self, fn, parent=None):
        super().__init__(parent)
        self.fn, self.cancelled, self.result, self.error = fn, False, None, None

    def cancel(self) -> None:
        self.cancelled = True

    def _progress(self, f: float) -> bool:
        self.progressed.emit(int(round(100 * f)))
        return not self.cancelled

    def run(self) -> None:
        try:
            self.result, self.error = self.fn(self._progress), ""
        except (PrismError, OSError, ValueError) as exc:
            self.result, self.error = None, str(exc)
        self.done.emit(self.result, self.error)


class _CloseGuard(QObject):
    def __init__(self, window, jobs):
        super().__init__(window)
        self.jobs = jobs

    def eventFilter(self, obj, ev) -> bool:
        if ev.type() == QEvent.Type.Close:
            for job in self.jobs():
                if job is not None and job.isRunning():
                    job.cancel()
                    job.wait(60000)
        return False


def finish_on_close(window, jobs) -> None:
    """When ``window`` closes, cancel and wait for the running workers ``jobs()`` returns
    (a QThread must not be destroyed while it runs)."""
    window.installEventFilter(_CloseGuard(window, jobs))


class Coalescer(QObject):
    """Call ``fn()`` once on the next event-loop turn however often :meth:`poke` was called."""

    def __init__(self, fn, parent=None):
        super().__init__(parent)
        self._t = QTimer(self)
        self._t.setSingleShot(True)
        self._t.setInterval(0)
        self._t.timeout.connect(fn)

    def poke(self, *_) -> None:
        self._t.start()


def watch_project(window, fn) -> Coalescer:
    """Call ``fn()`` after every edit, fit, and project (re)load of ``window``."""
    c = Coalescer(fn, window)
    window.undo_stack.indexChanged.connect(c.poke)
    window.solver.solution_changed.connect(c.poke)
    window.views.images_loaded.connect(c.poke)
    return c


def fmt(v: float, digits: int = 3) -> str:
    return f"{v:.{digits}f}" if v is not None and np.isfinite(v) else "—"
