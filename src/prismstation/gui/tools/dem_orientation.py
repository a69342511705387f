"""Tools ▸ Orient from reference DEM…: orientation with no GCP (Gonçalves, SRTM as ground control).

The dialog asks for the reference (SRTM ``.hgt`` or GeoTIFF, orthometric), the patch size and
the a-priori geolocation σ per view, which sets every search range of the engine
(:func:`prismstation.ops.orient_dem.orient_from_dem`, run in a worker with a cancellable
progress dialog). The result becomes the project's orientation in one undoable step
(``project.dem_control`` plus ``Settings.orientation = "dem"``); the solver then reports it like
a GCP orientation (model panel, ICP statistics, plots). A *Reference DEM patches* dock shows the
a-priori σ, the view offsets, the consistency verdict of the patch field (in red, and in a
message box and the status bar, when the patches do not agree with their σ or are too few) and
the patch shifts, which are also drawn as exaggerated vectors on the N view. *Back to GCP
orientation* is undoable too.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pyqtgraph as pg
import shiboken6
from PySide6.QtCore import Qt
from PySide6.QtGui import QColor, QUndoCommand
from PySide6.QtWidgets import (QDialog, QDialogButtonBox, QDoubleSpinBox, QFileDialog, QFormLayout,
                               QHBoxLayout, QLabel, QLineEdit, QMessageBox, QPushButton, QTableWidget,
                               QTableWidgetItem, QVBoxLayout, QWidget)

from prismstation.gui import settings as st
from prismstation.gui.tools._worker import run_with_progress
from prismstation.ops.coarse_offsets import SIGMA_APRIORI_M

VECTOR_FRACTION = 0.08  # the longest shift vector is drawn this fraction of the N image width


def _num(v) -> float:
    """A record's number (None where the engine had NaN) as a float."""
    return float("nan") if v is None else float(v)


class SetDemOrientation(QUndoCommand):
    """Make ``record`` (``DemOrientation.to_dict()``, or None to keep the stored one) the
    project's control and switch the orientation to ``orientation`` ("dem" or "gcp")."""

    def __init__(self, project, record, orientation: str, text: str):
        super().__init__(text)
        self.project = project
        self.old_record = project.dem_control
        self.new_record = self.old_record if record is None else record
        self.old_settings = project.settings
        self.new_settings = replace(project.settings, orientation=orientation)

    def _apply(self, record, settings) -> None:
        with self.project.batch():  # one change event: one refit
            self.project.set_dem_control(record)
            self.project.set_settings(settings)

    def redo(self) -> None:
        self._apply(self.new_record, self.new_settings)

    def undo(self) -> None:
        self._apply(self.old_record, self.old_settings)


class OrientDialog(QDialog):
    """Reference DEM file, patch size and the a-priori geolocation σ per view."""

    def __init__(self, parent=None, path: str = "", patch_km: float = 4.0,
                 sigma_m: float = SIGMA_APRIORI_M):
        super().__init__(parent)
        self.setWindowTitle("Orient from reference DEM")
        self.path = QLineEdit(path)
        browse = QPushButton("Browse…")
        browse.clicked.connect(self._browse)
        row = QHBoxLayout()
        row.addWidget(self.path, 1)
        row.addWidget(browse)
        self.patch = QDoubleSpinBox(decimals=1, minimum=0.5, maximum=20.0, singleStep=0.5, suffix=" km")
        self.patch.setValue(patch_km)
        self.sigma = QDoubleSpinBox(decimals=0, minimum=1.0, maximum=500.0, singleStep=5.0, suffix=" m")
        self.sigma.setValue(sigma_m)
        self.sigma.setToolTip("σ of each view's ancillary geolocation, per component: every search "
                              "covers 3 σ. 50 m: the shifts Gonçalves reports for uncalibrated "
                              "products; about 10 m for calibrated ones.")
        form = QFormLayout(self)
        form.addRow(QLabel("Orientation with no GCP: the image DSM is matched to the reference\n"
                           "(SRTM .hgt or GeoTIFF, orthometric heights) patch by patch."))
        form.addRow("Reference DEM", row)
        form.addRow("Patch size", self.patch)
        form.addRow("Geolocation σ per view", self.sigma)
        bb = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel)
        bb.accepted.connect(self.accept)
        bb.rejected.connect(self.reject)
        form.addRow(bb)

    def _browse(self) -> None:
        p, _ = QFileDialog.getOpenFileName(self, "Reference DEM", self.path.text() or st.value(st.Key.LAST_IMPORT_DIR),
                                           "DEM (*.tif *.tiff *.hgt);;All files (*)")
        if p:
            self.path.setText(p)


class PatchTable(QWidget):
    """The patches of the stored DEM orientation: position, shift, σ, used or why rejected."""

    HEADERS = ("x px", "y px", "dE m", "dN m", "dh m", "σE m", "σN m", "σh m", "|w|", "state")

    def __init__(self, parent=None):
        super().__init__(parent)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(2, 2, 2, 2)
        self.summary = QLabel("No orientation from a reference DEM yet (Tools ▸ Orient from reference DEM…).")
        self.summary.setWordWrap(True)
        self.verdict = QLabel("")
        self.verdict.setWordWrap(True)
        self.table = QTableWidget(0, len(self.HEADERS))
        self.table.setHorizontalHeaderLabels(self.HEADERS)
        self.table.verticalHeader().setVisible(False)
        self.table.setEditTriggers(QTableWidget.EditTrigger.NoEditTriggers)
        self.table.setSortingEnabled(True)
        lay.addWidget(self.summary)
        lay.addWidget(self.verdict)
        lay.addWidget(self.table, 1)

    def show_record(self, record, active: bool, scale: float | None = None) -> None:
        self.table.setSortingEnabled(False)
        patches = (record or {}).get("patches", [])
        verdict = (record or {}).get("verdict") or {}
        # the normalised residual |w| of each patch the test kept (in the order of the usable ones)
        usable = [i for i, p in enumerate(patches) if p.get("used") or "blunder" in (p.get("reason") or "")]
        w = dict(zip(usable, verdict.get("w") or []))
        self.table.setRowCount(len(patches))
        for i, p in enumerate(patches):
            vals = [p["x"], p["y"], p["dE"], p["dN"], p["dh"], p["sigma_E"], p["sigma_N"], p["sigma_h"],
                    w.get(i)]
            for j, v in enumerate(vals):
                it = QTableWidgetItem()
                v = _num(v)
                it.setData(Qt.ItemDataRole.DisplayRole, round(v, 0 if j < 2 else 2) if np.isfinite(v) else "—")
                it.setTextAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
                self.table.setItem(i, j, it)
            state = "used" if p.get("used") else f"not used: {p.get('reason') or '—'}"
            it = QTableWidgetItem(state)
            if not p.get("used"):
                it.setForeground(QColor("#c0392b"))
            self.table.setItem(i, len(vals), it)
        self.table.setSortingEnabled(True)
        self.table.resizeColumnsToContents()
        if record is None:
            self.summary.setText("No orientation from a reference DEM yet (Tools ▸ Orient from reference DEM…).")
            self.verdict.setText("")
            return
        used = sum(1 for p in patches if p.get("used"))
        state = "in use" if active else "not in use (GCP orientation)"
        off = {k: [_num(c) for c in v] for k, v in (record.get("offsets_px") or {}).items()}
        nan2 = [float("nan")] * 2
        vec = f"; vectors on N × {scale:.0f}" if scale else ""
        ref = str(record.get("reference", "?"))
        sigma = record.get("sigma_apriori_m")
        self.summary.setToolTip(ref)
        self.summary.setText(
            f"Reference {ref.replace(chr(92), '/').rsplit('/', 1)[-1]} — {state}. A-priori geolocation σ "
            f"{_num(sigma):.0f} m per view. {used} of {len(patches)} patches used; from the ancillary model "
            f"F−N ({off.get('F', nan2)[0]:+.1f}, {off.get('F', nan2)[1]:+.1f}) px, "
            f"B−N ({off.get('B', nan2)[0]:+.1f}, {off.get('B', nan2)[1]:+.1f}) px{vec}.")
        self.verdict.setText(verdict_text(record))
        self.verdict.setStyleSheet("" if verdict.get("status") == "ok" else "color: #c0392b; font-weight: bold")


def verdict_text(record) -> str:
    """One line on whether the stored orientation's patch field can be trusted, and its σ."""
    v = (record or {}).get("verdict")
    if not v:
        return "No consistency verdict (an orientation made by an earlier version, before the consistency test): not tested."
    sg = {k: _num(x) for k, x in ((record or {}).get("sigma_m") or {}).items()}
    sigma = (f" Orientation σ (in the reference DEM's frame): planimetric "
             f"{np.hypot(sg['E'], sg['N']):.1f} m, height {sg['h']:.1f} m." if {"E", "N", "h"} <= set(sg) else "")
    if v.get("status") == "ok":
        return f"Verdict: trusted — the patch shifts agree with their σ ({v.get('message', '')}).{sigma}"
    return f"Verdict: NOT TRUSTED ({v.get('status')}) — {v.get('message', '')}{sigma}"


class DemOrientationTool:
    """The menu actions, the patch dock and the N-view vectors (one per window)."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.job = None
        self.result = None
        self.patch_km = 4.0
        self.sigma_m = SIGMA_APRIORI_M
        self._items = []
        self.scale = None
        self.panel = PatchTable()
        self.dock = ctx.add_dock("dem_patches", "Reference DEM patches", self.panel,
                                 Qt.DockWidgetArea.BottomDockWidgetArea, tabify_with="points")
        self.a_orient = ctx.add_action("Orient from reference &DEM…", self.choose,
                                       tip="Orientation with no GCP: match the image DSM to SRTM patch by patch")
        self.a_gcp = ctx.add_action("Back to &GCP orientation", self.back_to_gcp,
                                    tip="Orient from the GCPs again (undoable)")
        ctx.tools_menu.addActions([self.a_orient, self.a_gcp])
        ctx.undo_stack.indexChanged.connect(lambda *_: self.refresh())
        ctx.files.project_opened.connect(lambda *_: self.refresh())
        ctx.solver.solution_changed.connect(lambda *_: self._draw_vectors())
        self.refresh()

    # ------------------------------------------------------------------ running
    def choose(self) -> None:
        if self.ctx.project is None:
            return
        dlg = OrientDialog(self.ctx.widget, st.value(st.Key.LAST_IMPORT_DIR) or "", self.patch_km, self.sigma_m)
        if dlg.exec() == QDialog.DialogCode.Accepted and dlg.path.text():
            self.patch_km, self.sigma_m = dlg.patch.value(), dlg.sigma.value()
            self.start(dlg.path.text(), self.patch_km * 1000.0, sigma_m=self.sigma_m)

    def start(self, reference_path, patch_m: float = 4000.0, posting_m: float = 30.0,
              sigma_m: float = SIGMA_APRIORI_M):
        """Orient the window's project from ``reference_path`` in a worker; returns the Job."""
        from prismstation.gui.solver import snapshot
        from prismstation.ops.orient_dem import orient_from_dem
        project = self.ctx.project
        if project is None or (self.job is not None and self.job.isRunning()):
            return None
        snap = snapshot(project)
        path = str(reference_path)

        def work(progress):
            return orient_from_dem(snap, path, sigma_apriori_m=sigma_m, patch_m=patch_m,
                                   posting_m=posting_m, progress=lambda f, m="": progress(f, m))

        self.job = run_with_progress(self.ctx, "Orientation from the reference DEM", work,
                                     lambda res: self._apply(project, res))
        return self.job

    def _apply(self, project, result) -> None:
        if project is not self.ctx.project:
            return  # the project was closed meanwhile
        self.result = result
        used = sum(1 for p in result.patches if p.used)
        self.ctx.undo_stack.push(SetDemOrientation(project, result.to_dict(), "dem",
                                                 f"Orient from DEM ({used} patches)"))
        self.dock.show()
        self.dock.raise_()
        if not result.verdict.ok:
            text = verdict_text(result.to_dict())
            self.ctx.status(text)
            if getattr(self.ctx, "interactive", False):
                QMessageBox.warning(self.ctx.widget, "Orientation from the reference DEM", text)

    def back_to_gcp(self) -> None:
        p = self.ctx.project
        if p is not None and p.settings.orientation != "gcp":
            self.ctx.undo_stack.push(SetDemOrientation(p, None, "gcp", "Back to GCP orientation"))

    # ------------------------------------------------------------------ display
    def refresh(self) -> None:
        p = self.ctx.project
        record = None if p is None else p.dem_control
        active = p is not None and p.settings.orientation == "dem"
        self.a_orient.setEnabled(p is not None and p.scene.is_triplet)
        self.a_gcp.setEnabled(active)
        self._draw_vectors()
        shown = (record, active, self.scale)
        if getattr(self, "_shown", None) is None or any(a is not b and a != b for a, b in zip(shown, self._shown)):
            self._shown = shown  # (an edit of a point leaves the record alone: no table rebuild)
            self.panel.show_record(record, active, self.scale)

    def _clear_vectors(self) -> None:
        for vb, item in self._items:
            if shiboken6.isValid(vb) and shiboken6.isValid(item):
                vb.removeItem(item)
        self._items = []

    def _draw_vectors(self) -> None:
        self._clear_vectors()
        self.scale = None
        p = self.ctx.project
        iv = self.ctx.views.views.get("N")
        if p is None or iv is None or p.settings.orientation != "dem" or not p.dem_control:
            return
        patches = p.dem_control["patches"]
        if not patches:
            return
        lin = p.scene.views["N"].map_to_image.apply_linear
        xy = np.array([[_num(q["x"]), _num(q["y"])] for q in patches], float)
        en = np.array([[_num(q["dE"]), _num(q["dN"])] for q in patches], float)
        d = np.array([lin(e) if np.isfinite(e).all() else (0.0, 0.0) for e in en], float)
        longest = float(np.max(np.hypot(*d.T))) if len(d) else 0.0
        width = p.scene.views["N"].shape[1]
        self.scale = VECTOR_FRACTION * width / longest if longest > 0 else 1.0
        used = np.array([bool(q.get("used")) for q in patches])
        for mask, colour in ((used, "#39ff14"), (~used, "#ff00ff")):
            if not mask.any():
                continue
            seg = np.empty((2 * mask.sum(), 2))
            seg[0::2], seg[1::2] = xy[mask], xy[mask] + self.scale * d[mask]
            lines = pg.PlotDataItem(seg[:, 0], seg[:, 1], connect="pairs", pen=pg.mkPen(colour, width=3))
            dots = pg.ScatterPlotItem(xy[mask, 0], xy[mask, 1], size=9, pen=pg.mkPen("k"), brush=pg.mkBrush(colour))
            for item in (lines, dots):
                item.setZValue(500)
                iv.vb.addItem(item)
                self._items.append((iv.vb, item))


def install(ctx) -> None:
    ctx.tools["dem_orientation"] = DemOrientationTool(ctx)
