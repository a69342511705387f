"""The main window: wiring only (views, table, model panel, plots, files, undo, solver).

Data flow for one click (docs/architecture.md): a gesture in :class:`TripletViews` becomes a
command pushed on the one ``QUndoStack``; the command edits the Project; the :class:`Solver`
refits and publishes a Solution; views, table, model panel, plots and the accuracy strip read
it. Actions and menus are built in :mod:`.menus`; without a project the central area is the
:class:`~.start_page.StartPage`.
"""
from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import Qt, QTimer
from PySide6.QtWidgets import (QDockWidget, QHBoxLayout, QMainWindow, QMessageBox,
                               QStackedWidget, QTabWidget, QVBoxLayout, QWidget)

from prismstation import __version__
from prismstation.errors import PrismError
from prismstation.gui import commands as cmd
from prismstation.gui import io_actions, menus, reference_dem, window_layout
from prismstation.gui.accuracy_strip import AccuracyStrip
from prismstation.gui.tools import install_tools
from prismstation.gui import settings as st
from prismstation.gui.contrast import ContrastPanel
from prismstation.gui.guide import show_guide
from prismstation.gui.linked_nav import LinkedNavigation
from prismstation.gui.loupe import Loupe
from prismstation.gui.measure_mode import MeasureMode
from prismstation.gui.memory import MemoryKeeper, one_dask_pool
from prismstation.gui.model_panel import ModelPanel
from prismstation.gui.overviews import offer_overviews
from prismstation.gui.plots import PlotsWidget
from prismstation.gui.point_editor import PointEditor
from prismstation.gui.point_table import PointTableModel
from prismstation.gui.point_table_view import PointTableView
from prismstation.gui.start_page import StartPage
from prismstation.gui.status_fields import StatusFields
from prismstation.gui.tools._worker import run_with_progress, running_jobs_of
from prismstation.gui.views import TripletViews
from prismstation.gui.workspace import Workspace


class MainWindow(QMainWindow):
    """The measurement workstation. ``interactive=False`` (tests, screenshots) never offers to
    build overviews. ``demo_maker(progress)``: makes the demo project (first use) and returns
    its path; the start page offers the demo when it is given."""

    def __init__(self, interactive: bool = True, threaded_fit: bool = True, demo_maker=None):
        super().__init__()
        self.setObjectName("MainWindow")
        self.setWindowTitle("prismstation")
        self.interactive = interactive
        # first: its heap setting holds for threads made from now on
        self.memory = MemoryKeeper(self, busy=lambda: bool(running_jobs_of(self)))
        self.workspace = ws = Workspace(self, threaded_fit)
        self.undo_stack, self.files, self.solver, self.dem_loader = (
            ws.undo_stack, ws.files, ws.solver, ws.dem_loader)
        self.views = TripletViews(self)
        self.linked_nav = LinkedNavigation(self.views, self)
        self.accuracy = AccuracyStrip(st.value(st.Key.RESIDUAL_SCALE))
        self.exaggeration = self.accuracy.exaggeration  # the one residual-exaggeration control
        work = QWidget()
        lay = QVBoxLayout(work)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.setSpacing(0)
        lay.addWidget(self.accuracy)
        lay.addWidget(self.views, 1)
        self.start_page = StartPage()
        self.demo_maker = demo_maker  # callable(progress) -> the demo project's path
        self.central = QStackedWidget()
        self.central.addWidget(self.start_page)
        self.central.addWidget(work)
        self.setCentralWidget(self.central)
        self.table_model = PointTableModel(self)
        self.table = PointTableView(self.table_model)
        self.panel = ModelPanel()
        self.loupes = {}
        self.loupe_box = QWidget()
        QHBoxLayout(self.loupe_box).setContentsMargins(2, 2, 2, 2)
        self.contrast_tabs = QTabWidget()
        self.contrast_tabs.setDocumentMode(True)  # a slim tab bar: the dock is short
        self.plots = PlotsWidget(own_exaggeration=False)
        self.docks = {}
        self._dock("points", "Points", self.table, Qt.DockWidgetArea.BottomDockWidgetArea)
        self._dock("model", "Model", self.panel, Qt.DockWidgetArea.RightDockWidgetArea)
        self._dock("plots", "Plots", self.plots, Qt.DockWidgetArea.BottomDockWidgetArea)
        self._dock("loupe", "Loupe", self.loupe_box, Qt.DockWidgetArea.RightDockWidgetArea)
        self._dock("contrast", "Contrast", self.contrast_tabs, Qt.DockWidgetArea.RightDockWidgetArea,
                   scroll=True)
        self.tabifyDockWidget(self.docks["loupe"], self.docks["contrast"])
        self.docks["loupe"].raise_()
        self.splitDockWidget(self.docks["points"], self.docks["plots"], Qt.Orientation.Horizontal)
        own_docks = set(self.docks)
        self.status = StatusFields(self)
        menus.build_actions(self)
        menus.build_menus(self)
        self._fill_recent(st.value(st.Key.RECENT_FILES))
        menus.build_toolbar(self)
        self._connect()
        self.measure_mode = MeasureMode(self)
        self.point_editor = PointEditor(self)
        self.tool_context = install_tools(self)
        self.tools = self.tool_context.tools
        for k, d in self.docks.items():  # a panel opened never makes the window grow
            if k not in own_docks:
                d.setWidget(window_layout.scrolled(d.widget()))
                window_layout.tab_when_shown(self, d)  # ... nor squeeze the model panel
        menus.fill_panels_menu(self)
        self._work_state = None  # the docks' state while the start page is up
        if interactive:
            self.views.offer_overviews = self._offer_overviews
        self._measured_timer = QTimer(self)
        self._measured_timer.setSingleShot(True)
        self._measured_timer.setInterval(0)
        self._measured_timer.timeout.connect(self.views.refresh_measured)
        self.restore_layout()
        self._update_actions()

    # ------------------------------------------------------------------ construction
    def _dock(self, key, title, widget, area, scroll=False) -> QDockWidget:
        d = QDockWidget(title, self)
        d.setObjectName(f"dock_{key}")
        d.setWidget(window_layout.scrolled(widget) if scroll else widget)
        self.addDockWidget(area, d)
        self.docks[key] = d
        return d

    def _connect(self) -> None:
        self.files.project_opened.connect(self.set_project)
        self.files.path_changed.connect(self._update_title)
        self.files.message.connect(lambda m: self.statusBar().showMessage(m, 8000))
        self.files.recent_changed.connect(self._fill_recent)
        self.undo_stack.cleanChanged.connect(self._on_clean_changed)
        self.undo_stack.indexChanged.connect(self._on_edit)
        self.solver.solution_changed.connect(self.on_solution)
        self.solver.failed.connect(lambda m: self.statusBar().showMessage(m, 10000))
        self.views.place_requested.connect(self.place)
        self.views.move_requested.connect(self.move)
        self.views.point_picked.connect(self._on_marker_picked)
        self.views.cursor_info.connect(self.on_cursor)
        self.views.message.connect(lambda m: self.statusBar().showMessage(m, 10000))
        self.views.images_loaded.connect(self._on_images_loaded)
        self.table.selectionModel().selectionChanged.connect(self._on_table_selection)
        self.table.setContextMenuPolicy(Qt.ContextMenuPolicy.ActionsContextMenu)
        self.table.addActions([self.a_goto, *self.a_kind.values(), self.a_del_point])
        self.panel.settings_requested.connect(self.change_settings)
        self.accuracy.exaggeration_changed.connect(self._on_exaggeration)
        sp = self.start_page
        sp.open_requested.connect(lambda: self.files.open_project())
        sp.scene_requested.connect(lambda: self.files.new_project())
        sp.product_requested.connect(lambda: self.files.new_project_from_product())
        sp.recent_requested.connect(lambda f: self.files.open_project(f))
        sp.guide_requested.connect(self.show_guide)
        sp.demo_requested.connect(self.open_demo)
        self.dem_loader.loaded.connect(self._on_dem)
        self.dem_loader.failed.connect(lambda m: self.statusBar().showMessage(f"Reference DEM: {m}", 10000))
        self.plots.point_clicked.connect(lambda pid: self.set_current(pid, drive=True))

    # ------------------------------------------------------------------ project
    def open_project(self, path, **kw) -> bool:
        return self.files.open_project(str(path), **kw)

    @property
    def project(self):
        return self.workspace.project

    @property
    def current(self) -> str | None:
        return self.workspace.current

    def set_project(self, project) -> None:
        if self.project is not None:
            self.project.changed.disconnect(self._on_project_changed)
        self.workspace.set_project(project)
        one_dask_pool()
        project.changed.connect(self._on_project_changed)
        self.views.height_of = None
        self.views.set_project(project)
        self.status.set_views(project.scene.views)
        self.panel.set_sensor(project.scene.sensor, list(project.scene.views))
        self.plots.show_parallax(bool(project.scene.sensor.parallax_models))
        self.status.clear()
        split = st.value(st.Key.SPLITTER)
        if split is not None and not split.isEmpty():
            self.views.splitter.restoreState(split)
        self._on_exaggeration(self.exaggeration.value())
        self.views.set_show_labels(self.a_labels.isChecked())
        self.table_model.set_project(project)
        self.panel.set_settings(project.settings)
        self._bind_image_tools()
        self._show_start(False)
        self._update_actions()

    def _bind_image_tools(self) -> None:
        lay = self.loupe_box.layout()
        while lay.count():
            w = lay.takeAt(0).widget()
            if w is not None:
                w.deleteLater()
        for i in range(self.contrast_tabs.count()):  # clear() keeps the pages alive: a leak
            self.contrast_tabs.widget(i).deleteLater()
        self.contrast_tabs.clear()
        self.loupes = {}
        for name, iv in self.views.views.items():
            lp = Loupe(zoom=6, pixels=25, label=name)
            lp.attach(iv)
            lay.addWidget(lp)
            self.loupes[name] = lp
            self.contrast_tabs.addTab(ContrastPanel(iv), name)

    def _on_images_loaded(self) -> None:
        for i in range(self.contrast_tabs.count()):
            self.contrast_tabs.widget(i).refresh()

    def _on_project_changed(self, change) -> None:
        self._measured_timer.start()
        if self.current is not None and self.current not in self.project.points:
            self.set_current(None)  # undone or deleted: no current point that does not exist

    def _on_edit(self, *_) -> None:
        """An edit (or its undo, redo) went through: a message about an earlier one (a refused
        value, a failed fit) no longer holds."""
        self.statusBar().clearMessage()
        self._update_actions()

    def _on_clean_changed(self, clean: bool) -> None:
        self.setWindowModified(not clean)

    def _update_title(self, path: str) -> None:
        name = Path(path).name if path else "untitled"
        self.setWindowTitle(f"{name}[*] — prismstation")
        self.setWindowModified(not self.undo_stack.isClean())

    def _fill_recent(self, files) -> None:
        self.recent_menu.clear()
        for f in files:
            self.recent_menu.addAction(f, lambda f=f: self.files.open_project(f))
        self.recent_menu.setEnabled(bool(files))
        self.start_page.set_recent(files)

    # ------------------------------------------------------------------ solution
    def on_solution(self, sol) -> None:
        self.views.set_solution(sol)
        self.table_model.set_solution(sol)
        self.table.select_id(self.current)
        self.panel.set_solution(sol)
        self.plots.set_solution(sol)
        self.accuracy.set_solution(sol)
        self.status_fit.setText(f"fit {self.solver.last_fit_ms:.0f} ms · σ0 "
                                + (f"{sol.bias[sol.reference_view].sigma0:.3f}"
                                   if sol.bias[sol.reference_view].sigma0 is not None else "—"))
        self._update_actions()

    # ------------------------------------------------------------------ current point
    def set_current(self, pid: str | None, drive: bool = True) -> None:
        changed = self.workspace.set_current(pid)
        pid = self.current
        self.views.set_current(pid)
        self.table.select_id(pid)
        for v, lp in self.loupes.items():
            xy = None if pid is None else self.views.point_position(pid, v)
            if xy is not None and self.views.views[v].source is not None:
                lp.set_position(*xy)
        if pid is not None and drive and changed:
            self.views.drive_to(pid)
        self._update_actions()

    def _on_marker_picked(self, pid: str) -> None:
        """A click on another point's marker makes it current. The click was meant to place
        the point just made by Insert, if that is current and still empty: it is dropped."""
        left = self.current
        self.set_current(pid, drive=False)
        if left is not None and left != self.current:
            self._drop_if_abandoned(left)

    def _drop_if_abandoned(self, pid: str) -> None:
        """Undo the creation of ``pid`` if it was the last edit (Insert) and the point is still
        as made: no measurement, no coordinates, its id."""
        st = self.undo_stack
        top = st.command(st.index() - 1) if st.index() == st.count() and st.index() > 0 else None
        p = self.project
        if (isinstance(top, cmd.AddPoint) and top.pid == pid and pid in p.points
                and p.points[pid] == top.point and not p.measurements_of(pid)):
            st.undo()

    def _on_table_selection(self, *_) -> None:
        pid = self.table.current_id()
        if pid is not None and pid != self.current:
            self.set_current(pid, drive=True)

    def drive_to_current(self) -> None:
        if self.current is not None:
            self.views.drive_to(self.current)

    def step_point(self, step: int) -> None:
        ids = self.table.ordered_ids()
        if not ids:
            return
        i = ids.index(self.current) + step if self.current in ids else (0 if step > 0 else -1)
        self.set_current(ids[i % len(ids)], drive=True)
        self.views.drive_to(self.current)

    # ------------------------------------------------------------------ edits
    def place(self, view: str, x: float, y: float) -> None:
        if self.project is None:
            return
        pid = self.measure_mode.target(view, x, y)  # None: this mode places nothing (it says why)
        if pid is None:
            return
        c = cmd.PlaceMeasurement(self.project, pid, view, x, y)
        self.undo_stack.push(c)
        if c.pid != self.current:
            self.set_current(c.pid, drive=False)
        self.measure_mode.placed(c.pid)
        self._first_frame(view, c)

    def move(self, pid: str, view: str, x: float, y: float, finished: bool) -> None:
        if self.project is not None and pid in self.project.points:
            c = cmd.PlaceMeasurement(self.project, pid, view, x, y, merge=True)
            self.undo_stack.push(c)
            if pid != self.current:
                self.set_current(pid, drive=False)
            self._first_frame(view, c)

    def _first_frame(self, view: str, c) -> None:
        """Answer a click (or a drag's step) in the next frame: the marker, its label, the loupe
        and the table's row painted now; the refit, which the solver starts from the event loop
        once this returns, repaints what it changes in the frame after."""
        xy = (c.new.x, c.new.y)
        self.table_model.refresh()  # the row's views (its residuals follow the refit)
        lp = self.loupes.get(view)
        if lp is not None:
            lp.set_position(*xy)
        self.views.paint_edit(view, [xy] + ([(c.old.x, c.old.y)] if c.old is not None else []))

    def new_point(self) -> None:
        if self.project is None:
            return
        c = cmd.AddPoint(self.project)
        self.undo_stack.push(c)
        self.set_current(c.pid, drive=False)
        self.statusBar().showMessage(f"{c.pid}: click in each view to place it", 8000)

    def delete_point(self) -> None:
        if self.project is not None and self.current in self.project.points:
            self.undo_stack.push(cmd.DeletePoint(self.project, self.current))
            self.set_current(None)

    def delete_measurement(self) -> None:
        v = self.views.active_view
        if self.project is not None and self.current and v and self.project.measurement(self.current, v):
            self.undo_stack.push(cmd.DeleteMeasurement(self.project, self.current, v))

    def set_kind(self, kind: str) -> None:
        if self.project is None or self.current not in self.project.points:
            return
        if self.project.points[self.current].kind == kind:
            return
        try:
            self.undo_stack.push(cmd.SetKind(self.project, self.current, kind))
        except PrismError as exc:
            self.statusBar().showMessage(str(exc), 8000)

    def change_settings(self, settings) -> None:
        if self.project is not None and settings != self.project.settings:
            self.undo_stack.push(cmd.ChangeSettings(self.project, settings))

    def choose_reference_dem(self) -> None:
        from PySide6.QtWidgets import QFileDialog
        path, _ = QFileDialog.getOpenFileName(self, "Reference DEM", st.value(st.Key.LAST_IMPORT_DIR),
                                              "DEM (*.tif *.tiff *.hgt);;All files (*)")
        if path:
            self.load_reference_dem(path)

    def load_reference_dem(self, path, wait: bool = False) -> None:
        """Read a DEM in a worker; then it gives the linked cursor and unparallaxed points
        their heights. ``wait``: block until it is loaded (scripts, tests)."""
        if self.project is None:
            return
        self.statusBar().showMessage(f"Reading the reference DEM {path}…")
        self.dem_loader.start(str(path), self.project)
        if wait:
            self.dem_loader.wait()
            from PySide6.QtCore import QCoreApplication
            QCoreApplication.processEvents()

    def _on_dem(self, heights) -> None:
        self.views.height_of = heights
        self.solver.set_height_of(heights)
        self.statusBar().showMessage(reference_dem.describe(heights), 8000)

    def _on_exaggeration(self, k) -> None:
        self.views.set_exaggeration(k)
        self.plots.set_exaggeration(k)
        st.set_value(st.Key.RESIDUAL_SCALE, float(k))

    def _update_actions(self) -> None:
        has_p = self.project is not None
        has_c = has_p and self.current in (self.project.points if has_p else {})
        for a in (self.a_save, self.a_save_as, self.a_import, self.a_export, self.a_new_point,
                  self.a_next, self.a_prev, self.a_fit, self.a_zoom_in, self.a_zoom_out):
            a.setEnabled(has_p)
        for a in [self.a_del_point, self.a_del_meas, self.a_goto] + list(self.a_kind.values()):
            a.setEnabled(bool(has_c))

    # ------------------------------------------------------------------ cursor and status
    def on_cursor(self, view, x, y, linked, ground) -> None:
        pos = dict(linked)
        pos[view] = (x, y)
        self.status.show_cursor(pos, ground)
        for v, xy in pos.items():
            if v != view and v in self.loupes:
                self.loupes[v].set_position(*xy)

    # the status bar's fields (tests, tools)
    status_xy = property(lambda self: self.status.xy)
    status_ground = property(lambda self: self.status.ground)
    status_fit = property(lambda self: self.status.fit)

    # ------------------------------------------------------------------ import / export
    def import_points(self) -> None:
        io_actions.import_points(self)

    def push_import(self, points, ms) -> None:
        """Add imported points and measurements as one undoable step."""
        io_actions.push_import(self, points, ms)

    def export_report(self, path: str | None = None) -> bool:
        return io_actions.export_report(self, path)

    # ------------------------------------------------------------------ misc
    def _offer_overviews(self, source) -> None:
        offer_overviews(self, source)

    def open_demo(self) -> None:
        """Make the demo project on first use (in a worker, with progress), then open it."""
        if self.demo_maker is None or not self.files.maybe_save():
            return
        def opened(path) -> None:
            if self.files.open_project(str(path), check_unsaved=False):
                dem = Path(path).parent / "triplet" / "srtm.tif"  # the demo's reference DEM (cli/demo.py)
                if dem.is_file():
                    self.load_reference_dem(dem)
        run_with_progress(self, "Making the demo project", lambda progress: self.demo_maker(progress=progress),
                          opened)

    def show_guide(self) -> None:
        show_guide(self)

    def about(self) -> None:
        QMessageBox.about(self, "prismstation", f"prismstation {__version__}\n"
                          "Orientation of ALOS-PRISM stereo triplets (empirical model).")

    def restore_layout(self) -> None:
        """The saved docks and geometry, or defaults that fit this screen, with the start page
        up (:func:`.window_layout.restore`)."""
        window_layout.restore(self, st.value(st.Key.GEOMETRY), st.value(st.Key.STATE))

    def default_layout(self) -> None:
        """Dock sizes for a first start (:func:`.window_layout.default_layout`)."""
        window_layout.default_layout(self)

    def _show_start(self, on: bool) -> None:
        window_layout.show_start(self, on)

    def save_layout(self) -> None:
        st.set_value(st.Key.GEOMETRY, self.saveGeometry())
        st.set_value(st.Key.STATE, self._work_state if self._work_state is not None else self.saveState())
        if self.views.views:
            st.set_value(st.Key.SPLITTER, self.views.splitter.saveState())
        st.set_value(st.Key.SHOW_LABELS, self.a_labels.isChecked())

    def closeEvent(self, ev) -> None:
        if not self.tool_context.may_close() or not self.files.maybe_save():
            ev.ignore()
            return
        self.save_layout()
        # every job reading the project or the images ends before they are released
        self.tool_context.shutdown()
        self.workspace.shutdown_jobs()
        self.views.shutdown()
        self.workspace.close()
        super().closeEvent(ev)
