"""The window's recovery journal (gui/project_io.py) writes on its own thread: an edit does not
wait for the disk, write errors reach the status bar through the GUI thread, and save, undo to
the saved state, save as, reopen and close stay right with a write in flight.

Slow or failing disks are simulated by wrapping ``write_atomic`` in io/recovery.py.
"""
from __future__ import annotations

import json
import threading
import time

import pytest
from PySide6.QtGui import QUndoStack

import prismstation.io.recovery as rec
from prismstation.gui.commands import PlaceMeasurement
from prismstation.gui.project_io import ProjectFiles, autosave_path
from tests.io.test_recovery_background import SlowDisk


@pytest.fixture()
def files(qtbot, demo):
    stack = QUndoStack()
    pf = ProjectFiles(stack)
    pf.interactive = False
    assert pf.open_project(str(demo.path), recover=False)
    pf.demo = demo
    yield pf
    pf.stack.setClean()
    pf.close()


def place(pf, k, view="N"):
    pf.stack.push(PlaceMeasurement(pf.project, "G9", view, 100.0 + k, 200.0 + k))


def side_revision(pf):
    return json.loads(autosave_path(pf.path).read_text())["recovery"]["revision"]


def test_an_edit_does_not_wait_for_the_disk(files, monkeypatch):
    disk = SlowDisk(delay=0.3)
    monkeypatch.setattr(rec, "write_atomic", disk)
    assert files.journal.background
    t0 = time.perf_counter()
    place(files, 1)
    place(files, 2, "F")
    assert time.perf_counter() - t0 < 0.15
    assert files.flush_journal(timeout=10)
    assert side_revision(files) == files.project.revision
    assert disk.threads and all(t is not threading.main_thread() for t in disk.threads)
    assert files.autosave() and side_revision(files) == files.project.revision  # write + flush


def test_edits_are_journaled_when_the_window_is_idle(files, qtbot, monkeypatch):
    """Not in the edit's call (a click's repaint must not wait for the serialisation), but
    within the idle delay and without any flush; edits in that time make one document."""
    disk = SlowDisk(delay=0.0)
    monkeypatch.setattr(rec, "write_atomic", disk)
    place(files, 1)
    place(files, 2, "F")
    assert files.journal.armed and files.journal.submitted == 0  # nothing serialised yet
    t0 = time.perf_counter()
    qtbot.waitUntil(lambda: autosave_path(files.path).exists(), timeout=3000)
    assert time.perf_counter() - t0 < 1.0
    assert files.journal.submitted == 1 and side_revision(files) == files.project.revision
    # an edit undone before the timer fired leaves no journal of the clean state behind
    files.save()
    place(files, 3)
    files.stack.undo()
    qtbot.wait(3 * files.journal.IDLE_MS)
    assert files.stack.isClean() and not autosave_path(files.path).exists()


def test_write_errors_reach_the_status_from_the_gui_thread(files, qtbot, monkeypatch):
    monkeypatch.setattr(rec, "write_atomic", SlowDisk(fail=OSError(28, "No space left on device")))
    got = []
    files.message.connect(lambda m: got.append((m, threading.get_ident())))
    place(files, 1)
    assert files.flush_journal(timeout=10)
    assert not got, "the message was delivered on the writer thread"  # queued, not yet here
    qtbot.waitUntil(lambda: bool(got), timeout=3000)
    text, ident = got[0]
    assert "Recovery journal not written" in text and "No space left" in text
    assert ident == threading.main_thread().ident


def test_save_with_a_write_in_flight_leaves_no_journal(files, qtbot, monkeypatch):
    disk = SlowDisk(delay=0.2)
    monkeypatch.setattr(rec, "write_atomic", disk)
    place(files, 1)
    qtbot.waitUntil(disk.started.is_set, timeout=5000)  # the idle timer handed it over
    place(files, 2, "F")  # pending behind the write in flight
    assert files.save()
    files.flush_journal(timeout=10)
    time.sleep(0.3)  # a late write would land here
    assert not autosave_path(files.path).exists()


def test_undo_to_the_saved_state_with_a_write_in_flight_leaves_no_journal(files, qtbot, monkeypatch):
    disk = SlowDisk(delay=0.2)
    monkeypatch.setattr(rec, "write_atomic", disk)
    place(files, 1)
    qtbot.waitUntil(disk.started.is_set, timeout=5000)  # the idle timer handed it over
    files.stack.undo()
    assert files.stack.isClean()
    files.flush_journal(timeout=10)
    time.sleep(0.3)
    assert not autosave_path(files.path).exists()


def test_save_as_with_a_write_in_flight_leaves_no_journal(files, qtbot, monkeypatch):
    disk = SlowDisk(delay=0.2)
    monkeypatch.setattr(rec, "write_atomic", disk)
    old = files.path
    place(files, 1)
    qtbot.waitUntil(disk.started.is_set, timeout=5000)  # the idle timer handed it over
    place(files, 2, "F")
    assert files.save_as(str(old.parent / "other.prismproj"))
    files.flush_journal(timeout=10)
    time.sleep(0.3)
    assert not autosave_path(old).exists() and not autosave_path(files.path).exists()


def test_reopen_and_close_flush_the_journal(files, qtbot, monkeypatch):
    disk = SlowDisk(delay=0.2)
    monkeypatch.setattr(rec, "write_atomic", disk)
    place(files, 1)
    want = files.project.measurement("G9", "N")
    # reopening at once finds the edit in the journal (it was flushed before looking)
    assert files.open_project(str(files.path), recover=True, check_unsaved=False)
    assert files.project.measurement("G9", "N") == want
    assert not files.stack.isClean()
    files.journal.flush(timeout=10)
    place(files, 2, "F")
    rev, journal = files.project.revision, files.journal
    files.close()  # unsaved: the journal stays, complete
    assert journal._thread is None
    assert json.loads(autosave_path(files.path).read_text())["recovery"]["revision"] == rev


def test_the_window_shows_a_journal_write_error(window, qtbot, monkeypatch):
    monkeypatch.setattr(rec, "write_atomic", SlowDisk(fail=OSError(30, "Read-only file system")))
    win = window
    win.measure_mode.set_mode("create")
    win.place("N", 150.0, 250.0)
    assert win.files.flush_journal(timeout=10)
    qtbot.waitUntil(lambda: "Recovery journal not written" in win.statusBar().currentMessage(),
                    timeout=3000)
    assert "Read-only" in win.statusBar().currentMessage()
