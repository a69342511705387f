"""The workspace: what the operator works on, apart from any window that shows it.

One :class:`Workspace` owns the project, the current point, the undo stack, the project files
(saves and the recovery journal), the solver and the reference-DEM loader. The main window
shows it; tools reach it through their :class:`~prismstation.gui.tools.ToolContext`.
:meth:`Workspace.close` ends every job that reads the project before the files let it go.

The reference DEM belongs to the project (:attr:`Project.reference_dem`, kept in its file): a
project that names one has it loaded when it opens; a DEM loaded for a project becomes its
reference (an unsaved change); one that cannot be read is a message box, not only a status
line.
"""
from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import QObject, Signal
from PySide6.QtGui import QUndoStack

from prismstation.gui.project_io import ProjectFiles
from prismstation.gui.reference_dem import DemLoader
from prismstation.gui.solver import Solver


class Workspace(QObject):
    """Project, current point, undo stack, files (journal), solver and reference DEM loader.

    Signals
    -------
    project_changed(project)
        Another project is open (the current point is then None).
    current_changed(pid)
        The current point changed (a point id, or None).
    """

    project_changed = Signal(object)
    current_changed = Signal(object)

    def __init__(self, parent_widget=None, threaded_fit: bool = True):
        super().__init__(parent_widget)
        self.project = None
        self.current: str | None = None
        self.undo_stack = QUndoStack(self)
        self.files = ProjectFiles(self.undo_stack, parent_widget)
        self.solver = Solver(self, threaded=threaded_fit)
        self.files.current_solution = lambda: self.solver.solution
        self.dem_loader = DemLoader(self)
        self.dem_loader.loaded.connect(self._on_dem_loaded)
        self.dem_loader.failed.connect(lambda m: self.files.warn("Reference DEM", m))

    @property
    def journal(self):
        """The recovery journal of the open project (None without one)."""
        return self.files.journal

    def set_project(self, project) -> None:
        """Make ``project`` the one worked on (no current point); the solver refits it."""
        self.project, self.current = project, None
        self.solver.height_of = None
        self.dem_loader.forget()  # a DEM being read for the previous project is not this one's
        self.project_changed.emit(project)
        self.solver.set_project(project)
        if project.reference_dem:
            self.dem_loader.start(project.reference_dem, project)

    def _on_dem_loaded(self, heights) -> None:
        """A DEM loaded for the project is its reference DEM (saved with it)."""
        p = self.project
        path = str(Path(str(heights.path)).resolve())
        if p is not None and (p.reference_dem is None or str(Path(p.reference_dem).resolve()) != path):
            p.set_reference_dem(path)
            self.undo_stack.resetClean()  # to be saved

    def set_current(self, pid: str | None) -> bool:
        """Make ``pid`` current (None, or a point not in the project: none); True if it changed."""
        if pid is not None and (self.project is None or pid not in self.project.points):
            pid = None
        if pid == self.current:
            return False
        self.current = pid
        self.current_changed.emit(pid)
        return True

    def push(self, command) -> None:
        """Do ``command`` (a QUndoCommand) on the project, undoably."""
        self.undo_stack.push(command)

    def shutdown_jobs(self) -> None:
        """End the jobs that read the project (fit, reference DEM); none starts afterwards."""
        self.solver.shutdown()
        self.dem_loader.close()

    def close(self) -> None:
        """Join the jobs, then close the project's files (journal)."""
        self.shutdown_jobs()
        self.files.close()
