"""Crash recovery: every edit of a project is journaled as it happens.

:class:`Journal` listens to :attr:`Project.changed` and writes the whole project atomically
(temporary file, fsync, rename) to ``<project>.recovery`` after every edit. Saving the project
clears the journal. At the next start :func:`recovery_for` tells whether there is something
to recover and :func:`recover` reads it (the project file itself is never touched).

By default the write happens in the edit's own call, so a crash or a ``kill -9`` loses at most
the edit being written, never an earlier one. With ``background=True`` (the window) the edit's
call only takes a snapshot of the project (:meth:`Project.snapshot`: two dict copies, ~20 µs
for 1,000 points) and hands it to one writer thread, which serialises and writes the newest
snapshot handed over (edits that arrive during one write are coalesced into the next). A crash
then loses at most the edits made since the last completed write — those of the write in
flight, a few to a few tens of milliseconds — never an earlier one: the file on disk is always
one whole, consistent state of the project, and a newer state is never replaced by an older
one. :meth:`Journal.flush` waits until everything handed over is on disk; :meth:`Journal.discard` (and so :meth:`Journal.save`) cancels what is
pending and waits for the write in flight before removing the file, so a late write never
brings back the journal of a saved project.

:class:`~prismstation.io.lock.ProjectLock` (``<project>.lock``) says which process works on a
project, so that a second window opening it does not take the first one's journal for a crash
to recover.
"""
from __future__ import annotations

import logging
import os
import threading
import time
from pathlib import Path
from typing import Callable

from prismstation.io.atomic import write_atomic
from prismstation.io.jsonfile import dumps
from prismstation.io.project import load_project, project_to_dict, save_project
from prismstation.model.project import Change, Project

SUFFIX = ".recovery"
IDLE_S = 5.0  # the writer thread ends after this long without work (started again on demand)

_log = logging.getLogger(__name__)


def recovery_path(project_path) -> Path:
    p = Path(project_path)
    return p.with_name(p.name + SUFFIX)


class Journal:
    """Journal ``project`` edits beside ``project_path`` (which need not exist yet).

    Parameters
    ----------
    project, project_path
        The project to follow and the path of its project file.
    background : bool
        Write on one writer thread (the edit's call only serialises); see the module docstring.
        The thread is started on demand and ends after :data:`IDLE_S` s without work, so a
        journal dropped without :meth:`close` leaves no thread behind.
    on_error : callable(Exception), optional
        Called with every write error. In background mode it is called **on the writer
        thread**; without it such errors are logged (and kept in :attr:`last_error`). In
        synchronous mode without it the error is raised from the edit's call.

    Attributes
    ----------
    writes : int
        Documents written to disk.
    submitted : int
        Documents journaled (written, or handed to the writer thread; coalesced ones count).
    written_revision : int or None
        The project revision of the newest document written to disk.
    last_error : Exception or None
        The last write error.
    """

    def __init__(self, project: Project, project_path, *, background: bool = False,
                 on_error: Callable[[Exception], None] | None = None):
        self.project = project
        self.path = Path(project_path)
        self.background = background
        self.on_error = on_error
        self.writes = 0
        self.submitted = 0
        self.written_revision: int | None = None
        self.last_error: Exception | None = None
        self._cond = threading.Condition()
        self._pending: tuple | None = None  # (project path, project or snapshot, revision, time)
        self._busy = False  # the writer thread is writing (outside the lock)
        self._stop = False
        self._thread: threading.Thread | None = None  # the writer, while it runs
        project.changed.connect(self._on_changed)

    # ------------------------------------------------------------------ journaling
    def _on_changed(self, change: Change) -> None:
        self.journal(change.revision)

    def journal(self, revision: int) -> None:
        """Write the project (at ``revision``) here, or hand a snapshot of it to the writer
        thread (serialised there)."""
        if not self.background or self._stop:  # (after close: written here, not dropped)
            item = (self.path, self.project, revision, time.time())
            self.submitted += 1
            try:
                self._write(item)
            except Exception as exc:
                self.last_error = exc
                if self.on_error is None:
                    raise
                self.on_error(exc)
            return
        item = (self.path, self.project.snapshot(), revision, time.time())
        with self._cond:
            self._pending = item  # replaces an older document not yet started: coalescing
            self.submitted += 1
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, daemon=True,
                                                name=f"journal {self.path.name}")
                self._thread.start()
            self._cond.notify_all()

    def _write(self, item: tuple) -> None:
        path, project, revision, when = item
        doc = project_to_dict(project, path)
        doc["recovery"] = {"of": path.name, "revision": revision, "time": when}
        write_atomic(recovery_path(path), dumps(doc), keep_backup=False)
        self.writes += 1
        self.written_revision = revision

    def _run(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: self._pending is not None or self._stop, IDLE_S)
                if self._pending is None:  # stopped or idle, nothing left
                    self._thread = None
                    return
                item, self._pending = self._pending, None
                self._busy = True
            try:
                self._write(item)
            except Exception as exc:  # reported, never lost; the thread goes on
                self.last_error = exc
                try:
                    if self.on_error is None:
                        _log.error("recovery journal %s not written: %s", recovery_path(item[0]), exc)
                    else:
                        self.on_error(exc)
                except Exception:  # a failing callback must not stop the writer
                    _log.exception("recovery journal error callback failed")
            finally:
                with self._cond:
                    self._busy = False
                    self._cond.notify_all()

    def flush(self, timeout: float | None = None) -> bool:
        """Wait until every document handed over is written (or its write failed).

        Returns False when ``timeout`` (seconds) ran out first; True at once in synchronous mode.
        """
        with self._cond:
            return self._cond.wait_for(lambda: self._pending is None and not self._busy, timeout)

    # ------------------------------------------------------------------ life cycle
    def save(self, path=None) -> None:
        """Save the project (atomically, with backup) and clear the journal."""
        if path is not None and Path(path) != self.path:
            self.discard()
            self.path = Path(path)
        save_project(self.project, self.path)
        self.discard()

    def discard(self) -> None:
        """Remove the journal: drop what is pending, wait for the write in flight, unlink."""
        with self._cond:
            self._pending = None
            self._cond.wait_for(lambda: not self._busy)
            try:  # under the lock: no write can start before the file is gone
                os.unlink(recovery_path(self.path))
            except FileNotFoundError:
                pass

    def close(self, timeout: float | None = None) -> None:
        """Stop journaling: what was handed over is written first, then the thread ends."""
        self.project.changed.disconnect(self._on_changed)
        with self._cond:
            self._stop = True
            thread = self._thread
            self._cond.notify_all()
        if thread is not None:
            thread.join(timeout)


def recovery_for(project_path) -> Path | None:
    """The journal left by a session that did not save, or None."""
    r = recovery_path(project_path)
    return r if r.is_file() else None


def recover(project_path) -> Project:
    """The project as journaled (unsaved edits included); the project file is untouched.

    The returned project counts as modified (revision > 0) so that the user saves it.
    """
    project = load_project(recovery_path(project_path))
    project.mark_modified()
    return project
