"""Project files in the window: new, open, save, save as, recent files, the unsaved-changes
prompt (driven by ``QUndoStack.isClean``), crash recovery, relocating missing files.

Crash recovery is the edit journal (:class:`prismstation.io.recovery.Journal`): every edit of
the project is journaled atomically to ``<project>.recovery`` as it happens (for a project never
saved, ``untitled.prismproj.recovery`` in the settings directory). The project is serialised
when the window is idle again (:attr:`.journal.WindowJournal.IDLE_MS` after the edit) and the disk write
(fsync) runs on the journal's writer thread, so a crash or ``kill -9`` loses at most the edits
of the last 40 ms and of the write in flight, never an earlier one.
Saving, discarding or undoing back to the saved state clears the journal (cancelling what is
pending first); closing, saving as and opening a project flush it. Opening a project with a
journal (or starting with an untitled one) offers to recover it — unless another window holds
the project (:class:`~prismstation.io.lock.ProjectLock`, ``<project>.lock``: that journal
is the other window's, not a crash's). A second window on this host does not open a project
another one has open; a lock from another host (a shared folder) is asked about. An untitled
project whose usual journal another window writes gets a journal of its own
(``untitled-<pid>.prismproj.recovery``); the next start offers the newest one no live window
holds. Write errors of the thread
reach the status bar through a queued signal (:attr:`ProjectFiles.message` in the GUI thread).

Dialogs go through small methods (:meth:`ProjectFiles.ask`, :meth:`ProjectFiles.choose_open`, ...)
so that tests can answer them.
"""
from __future__ import annotations

import os
from pathlib import Path

from PySide6.QtCore import QObject, Signal, Slot
from PySide6.QtWidgets import QFileDialog, QMessageBox

from prismstation.errors import InputError, PrismError, WriteError
from prismstation.gui import settings as st
from prismstation.gui import workers
from prismstation.gui.journal import (WindowJournal, autosave_path, untitled_journals,  # noqa: F401
                                      untitled_path)
from prismstation.io.project import SUFFIX, apply_relocations, load_project, save_project
from prismstation.ops.fit import orientation_record
from prismstation.io.lock import ProjectLock, describe_holder
from prismstation.io.recovery import Journal
from prismstation.io.scene import read_scene
from prismstation.model.project import Project, default_geoid
from prismstation.gui.plain import plain

FILTER = f"prismstation projects (*{SUFFIX});;All files (*)"


def missing_images(project) -> list[str]:
    """Views whose image file does not exist."""
    return [n for n, v in project.scene.views.items() if not v.image or not Path(v.image).is_file()]


class ProjectFiles(QObject):
    """Owns the current project's path and its life cycle in the window.

    Signals
    -------
    project_opened(project)
        A project was created, opened or recovered (the window rebinds everything).
    path_changed(str)
        The file name changed (save as).
    message(str)
        Something to show in the status bar.
    """

    project_opened = Signal(object)
    path_changed = Signal(str)
    message = Signal(str)
    recent_changed = Signal(list)

    #: the window's current fit (a callable → Solution or None; the workspace sets it): a save
    #: stores its result with the project, as ``prismstation fit`` does
    current_solution = None

    def __init__(self, undo_stack, parent_widget=None):
        super().__init__(parent_widget)
        self.stack = undo_stack
        self.widget = parent_widget
        self.project: Project | None = None
        self.path: Path | None = None
        self.journal: Journal | None = None
        self.lock: ProjectLock | None = None
        self.untitled = untitled_path()  # where an untitled project's journal goes (see module doc)
        self.interactive = True  # False: every question is answered "No" (screenshots, scripts)
        undo_stack.cleanChanged.connect(self._on_clean_changed)
        workers.relay()  # the journal's writer thread reports through it

    # ------------------------------------------------------------------ dialogs (overridable)
    def ask(self, title: str, text: str, buttons=None, default=None):
        b = QMessageBox.StandardButton
        if not self.interactive:
            return b.No
        buttons = buttons or (b.Yes | b.No)
        return QMessageBox.question(self.widget, title, plain(text), buttons, default or b.Yes)

    def warn(self, title: str, text: str) -> None:
        self.message.emit(f"{title}: {text}")
        if not self.interactive:
            import sys
            print(f"{title}: {text}", file=sys.stderr)
            return
        QMessageBox.warning(self.widget, title, plain(text))

    def choose_open(self, title=None, filt=FILTER) -> str:
        path, _ = QFileDialog.getOpenFileName(self.widget, title or "Open project",
                                              st.value(st.Key.LAST_PROJECT_DIR), filt)
        return path

    def choose_save(self) -> str:
        path, _ = QFileDialog.getSaveFileName(self.widget, "Save project as",
                                              st.value(st.Key.LAST_PROJECT_DIR), FILTER)
        if path and not path.endswith(SUFFIX):
            path += SUFFIX
        return path

    def choose_dir(self, title: str) -> str:
        return QFileDialog.getExistingDirectory(self.widget, title, st.value(st.Key.LAST_PROJECT_DIR))

    # ------------------------------------------------------------------ life cycle
    def _target(self) -> Path:
        """The project file the journal and the lock are named after."""
        return self.path or self.untitled

    def _take_lock(self) -> None:
        if self.lock is not None:
            self.lock.release()
        self.lock = ProjectLock(self._target())
        self.lock.acquire()

    def _install(self, project: Project, path) -> None:
        if self.journal is not None:
            self.journal.close()
        self.project = project
        self.path = None if path is None else Path(path).resolve()
        if self.path is None:  # another window's untitled journal is not this one's
            base = untitled_path()
            self.untitled = base if ProjectLock(base).holder() is None else \
                base.with_name(f"untitled-{os.getpid()}{SUFFIX}")
        self._take_lock()
        self.journal = WindowJournal(project, self._target(), self._journal_report)
        self.stack.clear()
        self.stack.setClean()
        self.project_opened.emit(project)
        self.path_changed.emit("" if self.path is None else str(self.path))

    def new_project(self, scene_path: str | None = None) -> bool:
        """A project on ``scene_path`` (asked for when None), untitled until saved."""
        if not self.maybe_save():
            return False
        scene_path = scene_path or self.choose_open("Scene of the new project", "Scene (*.json);;All files (*)")
        if not scene_path:
            return False
        try:
            scene = read_scene(scene_path)
        except PrismError as exc:
            self.warn("New project", str(exc))
            return False
        self._install(Project(scene, str(Path(scene_path).resolve()), geoid=default_geoid(scene)), None)
        self.message.emit(f"New project on {scene_path}")
        return True

    def open_project(self, path: str | None = None, *, recover: bool | None = None,
                     check_unsaved: bool = True) -> bool:
        """Open ``path`` (asked for when None). ``recover``: use a newer autosave (None asks)."""
        if check_unsaved and not self.maybe_save():
            return False
        path = path or self.choose_open()
        if not path:
            return False
        path = Path(path)
        if not self._may_open(path):
            return False
        self.flush_journal()  # reopening this project: its journal must be complete on disk
        side = autosave_path(path)
        source = path
        if side.is_file() and (not path.exists() or side.stat().st_mtime >= path.stat().st_mtime):
            if recover is None:
                b = QMessageBox.StandardButton
                recover = self.ask("Recover", f"{path.name} has edits that were not saved (the program "
                                   "did not close cleanly). Recover them?") == b.Yes
            if recover:
                source = side
        project = self._load(source, "Open project")
        if project is None:
            return False
        self._install(project, path)
        if source is side:
            self._recovered()
            self.message.emit(f"Recovered the unsaved edits of {path.name}; save to keep them")
        else:
            self.message.emit(f"Opened {path}")
        st.add_recent(str(path))
        st.set_value(st.Key.LAST_PROJECT_DIR, str(path.parent))
        self.recent_changed.emit(st.value(st.Key.RECENT_FILES))
        return True

    def _may_open(self, path: Path) -> bool:
        """False when another window has ``path`` open (said in a message); a lock of another
        host, which cannot be checked, is asked about."""
        holder = ProjectLock(path).holder()
        if holder is None:
            return True
        import socket
        who = describe_holder(holder)
        if holder.get("host") == socket.gethostname():
            self.warn("Open project", f"{path.name} is open in another prismstation window ({who}). "
                      "Work on it there, or close it there first: two windows would overwrite "
                      "each other's edits.")
            return False
        b = QMessageBox.StandardButton
        return self.ask("Open project", f"{path.name} is marked as open by prismstation on another "
                        f"computer ({who}). Open it here anyway? Only if that program no longer "
                        "runs: two windows would overwrite each other's edits.", b.Yes | b.No, b.No) == b.Yes

    def _load(self, path: Path, title: str) -> Project | None:
        """Load, offering to relocate a missing scene or missing images; None when the operator
        gives up or the file is bad (said in a message box titled ``title``)."""
        try:
            try:
                project = load_project(path)
            except InputError as exc:
                if "scene file not found" not in str(exc):
                    raise
                b = QMessageBox.StandardButton
                if self.ask("Scene not found", f"{exc}\n\nLocate the scene.json?") != b.Yes:
                    return None
                scene = self.choose_open("Locate the scene", "Scene (*.json);;All files (*)")
                if not scene:
                    return None
                project = load_project(path, scene_override=scene)
        except PrismError as exc:
            self.warn(title, str(exc))
            return None
        missing = missing_images(project)  # (relocations recorded earlier: applied by the load)
        if missing:
            self.relocate_images(project, missing)
        return project

    def recover_untitled(self, recover: bool | None = None) -> bool:
        """Offer the journal of a never-saved project left by a crash; True when recovered."""
        self.flush_journal()
        found = untitled_journals()
        if not found:
            return False
        side = found[0]
        if recover is None:
            b = QMessageBox.StandardButton
            recover = self.ask("Recover", "An unsaved, untitled project was being edited when the "
                               "program stopped. Recover it?") == b.Yes
        if not recover:
            return False
        project = self._load(side, "Recover")
        if project is None:
            return False
        self._install(project, None)
        self._recovered()
        if side != autosave_path(self.untitled):  # journaled again under this window's name
            side.unlink(missing_ok=True)
        self.message.emit("Recovered the untitled project; save it to keep it")
        return True

    def _recovered(self) -> None:
        """The project just installed came from a journal: unsaved, and journaled again at once
        (so a second crash before the next edit still finds it)."""
        self.stack.resetClean()
        self.journal.write()

    def relocate_images(self, project, missing: list[str]) -> bool:
        """Ask for a folder holding the missing images (same file names); record where they are."""
        names = ", ".join(f"{v} ({Path(project.scene.views[v].image or '?').name})" for v in missing)
        b = QMessageBox.StandardButton
        if self.ask("Images not found", f"Image files not found for view(s) {names}.\n\n"
                    "Choose the folder that holds them now?") != b.Yes:
            return False
        folder = self.choose_dir("Folder with the images")
        if not folder:
            return False
        reloc = dict(project.relocations)
        for v in missing:
            cand = Path(folder) / Path(project.scene.views[v].image or "").name
            if cand.is_file():
                reloc[v] = str(cand.resolve())
        project.set_relocations(reloc)
        apply_relocations(project)
        still = missing_images(project)
        if still:
            self.warn("Images not found", f"Still missing: {', '.join(still)}")
        return not still

    def save(self) -> bool:
        if self.project is None:
            return False
        if self.path is None:
            return self.save_as()
        sol = self.current_solution() if self.current_solution is not None else None
        if sol is not None and sol.revision == self.project.revision:
            record = orientation_record(self.project, sol)  # the fit's result, as `fit` stores it
            if record is not None:
                self.project.set_orientation(record)
        try:
            save_project(self.project, self.path)
        except (PrismError, OSError) as exc:
            named = isinstance(exc, WriteError) and exc.file == str(self.path)  # no path twice
            self.warn("Save", f"Could not save {exc}" if named else f"Could not save {self.path}: {exc}")
            return False
        self.stack.setClean()
        self._remove_autosave()
        self.message.emit(f"Saved {self.path}")
        return True

    def save_as(self, path: str | None = None) -> bool:
        if self.project is None:
            return False
        path = path or self.choose_save()
        if not path:
            return False
        self.flush_journal()  # nothing pending may land on the old name after it is removed
        old_path, old_side = self.path, autosave_path(self._target())
        self.path = Path(path).resolve()
        if not self._may_open(self.path):
            self.path = old_path
            return False
        self._scene_beside(self.path)
        self.journal.path = self.path
        if self.save():
            self._take_lock()
            if old_side.exists():
                old_side.unlink()
            st.add_recent(str(self.path))
            st.set_value(st.Key.LAST_PROJECT_DIR, str(self.path.parent))
            self.recent_changed.emit(st.value(st.Key.RECENT_FILES))
            self.path_changed.emit(str(self.path))
            return True
        self.path = old_path
        self.journal.path = self._target()
        return False

    def _scene_beside(self, path: Path) -> None:
        """A project made from a product keeps its scene.json in the settings directory until
        it is saved: then the scene is written beside the project (unless one is there)."""
        product = self.project.product
        scene = Path(self.project.scene_path or "")
        if not product or untitled_path().parent not in scene.parents:
            return
        target = path.parent / "scene.json"
        if target.exists():
            return
        from prismstation.io.products import write_scene_for_product  # start-up: the CEOS reader, 0.1 s
        try:
            self.project.scene_path = str(write_scene_for_product(product, path.parent).resolve())
        except (PrismError, OSError) as exc:
            self.message.emit(f"The scene stays in {scene.parent}: {exc}")

    def new_project_from_product(self, product: str | None = None) -> bool:
        """A new, untitled project on a JAXA product folder (CEOS or GeoTIFF 1B2, a triplet or
        one view): its scene.json is written from the product (:mod:`prismstation.io.products`)."""
        if not self.maybe_save():
            return False
        product = product or self.choose_dir("JAXA PRISM product folder")
        if not product:
            return False
        from prismstation.io.products import write_scene_for_product  # start-up: the CEOS reader, 0.1 s
        product = Path(product).resolve()
        staging = untitled_path().parent / "products" / product.name
        try:
            scene_path = write_scene_for_product(product, staging)
            scene = read_scene(scene_path)
        except (PrismError, OSError) as exc:
            self.warn("New project from product", str(exc))
            return False
        project = Project(scene, str(scene_path.resolve()), product=str(product), geoid=default_geoid(scene))
        self._install(project, None)
        self.message.emit(f"New project on the product {product.name} ({', '.join(scene.views)}); "
                          "Save as… to keep it")
        return True

    def maybe_save(self) -> bool:
        """The unsaved-changes prompt; True when it is fine to go on (saved or discarded)."""
        if self.project is None or self.stack.isClean():
            return True
        b = QMessageBox.StandardButton
        name = self.path.name if self.path else "The untitled project"
        answer = self.ask("Unsaved changes", f"{name} has unsaved changes. Save them?",
                          b.Save | b.Discard | b.Cancel, b.Save)
        if answer == b.Save:
            return self.save()
        if answer == b.Discard:
            self._remove_autosave()
            return True
        return False

    def close(self) -> None:
        """The window closes (after :meth:`maybe_save`)."""
        if self.stack.isClean():
            self._remove_autosave()
        if self.journal is not None:
            self.journal.close()
            self.journal = None
        if self.lock is not None:
            self.lock.release()
            self.lock = None

    # ------------------------------------------------------------------ journal
    def autosave(self) -> bool:
        """Write the journal now if there are unsaved changes (edits journal themselves; this is
        for callers that want it on disk at a given moment). True when the journal holds them."""
        if self.project is None or self.journal is None or self.stack.isClean():
            return False
        self.journal.write()
        self.journal.flush()
        return autosave_path(self._target()).is_file()

    def flush_journal(self, timeout: float | None = None) -> bool:
        """Wait until every edit journaled so far is on disk (False: ``timeout`` s ran out)."""
        return True if self.journal is None else self.journal.flush(timeout)

    @Slot(str)
    def _journal_report(self, text: str) -> None:  # any thread
        workers.post(self._on_journal_message, text)

    def _on_journal_message(self, text: str) -> None:
        self.message.emit(text)

    def _on_clean_changed(self, clean: bool) -> None:
        # undone back to the saved state: nothing to recover (only a journal this session wrote)
        if clean and self.journal is not None and (self.journal.submitted or self.journal.armed):
            self._remove_autosave()

    def _remove_autosave(self) -> None:
        # through the journal: a pending write is dropped and the one in flight (a few ms) is
        # waited for, so that no late write brings the file back
        if self.journal is not None and self.journal.path == self._target():
            self.journal.discard()  # drops a pending write, waits for the one in flight
        side = autosave_path(self._target())
        for f in (side, Path(str(side) + ".bak")):
            if f.exists():
                try:
                    os.unlink(f)
                except OSError:
                    pass
