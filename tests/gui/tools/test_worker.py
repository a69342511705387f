"""The tools' worker (gui/tools/_worker.py): cancel, errors as messages, a closing window."""
from __future__ import annotations

import time

import pytest
from PySide6.QtWidgets import QMainWindow

from prismstation.errors import InputError
from prismstation.gui.tools._worker import Job, run_with_progress


def _until_cancelled(seen):
    """A job body that reports progress until told to stop (10 s at most)."""
    def fn(progress):
        t0 = time.monotonic()
        while time.monotonic() - t0 < 10:
            seen.append(time.monotonic())
            if not progress(0.5, "working"):
                return "stopped"
            time.sleep(0.005)
        return "ran out"
    return fn


def test_cancel_ends_as_cancelled_only(qtbot, job_outcome):
    seen, reports = [], []
    job = Job(_until_cancelled(seen), "Loop")
    job.progress.connect(lambda f, m: reports.append((f, m)))
    job.start()
    qtbot.waitUntil(lambda: len(reports) >= 3, timeout=5000)
    job.cancel()
    assert job_outcome(job) == ("cancelled", None)
    assert not job.isRunning() and reports[0] == (0.5, "working")


@pytest.mark.parametrize("exc, want", [
    (InputError("no such reference DEM", "dem.tif"), "no such reference DEM"),
    (ZeroDivisionError("division by zero"), "Sums failed: ZeroDivisionError: division by zero"),
])
def test_an_error_is_a_one_line_message(qtbot, job_outcome, exc, want):
    def fn(progress):
        raise exc
    job = Job(fn, "Sums")
    job.start()
    kind, msg = job_outcome(job)
    assert kind == "failed" and want in msg and "Traceback" not in msg and "\n" not in msg


def test_closing_the_window_cancels_and_awaits_the_job(qtbot):
    win = QMainWindow()
    qtbot.addWidget(win)
    win.show()
    seen, results, failures = [], [], []
    job = run_with_progress(win, "Loop", _until_cancelled(seen), results.append,
                            on_failed=failures.append)
    qtbot.waitUntil(lambda: len(seen) >= 3, timeout=5000)
    win.close()
    assert not job.isRunning() and job.is_cancelled()  # stopped before close() returned
    qtbot.waitUntil(lambda: "cancelled" in win.statusBar().currentMessage(), timeout=5000)
    assert results == [] and failures == []


def test_run_with_progress_reports_a_failure(qtbot):
    win = QMainWindow()
    qtbot.addWidget(win)
    failures = []

    def fn(progress):
        progress(0.3)
        raise InputError("the DSM has no CRS")
    run_with_progress(win, "Validate DSM", fn, lambda v: None, on_failed=failures.append)
    qtbot.waitUntil(lambda: bool(failures), timeout=5000)
    assert failures == ["the DSM has no CRS"]
    assert win.statusBar().currentMessage() == "Validate DSM: the DSM has no CRS"


def test_a_progress_report_never_spins_the_event_loop(qtbot):
    """A window-modal QProgressDialog ran an event loop inside every setValue: a quit, the job's
    end or the dialog's deletion ran inside a progress report. Timers must not fire in one."""
    import traceback
    from PySide6.QtCore import QTimer
    win = QMainWindow()
    qtbot.addWidget(win)
    win.show()
    inside = []

    def fn(progress):
        t0 = time.monotonic()
        while time.monotonic() - t0 < 1.0:
            progress((time.monotonic() - t0) / 1.0, "step")
            time.sleep(0.002)
        return 1
    probe = QTimer()
    probe.timeout.connect(lambda: inside.append(any(f.name == "progressed" for f in traceback.extract_stack())))
    probe.start(1)
    results = []
    run_with_progress(win, "Loop", fn, results.append)
    qtbot.waitUntil(lambda: results == [1], timeout=10000)
    probe.stop()
    assert len(inside) > 50 and not any(inside)


def test_the_last_reference_to_a_job_goes_on_the_gui_thread(qtbot, monkeypatch):
    """A worker that dropped the last reference to its job deleted a QObject off the GUI thread
    (heap corruption, seen at quit). Here the worker lingers after posting its outcome, so the
    GUI side is done with the job first; the job must still be freed on the GUI thread."""
    import threading
    import weakref

    from prismstation.gui import workers
    post = workers.post

    def slow_post(*args, **kw):
        post(*args, **kw)
        if threading.current_thread() is not threading.main_thread():
            time.sleep(0.2)  # the worker is descheduled after its last post
    monkeypatch.setattr(workers, "post", slow_post)
    freed, results = [], []
    job = Job(lambda progress: progress(0.5) and 7, "Quick")
    job.result.connect(results.append)
    ref = weakref.ref(job, lambda _: freed.append(threading.current_thread()))
    job.start()
    del job
    qtbot.waitUntil(lambda: results == [7], timeout=5000)
    results.clear()
    qtbot.waitUntil(lambda: bool(freed) or ref() is None, timeout=5000)
    import gc
    gc.collect()
    time.sleep(0.3)
    assert freed == [threading.main_thread()]


def test_closing_the_progress_dialog_cancels_and_the_window_then_quits(qtbot, job_outcome):
    """The report's sequence: a job with its progress dialog, the dialog closed by its X (the
    job ignores the cancel for a while, as a long engine step does), then the window closed."""
    from PySide6.QtWidgets import QApplication, QProgressDialog
    win = QMainWindow()
    qtbot.addWidget(win)
    win.show()

    def fn(progress):
        t0 = time.monotonic()
        while time.monotonic() - t0 < 1.5:  # a step that checks for cancel only at its end
            progress(0.3, "matching")
            time.sleep(0.005)
        return "ran"
    job = run_with_progress(win, "DSM", fn, lambda v: None)
    qtbot.waitUntil(lambda: job.last[0] > 0, timeout=5000)
    dlg = next(w for w in QApplication.topLevelWidgets() if isinstance(w, QProgressDialog) and w.isVisible())
    assert not dlg.isModal()
    dlg.close()                                         # the title bar's X
    assert job.is_cancelled() and not dlg.isVisible()
    assert "cancelling" in win.statusBar().currentMessage()
    qtbot.wait(200)
    assert not dlg.isVisible()                          # reports after the cancel do not bring it back
    win.close()                                         # the window joins the job first
    assert not job.isRunning()
    assert job_outcome(job) == ("cancelled", None)
