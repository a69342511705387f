"""Single-image rectification in the window (docs/model.md §4; Subaryono et al., AVNIR).

A "Transforms" dock shows, for the project's GCPs/ICPs in every view, the side-by-side RMSE of
the affine, projective and polynomial (1–3) image→map transforms (Subaryono et al.'s Table 4.1: one
row per transform, GCP and ICP RMSE per image) and the per-point residuals of the chosen
transform; it refreshes after every edit. Tools ▸ Rectify… writes a GeoTIFF through the chosen
transform with :func:`prismstation.ops.rectify.rectify_raster` in a worker thread.
"""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (QComboBox, QDialog, QDialogButtonBox, QDoubleSpinBox, QFileDialog,
                               QFormLayout, QHBoxLayout, QLabel, QLineEdit, QMessageBox,
                               QPushButton, QTableWidget, QTableWidgetItem, QVBoxLayout, QWidget)

from prismstation.core.models.rectify import KINDS, compare_transforms, min_points, n_params
from prismstation.gui import settings as st
from prismstation.gui.titles import fit_title
from prismstation.gui.tools._rect_common import view_points, watch_project
from prismstation.gui.tools._worker import Job, run_with_progress
from prismstation.gui.plain import plain
from prismstation.io.formatting import fixed
from prismstation.io.georef import crs_name
from prismstation.ops.rectify import rectify_raster


def _item(text, align=Qt.AlignmentFlag.AlignRight) -> QTableWidgetItem:
    it = QTableWidgetItem(text)
    it.setTextAlignment(align | Qt.AlignmentFlag.AlignVCenter)
    it.setFlags(it.flags() & ~Qt.ItemFlag.ItemIsEditable)
    return it


class TransformsPanel(QWidget):
    """RMSE table (transform × image) and residuals of the chosen transform for one view."""

    def __init__(self, ctx):
        super().__init__(ctx.widget)
        self.ctx = ctx
        self.reports: dict = {}     # view -> tuple[TransformReport, ...]
        self.ids: dict = {}         # view -> (ids, is_check)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(4, 4, 4, 4)
        self.rmse = QTableWidget(0, 0)
        self.rmse.verticalHeader().setVisible(False)
        self.rmse.verticalHeader().setDefaultSectionSize(22)
        self.rmse.setMinimumHeight(175)
        lay.addWidget(QLabel("<b>Planimetric RMSE (m) — GCPs fit, ICPs check</b>"))
        lay.addWidget(self.rmse, 2)
        self.message = QLabel("")
        self.message.setWordWrap(True)
        self.message.setStyleSheet("color: #b45309;")
        lay.addWidget(self.message)
        row = QHBoxLayout()
        row.addWidget(QLabel("Residuals of"))
        self.kind = QComboBox()
        self.kind.addItems(KINDS)
        row.addWidget(self.kind)
        row.addWidget(QLabel("in view"))
        self.view = QComboBox()
        row.addWidget(self.view)
        row.addStretch(1)
        lay.addLayout(row)
        self.resid = QTableWidget(0, 5)
        self.resid.setHorizontalHeaderLabels(["ID", "Kind", "vE (m)", "vN (m)", "|v| (m)"])
        self.resid.verticalHeader().setVisible(False)
        self.resid.verticalHeader().setDefaultSectionSize(22)
        lay.addWidget(self.resid, 3)
        self.kind.currentTextChanged.connect(lambda *_: self._fill_residuals())
        self.view.currentTextChanged.connect(lambda *_: self._fill_residuals())
        self._key = None
        watch_project(ctx, self.refresh)

    def showEvent(self, ev) -> None:  # a hidden or tabbed-away panel catches up when shown
        super().showEvent(ev)
        self.refresh()

    def refresh(self, force: bool = False) -> None:
        """Refit every transform on every view's points (milliseconds) and redraw — only
        while the panel is visible (on a triplet it is otherwise ~40 ms on every click) or
        when ``force``d (a rectification needs the fit whether the panel is open or not)."""
        if not (force or self.isVisible()):
            return
        project = self.ctx.project
        key = None if project is None else (id(project), project.revision)
        if key == self._key:
            return
        self._key = key
        self.reports, self.ids = {}, {}
        if project is not None:
            for v in project.scene.views:
                ids, xy, g, chk = view_points(project, v)
                with warnings.catch_warnings():  # no points yet: NaN means, reports say why
                    warnings.simplefilter("ignore", RuntimeWarning)
                    self.reports[v] = compare_transforms(xy, g[:, :2], chk)
                self.ids[v] = (ids, chk)
        self._fill_rmse()
        cur = self.view.currentText()
        self.view.blockSignals(True)
        self.view.clear()
        self.view.addItems(list(self.reports))
        if cur in self.reports:
            self.view.setCurrentText(cur)
        self.view.blockSignals(False)
        self._fill_residuals()

    def _fill_rmse(self) -> None:
        views = list(self.reports)
        t = self.rmse
        t.clear()
        t.setRowCount(len(KINDS))
        t.setColumnCount(2 + 2 * len(views))
        t.setHorizontalHeaderLabels(["Transform", "u"] + [f"{v} {k}" for v in views
                                                           for k in ("GCP", "ICP")])
        notes = []
        for i, kind in enumerate(KINDS):
            t.setItem(i, 0, _item(kind, Qt.AlignmentFlag.AlignLeft))
            t.setItem(i, 1, _item(str(n_params(kind))))
            for j, v in enumerate(views):
                r = self.reports[v][i]
                t.setItem(i, 2 + 2 * j, _item(fixed(r.rmse_gcp, 3)))
                t.setItem(i, 3 + 2 * j, _item(fixed(r.rmse_icp, 3)))
                if not r.ok:
                    for c in (2 + 2 * j, 3 + 2 * j):
                        t.item(i, c).setToolTip(plain(r.error))
                    notes.append(f"{v} · {kind}: {r.error}")
        t.resizeColumnsToContents()
        if notes:
            need = ", ".join(f"{k} {min_points(k)}" for k in KINDS)
            self.message.setText("Not fitted — " + "; ".join(notes)
                                 + f".  (Minimum GCPs: {need}.)")
        else:
            self.message.setText("")

    def report(self, view: str, kind: str):
        """The :class:`TransformReport` of ``kind`` for ``view`` (None if unknown)."""
        reps = self.reports.get(view)
        return None if reps is None else next((r for r in reps if r.kind == kind), None)

    def _fill_residuals(self) -> None:
        v, kind = self.view.currentText(), self.kind.currentText()
        r = self.report(v, kind)
        self.resid.setRowCount(0)
        if r is None:
            return
        ids, chk = self.ids[v]
        self.resid.setRowCount(len(ids))
        for i, (pid, icp, (vx, vy)) in enumerate(zip(ids, chk, r.residuals)):
            for c, text in enumerate((pid, "ICP" if icp else "GCP", fixed(vx, 3), fixed(vy, 3),
                                      fixed(float(np.hypot(vx, vy)), 3))):
                self.resid.setItem(i, c, _item(text, Qt.AlignmentFlag.AlignLeft if c < 2
                                               else Qt.AlignmentFlag.AlignRight))
        self.resid.resizeColumnsToContents()


class RectifyDialog(QDialog):
    """Transform, view, output CRS, resolution and output file of a rectification."""

    def __init__(self, ctx, panel: TransformsPanel):
        super().__init__(ctx.widget)
        self.setWindowTitle("Rectify")
        fit_title(self)
        project = ctx.project
        f = QFormLayout(self)
        self.view = QComboBox()
        self.view.addItems(list(project.scene.views))
        if panel.view.currentText():
            self.view.setCurrentText(panel.view.currentText())
        self.kind = QComboBox()
        self.kind.addItems(KINDS)
        self.kind.setCurrentText(panel.kind.currentText())
        self.crs = QLineEdit(project.scene.crs)
        self.resolution = QDoubleSpinBox()
        self.resolution.setRange(0.0, 1e6)
        self.resolution.setDecimals(3)
        self.resolution.setSpecialValueText("auto (the image's own)")
        self.out = QLineEdit()
        self._suggested = ""
        self.view.currentTextChanged.connect(lambda *_: self._suggest(ctx))
        self.kind.currentTextChanged.connect(lambda *_: self._suggest(ctx))
        self._suggest(ctx)
        browse = QPushButton("…")
        browse.clicked.connect(self._browse)
        row = QHBoxLayout()
        row.addWidget(self.out, 1)
        row.addWidget(browse)
        for label, w in (("View", self.view), ("Transform", self.kind), ("Output CRS", self.crs),
                         ("Resolution", self.resolution)):
            f.addRow(label, w)
        f.addRow("Output GeoTIFF", row)
        bb = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok
                              | QDialogButtonBox.StandardButton.Cancel)
        bb.accepted.connect(self.accept)
        bb.rejected.connect(self.reject)
        f.addRow(bb)

    def _suggest(self, ctx) -> None:
        """A file beside the project named after the view and transform, until the operator
        types or browses one of their own."""
        if self.out.text() not in ("", self._suggested):
            return
        base = Path(ctx.files.path) if ctx.files.path else None
        folder = base.parent if base is not None else Path(st.value(st.Key.LAST_IMPORT_DIR) or ".")
        stem = f"{base.stem}_" if base is not None else ""
        self._suggested = str(folder / f"{stem}{self.view.currentText()}_{self.kind.currentText()}.tif")
        self.out.setText(self._suggested)

    def _browse(self) -> None:
        p, _ = QFileDialog.getSaveFileName(self, "Rectified GeoTIFF", self.out.text(), "GeoTIFF (*.tif)")
        if p:
            self.out.setText(p)

    def accept(self) -> None:
        """OK with no output file says so and stays open (it used to close, writing nothing)."""
        if not self.out.text().strip():
            QMessageBox.warning(self, "Rectify", "Choose the output GeoTIFF: a file name is needed.")
            self.out.setFocus()
            return
        super().accept()


class RectifyTool:
    def __init__(self, ctx):
        self.ctx = ctx
        self.panel = TransformsPanel(ctx)
        self.dock = ctx.add_dock("transforms", "Transforms", self.panel,
                                 Qt.DockWidgetArea.RightDockWidgetArea)
        self.job: Job | None = None
        self.summary = ""  # the last rectification's summary
        ctx.views.images_loaded.connect(self._show_for_single_view)
        ctx.tools_menu.addAction("Rectify…", self.open_dialog)
        ctx.tools_menu.addAction(self.dock.toggleViewAction())

    def _show_for_single_view(self, *args) -> None:
        """A single-image project (the AVNIR rectification of Subaryono et al.) is about transforms: show their table."""
        p = self.ctx.project
        if p is not None and len(p.scene.views) == 1:
            self.dock.show()
            self.dock.raise_()
            self.panel.refresh()

    def open_dialog(self) -> None:
        w = self.ctx
        if w.project is None:
            return
        d = RectifyDialog(w, self.panel)
        if d.exec() != QDialog.DialogCode.Accepted:
            return
        self.start(d.view.currentText(), d.kind.currentText(), d.out.text().strip(), d.crs.text() or None,
                   d.resolution.value() or None)

    def start(self, view: str, kind: str, out_path, out_crs=None, resolution=None,
              progress_dialog: bool = True) -> Job | None:
        """Rectify ``view`` through ``kind`` into ``out_path`` in a worker; returns the Job
        (result: the rectified raster's record), or None with a message when the transform
        cannot be fitted."""

        w = self.ctx
        self.panel.refresh(force=True)
        r = self.panel.report(view, kind)
        v = w.project.scene.views.get(view)
        image = None if v is None else v.image
        if r is None or not r.ok or not image:
            msg = r.error if r is not None and not r.ok else f"view {view} has no image"
            self._message(f"Cannot rectify: {msg}")
            return None
        crs = w.project.scene.crs

        def work(progress):
            return rectify_raster(image, r.transform, Path(out_path), points_crs=crs,
                                  out_crs=out_crs, resolution=resolution, progress=progress)

        self.job = run_with_progress(w, f"Rectifying {view} through {kind}", work,
                                     lambda res: self._done(res, view, r), dialog=progress_dialog)
        return self.job

    def _done(self, result, view: str, report) -> None:
        """The summary: what was written, on which grid, and how well the transform fits."""
        self.summary = (
            f"Rectified view {view} through the {report.kind} transform ({report.n_params} parameters, "
            f"{report.n_gcp} GCPs; planimetric RMSE {fixed(report.rmse_gcp, 3)} m on the GCPs, "
            f"{fixed(report.rmse_icp, 3)} m on {report.n_icp} ICPs).\n\n"
            f"Wrote {result.path}: {result.width} × {result.height} cells of {result.resolution:g} "
            f"in {crs_name(result.crs)}.")
        self.ctx.status(f"Wrote {result.path}: {result.width} × {result.height} cells of {result.resolution:g} "
                        f"in {crs_name(result.crs)} — {view} through {report.kind}, planimetric RMSE "
                        f"{fixed(report.rmse_gcp, 3)} m (GCPs), {fixed(report.rmse_icp, 3)} m (ICPs)", 30000)
        if self.ctx.interactive:
            box = QMessageBox(QMessageBox.Icon.Information, "Rectify", plain(self.summary),
                              QMessageBox.StandardButton.Ok, self.ctx.widget)
            fit_title(box)
            box.exec()

    def _message(self, text: str) -> None:
        self.ctx.status(text, 15000)
        if self.ctx.interactive and "Cannot" in text:
            QMessageBox.warning(self.ctx.widget, "Rectify", plain(text))


def install(ctx) -> None:
    ctx.tools["rectify"] = RectifyTool(ctx)
