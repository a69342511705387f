"""Refit after every change of the project, and publish the Solution.

Data flow (docs/architecture.md): a command edits the :class:`Project`; ``Project.changed`` arms a
zero-delay timer, so that many edits in one event-loop turn (an import, an undo macro) cause one
refit. A fit expected to take less than :attr:`Solver.inline_ms` (the last fit's time per point
times the points now: a few hundred points take a few milliseconds) runs right there on the GUI
thread, so that the marker, the table, the statistics and the plots change in one repaint; a
slower one (thousands of points, a reference DEM, the first fit) runs on a snapshot of the
project in a worker thread, and its :class:`Solution` is published by
:attr:`Solver.solution_changed` on the GUI thread. A result older than the newest one published
is dropped (by revision number); edits made while a fit runs start one more fit when it ends.
"""
from __future__ import annotations

import time

from PySide6.QtCore import QObject, QTimer, Signal

from prismstation.gui import workers

from prismstation.errors import PrismError
from prismstation.ops.fit import FitMemo, solve_project


def snapshot(project):
    """``project.snapshot()``: a copy safe to solve in another thread while the original is
    edited."""
    return project.snapshot()


def _fit(snap, height_of, memo=None):
    """``(solution or None, error text or None, seconds)``: a fit never raises — an error the
    operator can fix is its message, anything else is named (the window must survive it).
    ``memo``: the solver's :class:`~prismstation.ops.fit.FitMemo`."""
    t0 = time.perf_counter()
    try:
        # the reference DEM's σ is the project's setting (a model that holds tie points to the
        # DEM weighs them with it: ops.fit.reference_sigma; the PRISM model does not use it)
        sol, err = solve_project(snap, height_of=height_of, memo=memo), None
    except PrismError as exc:
        sol, err = None, str(exc)
    except Exception as exc:
        sol, err = None, f"the fit failed: {type(exc).__name__}: {exc}"
    return sol, err, time.perf_counter() - t0


def _fit_job(on_done, snap, height_of, memo, generation) -> None:  # worker thread
    workers.post(on_done, *_fit(snap, height_of, memo), generation)


class Solver(QObject):
    """Keeps :attr:`solution` current for one project.

    Signals
    -------
    solution_changed(Solution)
        A newer fit is available (GUI thread).
    failed(str)
        The fit raised an error the operator can fix (e.g. a geoid grid not found).

    Attributes
    ----------
    last_fit_ms : float
        Duration of the last fit, milliseconds.
    inline_ms : float
        A fit expected to take less than this runs on the GUI thread (0: always in the worker).
        Handing a 5 ms fit to a thread costs more than the fit: the hand-off waits for the event
        loop, and the two threads contend for the interpreter.
    """

    inline_ms = 25.0

    solution_changed = Signal(object)
    failed = Signal(str)

    def __init__(self, parent=None, threaded: bool = True):
        super().__init__(parent)
        self.project = None
        self.solution = None
        self.last_fit_ms = float("nan")
        self._fit_points = 1   # points in the fit started last
        self._ms_per_point = float("nan")
        self.threaded = threaded
        self.height_of = None  # reference DEM: (n, 2) map metres -> (n,) ellipsoidal metres
        self.memo = FitMemo()  # what the next fit takes again from the last ones (a click moves one view)
        self._generation = 0  # bumped per project: fits of a previous project are dropped
        self._running = False
        self._dirty = False
        self._jobs = workers.Jobs("fit")
        self._timer = QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.setInterval(0)
        self._timer.timeout.connect(self._start)
        self._retired: list = []
        self._reaper = QTimer(self)
        self._reaper.setSingleShot(True)
        self._reaper.setInterval(50)
        self._reaper.timeout.connect(self._retired.clear)

    def set_project(self, project) -> None:
        if self.project is not None:
            self.project.changed.disconnect(self._on_changed)
        self.project = project
        self.solution = None
        self._generation += 1
        if project is not None:
            project.changed.connect(self._on_changed)
            self._on_changed()

    def _on_changed(self, *_) -> None:
        self._dirty = True
        self._timer.start()

    def set_height_of(self, fn) -> None:
        """Use a reference DEM for points without parallax (None: the mean height); refits."""
        self.height_of = fn
        if self.project is not None:
            self._on_changed()

    def busy(self) -> bool:
        """True while a change waits for its fit or a fit runs."""
        return self._dirty or self._running

    def refit_now(self):
        """Fit synchronously on this thread and publish (scripts, screenshots)."""
        self._timer.stop()
        self._jobs.wait()
        self._dirty = False
        self._fit_points = max(len(self.project.points), 1)
        self._publish(*_fit(snapshot(self.project), self.height_of, self.memo))
        return self.solution

    def _start(self) -> None:
        if self.project is None or self._running or not self._dirty or self._jobs.closed:
            return
        self._dirty = False
        snap = snapshot(self.project)
        self._fit_points = max(len(snap.points), 1)
        expected = self._ms_per_point * self._fit_points  # (NaN at first: the worker)
        if not self.threaded or expected < self.inline_ms:
            self._publish(*_fit(snap, self.height_of, self.memo))
            return
        self._running = True
        self._jobs.start(_fit_job, self._on_done, snap, self.height_of, self.memo, self._generation)

    def _on_done(self, sol, err, seconds, generation) -> None:
        self._running = False
        if generation == self._generation:
            self._publish(sol, err, seconds)
        if self._dirty:
            self._timer.start()

    def _publish(self, sol, err, seconds) -> None:
        self.last_fit_ms = seconds * 1000.0
        self._ms_per_point = self.last_fit_ms / self._fit_points
        if err is not None:
            self.failed.emit(err)
            return
        if self.solution is not None and sol.revision < self.solution.revision \
                and self.project is not None and sol.revision != self.project.revision:
            return  # stale
        # the previous solution (thousands of small objects) is freed when the window is idle,
        # not by whichever widget happens to drop the last reference during the repaint
        self._retired.append(self.solution)
        self._reaper.start()
        self.solution = sol
        self.solution_changed.emit(sol)

    def shutdown(self) -> None:
        """Join the running fit (it reads a snapshot and the reference DEM); none starts after."""
        self._timer.stop()
        self._generation += 1  # a fit delivered after this is dropped
        self._jobs.close()
