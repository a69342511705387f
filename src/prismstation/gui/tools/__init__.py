"""Workstation tools beyond measuring (matching, GCP-free orientation, DSMs, rectification…).

Each module of this package (other than ones starting with ``_``) defines ``install(ctx)``,
called once when the main window is built, with a :class:`ToolContext`: the workspace, the
views, a widget to parent dialogs, and ways to add actions, menus entries and docks. A tool
registers itself in ``ctx.tools`` under its name. Modules are discovered, so adding a tool is
adding a module; the main window stays wiring only.
"""
from __future__ import annotations

import importlib
import pkgutil
import weakref

from PySide6.QtCore import Qt
from PySide6.QtGui import QAction
from PySide6.QtWidgets import QDockWidget, QMessageBox

from prismstation.gui.menus import act
from prismstation.gui.tools._worker import running_jobs_of, stop_jobs_of


class ToolContext:
    """What a tool may use of the window.

    Attributes
    ----------
    workspace : Workspace
        Project, current point, undo stack, files, solver (also as the shortcuts below).
    views : TripletViews
    widget : QMainWindow
        The parent of the tool's dialogs and message boxes (its status bar shows messages).
    tools_menu, file_menu : QMenu
    model_panel : ModelPanel
    tools : dict
        The installed tools by name.
    outputs : dict
        The last file a tool wrote, by what it is (``"dsm"``), for another tool to offer.
    """

    def __init__(self, window):
        self.workspace = window.workspace
        self.views = window.views
        self._window = weakref.ref(window)  # the window holds the context: no cycle
        self.tools_menu = window.tools_menu
        self.file_menu = window.menuBar().actions()[0].menu()
        self.open_action = window.a_open
        self.model_panel = window.panel
        self.tools: dict = {}
        self.outputs: dict = {}
        self._docks = window.docks

    @property
    def widget(self):
        return self._window()

    @property
    def interactive(self) -> bool:
        """The window asks questions (False: tests, screenshots)."""
        return bool(getattr(self.widget, "interactive", False))

    # the workspace's parts, for brevity
    project = property(lambda self: self.workspace.project)
    current = property(lambda self: self.workspace.current)
    undo_stack = property(lambda self: self.workspace.undo_stack)
    files = property(lambda self: self.workspace.files)
    solver = property(lambda self: self.workspace.solver)

    def status(self, message: str, ms: int = 0) -> None:
        """Show ``message`` in the window's status bar for ``ms`` milliseconds (0: until the next)."""
        self.widget.statusBar().showMessage(message, ms)

    def add_action(self, text, slot, shortcut=None, tip=None, checkable=False) -> QAction:
        """An action of the window (its shortcut works anywhere in it); not put in a menu."""
        return act(self.widget, text, slot, shortcut, tip=tip, checkable=checkable)

    def add_dock(self, key: str, title: str, widget, area=Qt.DockWidgetArea.RightDockWidgetArea,
                 tabify_with: str | None = None) -> QDockWidget:
        """A dock of the window (listed in its View menu), optionally tabbed with dock
        ``tabify_with`` (e.g. "points"), which stays in front."""
        d = QDockWidget(title, self.widget)
        d.setObjectName(f"dock_{key}")
        d.setWidget(widget)
        self.widget.addDockWidget(area, d)
        self._docks[key] = d
        if tabify_with in self._docks:
            self.widget.tabifyDockWidget(self._docks[tabify_with], d)
            self._docks[tabify_with].raise_()
        return d

    def may_close(self) -> bool:
        """The window is asked to close (X, Ctrl+Q): with a tool's job running, ask whether to
        cancel it and quit (a window that asks nothing — tests, screenshots — says yes). The
        question follows the jobs while it is open: their progress, and when the last one ends
        it closes unanswered — nothing is left to cancel, the window stays and shows the outcome
        (the operator quits again if they still want to)."""
        jobs = [job for job in running_jobs_of(self.widget) if not job.is_cancelled()]  # (cancelled: ending)
        if not jobs or not self.interactive:
            return True
        b = QMessageBox.StandardButton
        box = QMessageBox(QMessageBox.Icon.Question, "Quit", "", b.Yes | b.No, self.widget)
        box.setTextFormat(Qt.TextFormat.PlainText)  # (file names, ids)
        box.setDefaultButton(b.No)
        ended = []

        def say(*_):
            live = [job for job in jobs if job.isRunning() and not job.is_cancelled()]
            if not live:
                ended.append(True)
                box.done(b.No)
                return
            n = len(live)
            box.setText(f"{'A job is' if n == 1 else f'{n} jobs are'} running — "
                        f"{'; '.join(job.describe() for job in live)}.\n\n"
                        f"Cancel {'it' if n == 1 else 'them'} and quit?")
        say()
        for job in jobs:
            job.progress.connect(say)
            job.ended.connect(say)
        try:
            answer = box.exec()
        finally:
            for job in jobs:
                for sig in (job.progress, job.ended):
                    try:
                        sig.disconnect(say)
                    except (RuntimeError, TypeError):  # (a job already gone)
                        pass
            box.deleteLater()
        if ended:
            self.status("The job ended while the quit question was open: nothing was cancelled", 15000)
            return False
        return answer == b.Yes

    def shutdown(self) -> None:
        """Cancel and join the tools' running jobs, then let each tool with a ``shutdown()``
        release what it holds (the window is closing)."""
        stop_jobs_of(self.widget)
        for tool in self.tools.values():
            stop = getattr(tool, "shutdown", None)
            if callable(stop):
                stop()


def install_tools(window) -> ToolContext:
    """Install every tool; their docks start hidden until the operator opens one from the
    Tools or View menu (all shown at once, they made the window taller than a laptop; a tab
    group of hidden docks leaves a stray tab bar on screen, so they are not tabified here)."""
    ctx = ToolContext(window)
    before = set(window.docks)
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if not info.name.startswith("_"):
            mod = importlib.import_module(f"{__name__}.{info.name}")
            mod.install(ctx)
    for k in window.docks:
        if k not in before:
            window.docks[k].hide()
    return ctx
