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
