"""Crash recovery: every edit of a project is journaled as it happens.

:class:`Journal` listens to :attr:`Project.changed` and writes the whole project atomically
(temporary file, fsync, rename) to ``<project>.recovery`` after every edit, so a crash or a
``kill -9`` loses at most the edit being written, never an earlier one. Saving the project
clears the journal. At the next start :func:`recovery_for` tells whether there is something
to recover and :func:`recover` reads it (the project file itself is never touched).
"""
from __future__ import annotations

import json
import os
import time
from pathlib import Path

from prismstation.io.jsonfile import write_atomic
from prismstation.io.project import load_project, project_to_dict, save_project
from prismstation.model.project import Project

SUFFIX = ".recovery"


def recovery_path(project_path) -> Path:
    p = Path(project_path)
    return p.with_name(p.name + SUFFIX)


class Journal:
    """Journal ``project`` edits beside ``project_path`` (which need not exist yet)."""

    def __init__(self, project: Project, project_path):
        self.project = project
        self.path = Path(project_path)
        self.writes = 0
        project.changed.connect(self._on_changed)

    def _on_changed(self, revision: int) -> None:
        doc = project_to_dict(self.project, self.path)
        doc["recovery"] = {"of": self.path.name, "revision": revision, "time": time.time()}
        write_atomic(recovery_path(self.path), json.dumps(doc, ensure_ascii=False), keep_backup=False)
        self.writes += 1

    def save(self, path=None) -> None:
        """Save the project (atomically, with backup) and clear the journal."""
        if path is not None and Path(path) != self.path:
            self.discard()
            self.path = Path(path)
        save_project(self.project, self.path)
        self.discard()

    def discard(self) -> None:
        try:
            os.unlink(recovery_path(self.path))
        except FileNotFoundError:
            pass

    def close(self) -> None:
        self.project.changed.disconnect(self._on_changed)


def recovery_for(project_path) -> Path | None:
    """The journal left by a session that did not save, or None."""
    r = recovery_path(project_path)
    return r if r.is_file() else None


def recover(project_path) -> Project:
    """The project as journaled (unsaved edits included); the project file is untouched.

    The returned project counts as modified (revision > 0) so that the user saves it.
    """
    project = load_project(recovery_path(project_path))
    project.extra.pop("recovery", None)
    project.revision = 1
    return project
