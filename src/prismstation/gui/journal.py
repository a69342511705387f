"""The window's recovery journal and where it lives (see :mod:`.project_io`).

:class:`WindowJournal` journals every edit of the open project to ``<project>.recovery``: an
edit only arms a short timer; once the window is idle a snapshot of the project is handed to
the journal's writer thread, which serialises and writes it. A never-saved project's journal lives in the settings directory
(:func:`untitled_path`).
"""
from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import QTimer

from prismstation.gui import settings as st
from prismstation.io.project import SUFFIX
from prismstation.io.lock import ProjectLock
from prismstation.io.recovery import Journal, recovery_path


def untitled_path() -> Path:
    """Where the journal of a never-saved project lives (its name plus ``.recovery``)."""
    name = st._settings().fileName()
    base = Path(name).parent if name else Path.home()
    return base / "untitled.prismproj"


def autosave_path(path) -> Path:
    """The journal (recovery file) of the project at ``path`` (None: the untitled project's)."""
    return recovery_path(untitled_path() if path is None else path)


def untitled_journals() -> list[Path]:
    """Journals of untitled projects that no live window holds, newest first."""
    base = untitled_path()
    found = [p for p in base.parent.glob(f"untitled*{SUFFIX}.recovery")
             if ProjectLock(p.with_suffix("")).holder() is None]
    return sorted(found, key=lambda p: p.stat().st_mtime, reverse=True)


class WindowJournal(Journal):
    """A journal whose write failure is a status message, never an exception in an edit.

    An edit only arms a short timer (:attr:`IDLE_MS`): once the window is idle again a
    snapshot of the project (~20 µs for 1,000 points) is handed to the writer thread, which
    serialises it (5–25 ms for 200–1,000 points, away from the GUI thread) and writes it; edits
    within that time make one document. The timer keeps the writer's Python work out of the
    click → repaint that follows an edit. A crash thus loses at most the edits of the last
    :attr:`IDLE_MS` and of the write in flight. ``report(str)`` is called from the writer
    thread (serialisation and write errors), so it must be safe to call from any thread
    (:class:`ProjectFiles` posts it to the GUI thread).
    """

    IDLE_MS = 40

    def __init__(self, project, path, report, background: bool = True):
        self.report = report
        self._timer = QTimer()
        self._timer.setSingleShot(True)
        self._timer.setInterval(self.IDLE_MS)
        self._timer.timeout.connect(self.write)
        super().__init__(project, path, background=background, on_error=self._failed)

    def _failed(self, exc: Exception) -> None:
        self.report(f"Recovery journal not written: {exc}")

    def _on_changed(self, change) -> None:
        if not self._timer.isActive():  # the first edit since the last document sets the pace
            self._timer.start()

    @property
    def armed(self) -> bool:
        """An edit waits for the timer to be journaled."""
        return self._timer.isActive()

    def write(self) -> None:
        """Journal the project now."""
        self._timer.stop()
        self.journal(self.project.revision)

    def flush(self, timeout: float | None = None) -> bool:
        if self._timer.isActive():
            self.write()
        return super().flush(timeout)

    def discard(self) -> None:
        self._timer.stop()
        super().discard()

    def close(self, timeout: float | None = None) -> None:
        if self._timer.isActive():
            self.write()
        super().close(timeout)
