"""Point transfer and automatic tie points.

*Automatic transfer* (Tools, checkable, on by default): when a point is placed in one view and is
measured in no other, it is searched in the other views in a worker
(:func:`prismstation.ops.transfer.transfer`: along the parallax direction around the model's
prediction, correlation in the predicted shape then least-squares matching; the height range
searched and the shape come from the loaded reference DEM, else the mean height — the window
only hands over what it has loaded). The candidates appear as green circles in those views —
each view is driven to its candidate — and in the *Point transfer* dock with their NCC score, σ
(pixels, from the adjustment, checked against empirical scatter) and status (a failed search
says why, in red); the status bar says the same. Enter (or *Accept*) places the found ones, one
undoable step; a click in a view places the point there instead (that candidate is dropped);
Esc (or *Reject*) drops them all. The views go to the candidates at the working zoom (the
source view's, at most one image pixel per screen pixel): a view left at the overview zooms in.

*Transfer this point* (Tools, Ctrl+T): the same search for the current point from a view it is
measured in (N first) to the views it is not — a point measured before automatic transfer was
on, or whose transfer was rejected.

*Transfer every incomplete point* (Tools): the same search for every point measured in some
views and not in all (:mod:`prismstation.ops.transfer_points`, as ``prismstation transfer``
does) in a worker with progress and Cancel; what it found is placed in one undoable step and
a summary (how many each view found, why the rest were not) goes to the status line and,
interactively, to a box.

*Automatic tie points…*: a grid over the N image (the first of other scenes) transferred to
the other views, blunders rejected
(:func:`prismstation.ops.tie_points.find_tie_points`, as ``prismstation ties`` does, with the
reference DEM when one is loaded),
added as new tie points in one undoable step; a summary (how many added, not found and why,
rejected as blunders, the across-track RMS) on the status line and, interactively, in a box.
"""
from __future__ import annotations

import math

import pyqtgraph as pg
import shiboken6
from PySide6.QtCore import Qt
from PySide6.QtGui import QKeySequence
from PySide6.QtWidgets import (QDialog, QDialogButtonBox, QFormLayout, QHBoxLayout, QLabel,
                               QMessageBox, QPushButton, QSpinBox, QTableWidget, QTableWidgetItem,
                               QVBoxLayout, QWidget)

from prismstation.core.models.scene import reference_view
from prismstation.errors import InputError
from prismstation.gui import commands as cmd
from prismstation.gui.tools._worker import Job, run_with_progress
from prismstation.gui.views import DRIVE_TO_MAX_SCALE
from prismstation.gui.plain import plain
from prismstation.io.windows import ImageWindows
from prismstation.model.points import Measurement
from prismstation.ops.tie_points import find_tie_points, tie_point_edits, ties_summary
from prismstation.ops.transfer import search_height, transfer
from prismstation.ops.transfer_points import found_measurements, to_transfer, transfer_points, transfer_summary

CANDIDATE_COLOUR = "#39ff14"


class TransferPanel(QWidget):
    """The candidates of the pending transfer: view, x, y, score, σx, σy, status."""

    HEADERS = ("view", "x px", "y px", "score", "σx px", "σy px", "status")

    def __init__(self, parent=None):
        super().__init__(parent)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(2, 2, 2, 2)
        self.label = QLabel("Place a point in one view: it is searched in the others.")
        self.label.setTextFormat(Qt.TextFormat.PlainText)  # it shows the point's id
        self.label.setWordWrap(True)
        self.table = QTableWidget(0, len(self.HEADERS))
        self.table.setHorizontalHeaderLabels(self.HEADERS)
        self.table.verticalHeader().setVisible(False)
        self.table.setEditTriggers(QTableWidget.EditTrigger.NoEditTriggers)
        self.accept_button = QPushButton("Accept (Enter)")
        self.reject_button = QPushButton("Reject (Esc)")
        row = QHBoxLayout()
        row.addWidget(self.accept_button)
        row.addWidget(self.reject_button)
        row.addStretch(1)
        lay.addWidget(self.label)
        lay.addWidget(self.table, 1)
        lay.addLayout(row)

    def show_candidates(self, pid, cands: dict) -> None:
        self.table.setRowCount(len(cands))
        for i, (v, t) in enumerate(sorted(cands.items())):
            m = t.match
            vals = [v, f"{t.x:.2f}", f"{t.y:.2f}", f"{m.score:.3f}", f"{m.sigma_x:.3f}", f"{m.sigma_y:.3f}", m.status]
            for j, s in enumerate(vals):
                item = QTableWidgetItem(s)
                item.setToolTip(plain(m.reason))   # why a search failed
                self.table.setItem(i, j, item)
        self.table.resizeColumnsToContents()
        ok = [v for v, t in cands.items() if t.ok]
        self.label.setText(f"{pid}: found in {', '.join(sorted(ok)) or 'no other view'}"
                           if pid else "Place a point in one view: it is searched in the others.")
        self.accept_button.setEnabled(bool(ok))
        self.reject_button.setEnabled(bool(cands))


class TransferTool:
    """Automatic transfer of a placed point and automatic tie points (one per window)."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.job = None
        self.summary = ""  # what the last automatic tie points did (ties_summary)
        self.pid = None
        self.source = None
        self.candidates: dict = {}
        self._items = []
        self.panel = TransferPanel()
        ctx.add_dock("transfer", "Point transfer", self.panel, Qt.DockWidgetArea.RightDockWidgetArea)
        self.a_auto = ctx.add_action("Automatic &transfer", None, checkable=True,
                                  tip="Search a point placed in one view in the other views")
        self.a_auto.setChecked(True)
        self.a_accept = ctx.add_action("Accept transferred point", self.accept, [QKeySequence(Qt.Key.Key_Return), QKeySequence(Qt.Key.Key_Enter)],
                                    tip="Place the transferred point in the other views")
        self.a_reject = ctx.add_action("Reject transferred point", self.reject, "Esc")
        self.a_this = ctx.add_action("Transfer t&his point", self.transfer_current, "Ctrl+T",
                                        tip="Search the current point, measured in one view, in the others")
        self.a_all = ctx.add_action("Transfer every &incomplete point", self.start_all,
                                    tip="Search every point measured in some views in the views it is not measured in")
        self.a_ties = ctx.add_action("Automatic tie &points…", self.choose_ties,
                                  tip="A grid of tie points over the N image, found in F and B")
        ctx.tools_menu.addActions([self.a_auto, self.a_this, self.a_accept, self.a_reject, self.a_all])
        ctx.tools_menu.addSeparator()
        ctx.tools_menu.addAction(self.a_ties)
        self.panel.accept_button.clicked.connect(self.accept)
        self.panel.reject_button.clicked.connect(self.reject)
        ctx.views.place_requested.connect(self._on_placed)  # after the window's own place()
        ctx.files.project_opened.connect(lambda *_: self.reject())
        ctx.undo_stack.indexChanged.connect(lambda *_: self._prune())
        ctx.undo_stack.indexChanged.connect(lambda *_: self._update_this())
        ctx.workspace.current_changed.connect(lambda *_: self._update_this())
        self._update()

    # ------------------------------------------------------------------ transfer of one point
    def _on_placed(self, view: str, x: float, y: float) -> None:
        p, pid = self.ctx.project, self.ctx.current
        if not self.a_auto.isChecked() or p is None or pid is None or pid not in p.points:
            return
        measured = [v for v in p.scene.views if p.measurement(pid, v) is not None]
        if measured == [view] and len(p.scene.views) > 1:
            self.start(pid, view, x, y)

    def transfer_current(self):
        """Transfer the current point from a view it is measured in (N where it is, else the
        first in the scene's order) to the views it is not measured in; returns the Job (None when
        there is nothing to transfer)."""
        p, pid = self.ctx.project, self.ctx.current
        if p is None or pid is None or pid not in p.points:
            self.ctx.status("Transfer: choose a point measured in one view first", 8000)
            return None
        measured = [v for v in p.scene.views if p.measurement(pid, v) is not None]
        if not measured or len(measured) == len(p.scene.views):
            self.ctx.status(f"Transfer: {pid} is {'measured in every view' if measured else 'not measured'}", 8000)
            return None
        source = reference_view(measured)  # N where measured, else the first in the scene's order
        m = p.measurement(pid, source)
        return self.start(pid, source, m.x, m.y)

    def prior_height(self, sol, source: str, x: float, y: float) -> tuple[float, float]:
        """``(h, h_range)`` metres searched for a point at ``(x, y)`` of ``source``
        (:func:`prismstation.ops.transfer.search_height` with the loaded reference DEM and the
        σ the predictions measured for it and for the mean height)."""
        preds = self.ctx.views.predictions
        return search_height(sol, source, (x, y), height_of=self.ctx.views.height_of,
                             sigma_dem=preds.sigma_dem, sigma_mean=preds.sigma_mean)

    def start(self, pid: str, source: str, x: float, y: float):
        """Search ``pid`` at image ``(x, y)`` of ``source`` in the other views (worker); returns the Job."""
        sol = self.ctx.solver.solution
        if sol is None or self.ctx.project is None:
            self.ctx.status("Point transfer needs a fitted model", 8000)
            return None
        self.reject()
        scene = self.ctx.project.scene
        height_of, preds = self.ctx.views.height_of, self.ctx.views.predictions
        sigma_dem, sigma_mean = preds.sigma_dem, preds.sigma_mean

        def work(progress):
            with ImageWindows(scene) as im:
                return transfer(sol, im, source, (x, y), height_of=height_of, sigma_dem=sigma_dem,
                                sigma_mean=sigma_mean)

        self.pid, self.source = pid, source
        job = self.job = Job(work, "Point transfer", self.ctx)
        job.result.connect(lambda res, job=job: self._on_result(job, pid, res))
        job.failed.connect(lambda msg: shiboken6.isValid(self.ctx.widget)
                           and self.ctx.status(f"Point transfer: {msg}", 10000))
        self.ctx.status(f"{pid}: searching in the other views…")
        job.start()
        return job

    def _on_result(self, job, pid, res) -> None:
        if not shiboken6.isValid(self.ctx.widget) or not shiboken6.isValid(self.panel):
            return  # the window was closed while the search ran
        if job is not self.job or pid != self.pid or self.ctx.project is None or pid not in self.ctx.project.points:
            return
        self.candidates = {v: t for v, t in res.items() if self.ctx.project.measurement(pid, v) is None}
        parts = [f"{v} {'✓' if t.ok else '✗ ' + t.match.status} NCC {t.match.score:.2f} "
                 f"σ {t.match.sigma_x:.2f}/{t.match.sigma_y:.2f} px" for v, t in sorted(self.candidates.items())]
        self.ctx.status(f"{pid} transferred: " + "; ".join(parts) + " — Enter accepts", 20000)
        self._update()
        self.drive_to_candidates()

    def drive_to_candidates(self) -> None:
        """Centre each view holding a candidate on it at the working zoom — the source view's,
        at most :data:`~prismstation.gui.views.DRIVE_TO_MAX_SCALE` image px per screen px, so
        that a view at the overview zooms in to detail — and the source view on the point when
        it showed it coarser: the operator sees at once what to accept."""
        views = self.ctx.views.views
        src = views.get(self.source)
        scale = min(src.scale(), DRIVE_TO_MAX_SCALE) if src is not None else DRIVE_TO_MAX_SCALE
        if not scale > 0:  # (a view without its image: no scale of its own)
            scale = DRIVE_TO_MAX_SCALE
        for v, t in self.candidates.items():
            iv = views.get(v)
            if iv is not None and math.isfinite(t.x) and math.isfinite(t.y):
                iv.center_on(t.x, t.y, scale)
        m = self.ctx.project.measurement(self.pid, self.source) if self.ctx.project is not None else None
        if src is not None and m is not None and src.scale() > scale * (1 + 1e-6):
            src.center_on(m.x, m.y, scale)

    def accept(self) -> bool:
        """Place the good candidates (one undoable step); True if anything was placed."""
        p = self.ctx.project
        ok = {v: t for v, t in self.candidates.items() if t.ok}
        if p is None or not ok or self.pid not in p.points:
            return False
        ms = [Measurement(self.pid, v, float(t.x), float(t.y)) for v, t in sorted(ok.items())]
        pid = self.pid
        self.candidates = {}
        self.ctx.undo_stack.push(cmd.Import(p, [], ms, text=f"Transfer {pid} to {', '.join(sorted(ok))}"))
        self._update()
        return True

    def reject(self) -> None:
        self.candidates = {}
        self.pid = None
        self._update()

    def _prune(self) -> None:
        """A click (correction) or an undo made some candidates moot: drop them."""
        p = self.ctx.project
        if not self.candidates:
            return
        if p is None or self.pid not in p.points or p.measurement(self.pid, self.source) is None:
            self.reject()
            return
        self.candidates = {v: t for v, t in self.candidates.items() if p.measurement(self.pid, v) is None}
        self._update()

    def _update_this(self) -> None:
        """*Transfer this point* is there for a current point measured in some views, not all."""
        p, pid = self.ctx.project, self.ctx.current
        n = 0 if p is None or pid not in p.points else sum(
            p.measurement(pid, v) is not None for v in p.scene.views)
        self.a_this.setEnabled(p is not None and 0 < n < len(p.scene.views))

    def _update(self) -> None:
        for vb, item in self._items:
            if shiboken6.isValid(vb) and shiboken6.isValid(item):
                vb.removeItem(item)
        self._items = []
        pending = bool(self.candidates)
        self.a_accept.setEnabled(any(t.ok for t in self.candidates.values()))
        self.a_reject.setEnabled(pending)
        self._update_this()
        self.a_ties.setEnabled(self.ctx.project is not None and len(self.ctx.project.scene.views) > 1)
        self.panel.show_candidates(self.pid if pending else None, self.candidates)
        for v, t in self.candidates.items():
            iv = self.ctx.views.views.get(v)
            if iv is None:
                continue
            colour = CANDIDATE_COLOUR if t.ok else "#ff4040"
            dot = pg.ScatterPlotItem([t.x], [t.y], symbol="o", size=22, pen=pg.mkPen(colour, width=2),
                                     brush=pg.mkBrush(None))
            text = pg.TextItem(f"{t.match.score:.2f}", color=colour, anchor=(-0.3, 1.2))
            text.setPos(t.x, t.y)
            for item in (dot, text):
                item.setZValue(600)
                iv.vb.addItem(item)
                self._items.append((iv.vb, item))

    # ------------------------------------------------------------------ every incomplete point
    def start_all(self):
        """Search every point measured in some views and not in all, in a worker with a progress
        dialog; returns the Job (None when there is nothing to search)."""
        sol, project = self.ctx.solver.solution, self.ctx.project
        if sol is None or project is None:
            self.ctx.status("Point transfer needs a fitted model", 8000)
            return None
        snapshot = project.snapshot()
        try:
            todo = to_transfer(snapshot)
        except InputError as exc:
            self.ctx.status(f"Transfer: {exc}", 10000)
            return None
        if not todo:
            self.ctx.status("Transfer: every point is measured in every view or in none", 8000)
            return None
        height_of = self.ctx.views.height_of

        def work(progress):
            return transfer_points(snapshot, sol, todo, height_of=height_of, progress=progress)

        self.job = run_with_progress(self.ctx, "Point transfer", work, lambda out: self._add_all(project, out))
        return self.job

    def _add_all(self, project, results) -> None:
        """Place what :meth:`start_all` found in one undoable step — where the point still exists
        and the view is still unmeasured — and say what it did."""
        if project is not self.ctx.project:
            return
        ms = [m for m in found_measurements(results)
              if m.id in project.points and project.measurement(m.id, m.view) is None]
        if ms:
            self.ctx.undo_stack.push(cmd.Import(project, [], ms, text=f"Transfer {len({m.id for m in ms})} points"))
        self.summary = f"{len(results)} points searched; " + transfer_summary(results, project.scene.views)
        self.ctx.status(f"Point transfer: {self.summary}", 30000)
        if self.ctx.interactive:
            (QMessageBox.information if ms else QMessageBox.warning)(
                self.ctx.widget, "Point transfer", plain(self.summary))

    # ------------------------------------------------------------------ automatic tie points
    def choose_ties(self) -> None:
        if self.ctx.project is None:
            return
        dlg = QDialog(self.ctx.widget)
        dlg.setWindowTitle("Automatic tie points")
        grid = QSpinBox(minimum=2, maximum=40, value=8)
        form = QFormLayout(dlg)
        sc = self.ctx.project.scene
        others = [v for v in sc.views if v != sc.reference_view]
        form.addRow(QLabel(f"A grid over the {sc.reference_view} image, found in {' and '.join(others)}; "
                           "blunders rejected."))
        form.addRow("Grid (points per side)", grid)
        bb = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel)
        bb.accepted.connect(dlg.accept)
        bb.rejected.connect(dlg.reject)
        form.addRow(bb)
        if dlg.exec() == QDialog.DialogCode.Accepted:
            self.start_ties(grid.value())

    def start_ties(self, grid: int = 8):
        """Run the automatic tie points in a worker with a progress dialog; returns the Job."""
        sol, project = self.ctx.solver.solution, self.ctx.project
        if sol is None or project is None:
            self.ctx.status("Automatic tie points need a fitted model", 8000)
            return None
        height_of = self.ctx.views.height_of

        snapshot = project.snapshot()

        def work(progress):
            return find_tie_points(snapshot, grid=grid, height_of=height_of, progress=progress, sol=sol)

        self.job = run_with_progress(self.ctx, "Automatic tie points", work,
                                     lambda out: self._add_ties(project, *out))
        return self.job

    def _add_ties(self, project, ties, summary) -> None:
        """Add ``ties`` in one undoable step and say what the search did (:func:`ties_summary`)
        on the status line and, in an interactive window, in a message box."""
        if project is not self.ctx.project:
            return
        ids, points, ms = tie_point_edits(project, ties)
        if ties:
            self.ctx.undo_stack.push(cmd.Import(project, points, ms, text=f"{len(ties)} automatic tie points"))
        self.summary = ties_summary(summary, ids, project.scene)
        self.ctx.status(f"Automatic tie points: {self.summary}", 30000)
        if self.ctx.interactive:
            (QMessageBox.information if ties else QMessageBox.warning)(
                self.ctx.widget, "Automatic tie points", plain(self.summary))


def install(ctx) -> None:
    ctx.tools["transfer"] = TransferTool(ctx)
