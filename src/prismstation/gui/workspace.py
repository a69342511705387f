"""The workspace: what the operator works on, apart from any window that shows it.

One :class:`Workspace` owns the project, the current point, the undo stack, the project files
(saves and the recovery journal), the solver and the reference-DEM loader. The main window
shows it; tools reach it through their :class:`~prismstation.gui.tools.ToolContext`.
:meth:`Workspace.close` ends every job that reads the project before the files let it go.
"""
from __future__ import annotations

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
        self.dem_loader = DemLoader(self)

    @property
    def journal(self):
        """The recovery journal of the open project (None without one)."""
        return self.files.journal

    def set_project(self, project) -> None:
        """Make ``project`` the one worked on (no current point); the solver refits it."""
        self.project, self.current = project, None
        self.solver.height_of = None
        self.project_changed.emit(project)
        self.solver.set_project(project)

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
