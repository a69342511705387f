"""No job outlives what it reads: a window, a project or a view that goes away while tile reads,
image loads, fits and tool jobs run has joined them first, and every file handle of its images
is closed (each worker thread closes its own)."""
from __future__ import annotations

import threading
import time

from prismstation.gui import workers
from prismstation.gui.tools._worker import run_with_progress
from prismstation.io.raster import RasterSource

from tests.qt_windows import open_window


def _slow_reads(monkeypatch, seconds=0.1):
    """Every tile read takes ``seconds`` more; returns the list of (thread name, key) started."""
    started = []
    real = RasterSource.read_tile

    def slow(self, *key):
        started.append((threading.current_thread().name, key))
        time.sleep(seconds)
        return real(self, *key)
    monkeypatch.setattr(RasterSource, "read_tile", slow)
    return started


def _reads_in_flight(qtbot, win, started):
    """Ask every view for all its level-1 tiles; wait until reads run in several views."""
    for iv in win.views.views.values():
        ncols, nrows = iv.source.tile_grid(1)
        iv.loader.request([(1, c, r) for r in range(nrows) for c in range(ncols)])
    qtbot.waitUntil(lambda: len({name for name, _ in started}) >= 2, timeout=5000)
    assert any(iv.loader.pending() for iv in win.views.views.values())


def _close(win):
    """What the operator does: close the window (no save question: the edits are dropped)."""
    win.undo_stack.setClean()
    win.close()


def _no_worker_left():
    names = [t.name for t in threading.enumerate()]
    return workers.live() == [] and not any(n.startswith(("tiles-", "fit-", "tool-")) for n in names)


def test_closing_the_window_joins_tile_reads_fit_and_tool_job(qtbot, demo, monkeypatch):
    started = _slow_reads(monkeypatch)
    win = open_window(qtbot, demo.path)
    sources = [iv.source for iv in win.views.views.values()]
    _reads_in_flight(qtbot, win, started)
    stop = threading.Event()

    def long_job(progress):  # a tool's job that only ends when cancelled
        while progress(0.5) and not stop.wait(0.01):
            pass
    job = run_with_progress(win, "Long", long_job, lambda v: None, dialog=False)
    win.solver.inline_ms = 0.0  # the next fit runs in a worker
    win.move("G1", "N", *win.views.point_position("G1", "N"), True)
    win.solver._start()
    assert job.isRunning() and workers.live()
    _close(win)
    assert _no_worker_left(), [t.name for t in threading.enumerate()]
    assert job.is_cancelled()
    assert all(src._handles == [] for src in sources)  # every thread's handle closed


def test_opening_another_project_while_tiles_are_read(qtbot, demo, monkeypatch):
    started = _slow_reads(monkeypatch)
    win = open_window(qtbot, demo.path)
    old = {name: (iv.source, iv.loader) for name, iv in win.views.views.items()}
    _reads_in_flight(qtbot, win, started)
    win.undo_stack.setClean()
    assert win.open_project(demo.path, recover=False)  # the same file again: new sources
    for src, loader in old.values():  # the old readers ended before their files were closed
        assert not loader.jobs.busy() and src._handles == []
    assert all(iv.source is not old[n][0] for n, iv in win.views.views.items() if iv.source)
    _close(win)
    assert _no_worker_left()


def test_a_view_deleted_without_close_ends_its_readers(qtbot, demo, monkeypatch):
    """The safety net: a view deleted by its parent (no close event) stops its queue; the
    readers end after the read they are in, and deliver nothing."""
    started = _slow_reads(monkeypatch, 0.2)
    win = open_window(qtbot, demo.path)
    _reads_in_flight(qtbot, win, started)
    loaders = [iv.loader for iv in win.views.views.values()]
    for pane in win.views.panes.values():
        pane.deleteLater()
    qtbot.waitUntil(lambda: not any(ld.jobs.busy() for ld in loaders), timeout=5000)
    win.views.views = {}
    _close(win)
    assert _no_worker_left()
