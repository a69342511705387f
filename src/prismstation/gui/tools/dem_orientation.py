"""Tools ▸ Orient from reference DEM…: orientation with no GCP (Gonçalves, SRTM as ground control).

The dialog asks for the reference (SRTM ``.hgt`` or GeoTIFF, orthometric), the patch size and
the a-priori geolocation σ per view, which sets every search range of the engine. The
orientation is the project's sensor model's (:func:`prismstation.ops.sensors.workflows_of`:
``orient(project, reference, request)``, the request made by the model's widgets,
:mod:`prismstation.gui.sensors`), run in a worker with a cancellable progress dialog. The
result becomes the project's orientation in one undoable step (``project.dem_control`` plus
``Settings.orientation = "dem"``); the solver then reports it like a GCP orientation (model
panel, ICP statistics, plots). A *Reference DEM patches* dock shows the orientation in the
model's words: for a PRISM triplet the a-priori σ, the view offsets, the consistency verdict of
the patch field (in red, and in a message box and the status bar, when the patches do not
agree with their σ or are too few) and the patch shifts, which are also drawn as exaggerated
vectors on the N view; for images with RPCs the block's shift and each image's bias. An
orientation with nothing to apply (images with RPCs whose DSM could not be laid on the
reference) is not applied, the status bar says why. *Back to GCP orientation* is undoable too.

An orientation whose verdict is not *trusted* is never applied without the operator's yes: a
question states the verdict and why (a window that asks nothing — tests, scripts — does not
apply it); declined, it stays in the dock, not in use, with a button to apply it after all.
The dialog starts from the project's reference DEM and a patch size chosen from the scene's
size (:func:`default_patch_km`), and says how many patches that gives.
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

from prismstation.core.orientation.conditioning import MIN_PATCHES, TARGET_M
from prismstation.core.orientation.dem_orient import patch_windows
from prismstation.gui import settings as st
from prismstation.gui.plain import plain
from prismstation.gui.sensors import parts_of
from prismstation.gui.solver import snapshot
from prismstation.gui.titles import fit_title
from prismstation.gui.tools._worker import run_with_progress
from prismstation.io.jsonfile import number
from prismstation.ops.coarse_offsets import SIGMA_APRIORI_M
from prismstation.ops.orientation import default_patch_km, scene_km
from prismstation.ops.sensors import workflows_of

VECTOR_FRACTION = 0.08  # the longest shift vector is drawn this fraction of the N image width


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


def patch_count(scene, patch_km: float) -> tuple[int, int]:
    """``(columns, rows)`` of patches the engine cuts the N image into (its own rule)."""
    n = scene.views[scene.reference_view]
    px = max(int(round(patch_km * 1000.0 / n.pixel_size_m)), 64)
    wins = patch_windows(n.shape, px, margin_px=32)
    cols = len({w[0] for w in wins})
    return cols, len(wins) // max(cols, 1)


class OrientDialog(QDialog):
    """Reference DEM file, patch size (km, chosen from the scene's size unless the operator
    changed it) and the a-priori geolocation σ per view; says how many patches the size gives."""

    def __init__(self, parent=None, path: str = "", patch_km: float | None = None,
                 sigma_m: float = SIGMA_APRIORI_M, scene=None, target_m: float = TARGET_M):
        super().__init__(parent)
        self.setWindowTitle("Orient from reference DEM")
        fit_title(self)
        self.scene = scene
        self.path = QLineEdit(path)
        browse = QPushButton("Browse…")
        browse.clicked.connect(self._browse)
        row = QHBoxLayout()
        row.addWidget(self.path, 1)
        row.addWidget(browse)
        self.patch = QDoubleSpinBox(decimals=2, minimum=0.25, maximum=20.0, singleStep=0.25, suffix=" km")
        self.auto_km = default_patch_km(scene) if scene is not None else 4.0
        self.patch.setValue(self.auto_km if patch_km is None else patch_km)
        self.patches = QLabel()
        self.patches.setWordWrap(True)
        self.patch.valueChanged.connect(self._count)
        self.sigma = QDoubleSpinBox(decimals=0, minimum=1.0, maximum=500.0, singleStep=5.0, suffix=" m")
        self.sigma.setValue(sigma_m)
        self.sigma.setToolTip("σ of each view's ancillary geolocation, per component: every search "
                              "covers 3 σ. 50 m: the shifts Gonçalves reports for uncalibrated "
                              "products; about 10 m for calibrated ones.")
        self.target = QDoubleSpinBox(decimals=1, minimum=0.5, maximum=100.0, singleStep=0.5, suffix=" m")
        self.target.setValue(target_m)
        self.target.setToolTip("The planimetric and height σ the orientation must reach to be trusted "
                               "(by default one PRISM pixel, 2.5 m): terrain too smooth to fix it that "
                               "well is refused, with what would help.")
        form = QFormLayout(self)
        form.addRow(QLabel("Orientation with no GCP: the image DSM is matched to the reference\n"
                           "(SRTM .hgt or GeoTIFF, orthometric heights) patch by patch."))
        form.addRow("Reference DEM", row)
        form.addRow("Patch size", self.patch)
        form.addRow("", self.patches)
        form.addRow("Geolocation σ per view", self.sigma)
        form.addRow("Target σ", self.target)
        bb = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel)
        bb.accepted.connect(self.accept)
        bb.rejected.connect(self.reject)
        form.addRow(bb)
        self._count()

    def _count(self, *_) -> None:
        """Say how many patches the size gives on this scene, and when they are too few."""
        if self.scene is None:
            return
        across, along = scene_km(self.scene)
        nx, ny = patch_count(self.scene, self.patch.value())
        n = nx * ny
        text = f"{n} patch{'es' if n != 1 else ''} ({nx} × {ny}) on this {across:.1f} × {along:.1f} km scene"
        if abs(self.patch.value() - self.auto_km) < 1e-9:
            text += " (the size chosen for it: a quarter of its side, 1–4 km)"
        if nx * ny < MIN_PATCHES:
            text = (f"<span style='color:#c0392b'><b>{text}: fewer than {MIN_PATCHES}, too few to test "
                    "the orientation</b> — it would not be trusted. Choose smaller patches.</span>")
        self.patches.setText(text)

    def _browse(self) -> None:
        p, _ = QFileDialog.getOpenFileName(self, "Reference DEM", self.path.text() or st.value(st.Key.LAST_IMPORT_DIR),
                                           "DEM (*.tif *.tiff *.hgt);;All files (*)")
        if p:
            self.path.setText(p)


class PatchTable(QWidget):
    """The patches of the stored DEM orientation: position, shift, σ, used or why rejected."""

    HEADERS = ("x px", "y px", "dE m", "dN m", "dh m", "σE m", "σN m", "σh m", "T/dof", "state")

    def __init__(self, parent=None):
        super().__init__(parent)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(2, 2, 2, 2)
        self.summary = QLabel("No orientation from a reference DEM yet (Tools ▸ Orient from reference DEM…).")
        self.summary.setWordWrap(True)
        self.verdict = QLabel("")
        self.verdict.setWordWrap(True)
        for lab in (self.summary, self.verdict):
            lab.setTextFormat(Qt.TextFormat.PlainText)  # (the reference's file name)
        self.apply_button = QPushButton("Apply this orientation anyway")
        self.apply_button.setToolTip("Make this untrusted orientation the project's (undoable)")
        self.apply_button.hide()
        self.table = QTableWidget(0, len(self.HEADERS))
        self.table.setHorizontalHeaderLabels(self.HEADERS)
        self.table.verticalHeader().setVisible(False)
        self.table.setEditTriggers(QTableWidget.EditTrigger.NoEditTriggers)
        self.table.setSortingEnabled(True)
        lay.addWidget(self.summary)
        lay.addWidget(self.verdict)
        row = QHBoxLayout()
        row.addWidget(self.apply_button)
        row.addStretch(1)
        lay.addLayout(row)
        lay.addWidget(self.table, 1)

    def show_record(self, record, active: bool, scale: float | None = None, applied: bool = True,
                    parts=None) -> None:
        """Show ``record``; ``active``: the project is oriented by it; ``applied`` False: a
        result the operator declined (not the project's); ``parts``: the project's sensor
        model's widgets (:mod:`prismstation.gui.sensors`), which say it in words."""
        self.apply_button.setVisible(record is not None and not applied)
        self.table.setSortingEnabled(False)
        patches = (record or {}).get("patches", [])
        self.table.setRowCount(len(patches))
        for i, p in enumerate(patches):
            # each patch's χ² test against the other patches' field, per direction it fixes
            t = number(p.get("T")) / p["dof"] if p.get("dof") else None
            vals = [p["x"], p["y"], p["dE"], p["dN"], p["dh"], p["sigma_E"], p["sigma_N"], p["sigma_h"], t]
            for j, v in enumerate(vals):
                it = QTableWidgetItem()
                v = number(v)
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
        if record is None or parts is None:
            self.summary.setText("No orientation from a reference DEM yet (Tools ▸ Orient from reference DEM…).")
            self.verdict.setText("")
            return
        state = ("NOT APPLIED (not trusted; the GCP orientation stays)" if not applied
                 else "in use" if active else "not in use (GCP orientation)")
        self.summary.setToolTip(plain(str(record.get("reference", "?"))))
        self.summary.setText(parts.orientation_text(record, state, scale))
        self.verdict.setText(parts.verdict_text(record))
        verdict = record.get("verdict") or {}
        self.verdict.setStyleSheet("" if verdict.get("status") == "ok" else "color: #c0392b; font-weight: bold")


class DemOrientationTool:
    """The menu actions, the patch dock and the N-view vectors (one per window)."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.job = None
        self.result = None
        self.message = ""
        self.patch_km = None  # None: chosen from the scene's size
        self.sigma_m = SIGMA_APRIORI_M
        self.target_m = TARGET_M
        self.declined = None  # (project, record) of an untrusted result the operator declined
        self.last_path = ""
        self._items = []
        self.scale = None
        self.panel = PatchTable()
        self.panel.apply_button.clicked.connect(self.apply_declined)
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
        dlg = OrientDialog(self.ctx.widget, self.reference_path(), self.patch_km, self.sigma_m,
                           self.ctx.project.scene, self.target_m)
        if dlg.exec() == QDialog.DialogCode.Accepted and dlg.path.text():
            km = dlg.patch.value()
            self.patch_km = None if abs(km - dlg.auto_km) < 1e-9 else km  # the operator's own size is kept
            self.sigma_m, self.last_path, self.target_m = dlg.sigma.value(), dlg.path.text(), dlg.target.value()
            self.start(dlg.path.text(), km * 1000.0, sigma_m=self.sigma_m, target_m=self.target_m)

    def reference_path(self) -> str:
        """The DEM to offer: the project's reference DEM, else the one loaded, else the last used."""
        p = self.ctx.project
        loaded = getattr(self.ctx.solver, "height_of", None)
        return (p.reference_dem if p is not None and p.reference_dem else
                str(loaded.path) if loaded is not None and getattr(loaded, "path", None) else self.last_path)

    def start(self, reference_path, patch_m: float = 4000.0, posting_m: float = 30.0,
              sigma_m: float = SIGMA_APRIORI_M, target_m: float = TARGET_M):
        """Orient the window's project from ``reference_path`` in a worker (the sensor model's
        orientation, asked as its widgets make the request); returns the Job (its result: an
        :class:`~prismstation.ops.orientation.Orientation`)."""
        project = self.ctx.project
        if project is None or (self.job is not None and self.job.isRunning()):
            return None
        request = parts_of(project.scene.sensor).orient_request(patch_m, posting_m, sigma_m, target_m)
        snap, sol, path = snapshot(project), self.ctx.solver.solution, str(reference_path)
        orient = workflows_of(project).orient

        def work(progress):
            return orient(snap, path, request, solution=sol, progress=lambda f, m="": progress(f, m))

        self.job = run_with_progress(self.ctx, "Orientation from the reference DEM", work,
                                     lambda res: self._apply(project, res))
        return self.job

    def _apply(self, project, result) -> None:
        self.result = result
        if project is not self.ctx.project:
            return  # the project was closed meanwhile
        if result.record is None:           # nothing to apply: the status bar says why
            self.message = f"Not applied: {result.verdict.message}"
            self.ctx.status(self.message, 30000)
            return
        record = result.record
        self.dock.show()
        self.dock.raise_()
        parts = parts_of(project.scene.sensor)
        if not result.ok and not self._operator_says_apply(record):
            self.declined = (project, record, result.title)
            self.ctx.status(f"Not applied: {parts.verdict_text(record)}", 30000)
            self._shown = None
            self.refresh()
            return
        self._push(project, record, result.title)

    def _push(self, project, record, title: str) -> None:
        self.declined = None
        self._shown = None
        self.ctx.undo_stack.push(SetDemOrientation(project, record, "dem", f"Orient from DEM ({title})"))
        parts = parts_of(project.scene.sensor)
        self.message = parts.applied_text(record)
        if self.message:
            self.ctx.status(self.message, 30000)

    def _operator_says_apply(self, record) -> bool:
        """The question for an untrusted orientation: its verdict and why; No by default."""
        if not self.ctx.interactive:
            return False
        v = record.get("verdict") or {}
        p = self.ctx.project
        if p is not None and p.settings.orientation == "dem":
            now = ("the orientation from the reference DEM applied before (Edit ▸ Undo returns to "
                   "it; Tools ▸ Back to GCP orientation to the GCPs)")
        else:
            now = "the GCP orientation (Edit ▸ Undo or Tools ▸ Back to GCP orientation return to it)"
        box = QMessageBox(QMessageBox.Icon.Warning, "Orientation from the reference DEM",
                          plain(f"The orientation from the reference DEM is NOT TRUSTED ({v.get('status')}): "
                                f"{v.get('message', '').removeprefix('NOT TRUSTED: ')}."
                                + (f"\n\nWhat would help: {v['advice']}." if v.get("advice") else "")
                                + f"\n\nApply it anyway? It would replace {now}."),
                          QMessageBox.StandardButton.Yes | QMessageBox.StandardButton.No, self.ctx.widget)
        box.setDefaultButton(QMessageBox.StandardButton.No)
        fit_title(box)
        return box.exec() == QMessageBox.StandardButton.Yes

    def apply_declined(self) -> None:
        """The dock's button: the operator applies the declined result after all."""
        if self.declined is not None and self.declined[0] is self.ctx.project:
            self._push(*self.declined)

    def back_to_gcp(self) -> None:
        p = self.ctx.project
        if p is not None and p.settings.orientation != "gcp":
            self.ctx.undo_stack.push(SetDemOrientation(p, None, "gcp", "Back to GCP orientation"))

    # ------------------------------------------------------------------ display
    def refresh(self) -> None:
        p = self.ctx.project
        record = None if p is None else p.dem_control
        active = p is not None and p.settings.orientation == "dem"
        applied = True
        if self.declined is not None and (self.declined[0] is not p or active):
            self.declined = None  # another project, or oriented since
        if self.declined is not None:
            record, applied = self.declined[1], False
        self.a_orient.setEnabled(p is not None and "orient-dem" in p.scene.sensor.workflows
                                 and parts_of(p.scene.sensor).orientable(p.scene))
        self.a_gcp.setEnabled(active)
        self._draw_vectors()
        shown = (record, active, self.scale, applied)
        if getattr(self, "_shown", None) is None or any(a is not b and a != b for a, b in zip(shown, self._shown)):
            self._shown = shown  # (an edit of a point leaves the record alone: no table rebuild)
            self.panel.show_record(record, active, self.scale, applied,
                                   None if p is None else parts_of(p.scene.sensor))

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
        patches = p.dem_control.get("patches")
        if not patches:
            return
        lin = p.scene.views["N"].map_to_image.apply_linear
        xy = np.array([[number(q["x"]), number(q["y"])] for q in patches], float)
        en = np.array([[number(q["dE"]), number(q["dN"])] for q in patches], float)
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
