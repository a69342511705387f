"""The journal's background writer (io/recovery.py): coalescing, flush, save/discard against a
write in flight, errors reported from the thread, close joins the thread.

Slow disks are simulated by wrapping ``write_atomic`` (the real one still writes the file).
"""
from __future__ import annotations

import json
import logging
import threading
import time

import pytest

import prismstation.io.recovery as rec
from prismstation.io.jsonfile import write_atomic
from prismstation.io.recovery import Journal, recover, recovery_for, recovery_path
from prismstation.model.points import Measurement
from tests.io.test_geoid_project import _project


class SlowDisk:
    """``write_atomic`` that takes ``delay`` s (after the real write, before returning); records
    the revision of every document written and the thread that wrote it."""

    def __init__(self, delay=0.0, fail=None, gate=None):
        self.delay, self.fail, self.gate = delay, fail, gate
        self.revisions, self.threads = [], []
        self.started = threading.Event()

    def __call__(self, path, text, keep_backup=True):
        self.started.set()
        self.threads.append(threading.current_thread())
        if self.gate is not None:
            self.gate.wait()  # a disk that answers only when the test lets it
        time.sleep(self.delay)  # the fsync of a slow disk, before the rename lands
        if self.fail is not None:
            raise self.fail
        write_atomic(path, text, keep_backup)
        self.revisions.append(json.loads(text)["recovery"]["revision"])


@pytest.fixture()
def proj(tmp_path):
    _project(tmp_path)
    from prismstation.io.project import load_project
    path = tmp_path / "p.prismproj"
    return load_project(path), path


def edit(project, k, view="N"):
    project.set_measurement(Measurement(f"K{k}", view, 10.0 + k, 20.0 + 0.5 * k))


def journal_revision(path):
    return json.loads(recovery_path(path).read_text())["recovery"]["revision"]


def test_default_is_synchronous(proj, monkeypatch):
    project, path = proj
    disk = SlowDisk()
    monkeypatch.setattr(rec, "write_atomic", disk)
    j = Journal(project, path)
    edit(project, 1)
    assert recovery_for(path) is not None and journal_revision(path) == project.revision
    assert disk.threads == [threading.current_thread()]
    assert j.writes == j.submitted == 1 and j._thread is None
    j.close()


def test_the_edit_only_takes_a_snapshot_the_writer_serialises_it(proj, monkeypatch):
    """The edit's call (the GUI thread) never serialises: ``project_to_dict`` runs on the
    writer thread, on a snapshot that later edits do not reach."""
    project, path = proj
    gate = threading.Event()
    disk = SlowDisk(gate=gate)
    monkeypatch.setattr(rec, "write_atomic", disk)
    serialised_on = []
    to_dict = rec.project_to_dict

    def spy(project, path):
        serialised_on.append(threading.current_thread())
        return to_dict(project, path)
    monkeypatch.setattr(rec, "project_to_dict", spy)
    j = Journal(project, path, background=True)
    edit(project, 1)
    assert disk.started.wait(5)  # the writer serialised revision r and waits for the disk
    edit(project, 2)  # r + 1 handed over behind it, as a snapshot
    handed = project.revision
    project.changed.disconnect(j._on_changed)  # edits from now on are not journaled ...
    project.remove_point("K1")  # ... and must not reach the snapshot of r + 1
    project.set_measurement(Measurement("K2", "N", 1.0, 2.0))
    gate.set()
    assert j.flush(timeout=10) and disk.revisions == [handed - 1, handed]
    assert serialised_on and threading.main_thread() not in serialised_on
    assert all(t.name.startswith("journal") for t in serialised_on)
    got = recover(path)
    assert "K1" in got.points and got.measurement("K2", "N").x == 10.0 + 2
    project.changed.connect(j._on_changed)
    j.close()


def test_rapid_edits_are_coalesced_and_the_last_state_lands(proj, monkeypatch):
    project, path = proj
    gate = threading.Event()
    disk = SlowDisk(delay=0.03, gate=gate)
    monkeypatch.setattr(rec, "write_atomic", disk)
    j = Journal(project, path, background=True)
    watchdog = threading.Timer(30.0, gate.set)  # opens the disk if an edit waits for it
    watchdog.start()
    for k in range(60):  # the disk answers nothing until the loop is over
        edit(project, k)
    assert not gate.is_set(), "the edits waited for the disk"
    watchdog.cancel()
    gate.set()
    assert j.flush(timeout=10)
    assert j.submitted == 60
    assert 1 <= j.writes <= 10 and len(disk.revisions) == j.writes  # far fewer writes than edits
    assert disk.revisions == sorted(disk.revisions)  # never an older state after a newer one
    assert j.written_revision == project.revision == journal_revision(path)
    got = recover(path)
    assert got.measurements == project.measurements and got.points == project.points
    assert all(t is not threading.current_thread() for t in disk.threads)
    j.close()


def test_flush_timeout_and_close_writes_what_was_handed_over(proj, monkeypatch):
    project, path = proj
    disk = SlowDisk(delay=0.25)
    monkeypatch.setattr(rec, "write_atomic", disk)
    j = Journal(project, path, background=True)
    edit(project, 1)
    assert disk.started.wait(5)
    edit(project, 2)  # pending behind the write in flight
    assert j.flush(timeout=0.01) is False
    thread = j._thread
    j.close()  # the pending document is written, then the thread ends
    assert not thread.is_alive()
    assert journal_revision(path) == project.revision
    assert "K2" in recover(path).points
    edit(project, 3)  # no longer journaled
    assert journal_revision(path) == project.revision - 1
    j.close()  # twice is fine


def test_save_with_a_write_in_flight_leaves_no_journal(proj, monkeypatch):
    project, path = proj
    disk = SlowDisk(delay=0.2)
    monkeypatch.setattr(rec, "write_atomic", disk)
    j = Journal(project, path, background=True)
    edit(project, 1)
    assert disk.started.wait(5)  # the first write is under way (its rename not yet done) ...
    edit(project, 2)  # ... and a newer document waits behind it
    j.save()
    assert recovery_for(path) is None
    j.flush(timeout=5)
    time.sleep(0.3)  # a late write would land here
    assert recovery_for(path) is None, "a background write brought back the journal of a saved project"
    assert disk.revisions == [project.revision - 1]  # the pending one was dropped, not written
    from prismstation.io.project import load_project
    assert "K2" in load_project(path).points
    j.close()


def test_discard_cancels_the_pending_document(proj, monkeypatch):
    project, path = proj
    disk = SlowDisk(delay=0.15)
    monkeypatch.setattr(rec, "write_atomic", disk)
    j = Journal(project, path, background=True)
    edit(project, 1)
    assert disk.started.wait(5)
    for k in range(2, 6):
        edit(project, k)
    j.discard()
    assert recovery_for(path) is None
    assert j.flush(timeout=5)
    assert recovery_for(path) is None and len(disk.revisions) == 1
    edit(project, 7)  # journaling goes on after a discard
    assert j.flush(timeout=5) and journal_revision(path) == project.revision
    j.close()


def test_write_errors_reach_the_callback_from_the_writer_thread(proj, monkeypatch):
    project, path = proj
    disk = SlowDisk(fail=OSError(28, "No space left on device"))
    monkeypatch.setattr(rec, "write_atomic", disk)
    errors = []
    j = Journal(project, path, background=True,
                on_error=lambda exc: errors.append((exc, threading.current_thread())))
    edit(project, 1)
    assert j.flush(timeout=5)
    assert len(errors) == 1 and "No space left" in str(errors[0][0])
    assert errors[0][1] is not threading.main_thread() and errors[0][1].name.startswith("journal")
    assert j.last_error is errors[0][0]
    assert recovery_for(path) is None and j.writes == 0
    disk.fail = None  # the disk recovers: the thread is still there and writes the next edit
    edit(project, 2)
    assert j.flush(timeout=5) and journal_revision(path) == project.revision
    j.close()


def test_write_errors_without_a_callback_are_logged(proj, monkeypatch, caplog):
    project, path = proj
    monkeypatch.setattr(rec, "write_atomic", SlowDisk(fail=PermissionError(13, "Permission denied")))
    j = Journal(project, path, background=True)
    with caplog.at_level(logging.ERROR, logger="prismstation.io.recovery"):
        edit(project, 1)
        assert j.flush(timeout=5)
    assert any("Permission denied" in r.getMessage() for r in caplog.records)
    assert isinstance(j.last_error, PermissionError)
    j.close()


def test_sync_errors_raise_or_go_to_the_callback(proj, monkeypatch):
    project, path = proj
    monkeypatch.setattr(rec, "write_atomic", SlowDisk(fail=OSError(5, "I/O error")))
    j = Journal(project, path)
    with pytest.raises(OSError):
        edit(project, 1)
    j.close()
    errors = []
    j = Journal(project, path, on_error=errors.append)
    edit(project, 2)
    assert len(errors) == 1
    j.close()


def test_the_writer_thread_ends_when_idle_and_comes_back(proj, monkeypatch):
    project, path = proj
    monkeypatch.setattr(rec, "IDLE_S", 0.05)
    disk = SlowDisk()
    monkeypatch.setattr(rec, "write_atomic", disk)
    j = Journal(project, path, background=True)
    assert j._thread is None  # nothing to write yet: no thread
    edit(project, 1)
    first = j._thread
    assert first is not None and j.flush(timeout=5)
    first.join(timeout=5)
    assert not first.is_alive() and j._thread is None
    edit(project, 2)  # a new writer on demand
    assert j.flush(timeout=5) and journal_revision(path) == project.revision
    assert len({t.ident for t in disk.threads}) >= 1 and threading.main_thread() not in disk.threads
    j.close()
