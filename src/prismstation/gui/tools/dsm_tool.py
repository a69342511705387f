"""Tools ▸ Export DSM…: the project's DSM as a GeoTIFF (a PRISM triplet's, or that of images
with RPCs: every pair matched and fused through the fitted biases,
:func:`prismstation.ops.rpc_project.export_dsm`; the sensor model's export,
:func:`prismstation.ops.sensors.workflows_of`).

The whole N image or the area visible in the N view (images with RPCs: the ground every image
sees), at a chosen posting (twice the images' pixel on the ground unless changed), with ellipsoidal or
orthometric heights (through the project's geoid), computed and written in a worker by the
same export as ``prismstation dsm`` (:func:`prismstation.ops.dsm_export.export_dsm`) with the
same options: the a-priori height uncertainty of the prior, the height model (``--heights``),
void filling, the minimum fill, and the loaded reference DEM as the prior. The dialog is
prefilled from the project (a file beside it, orthometric heights when its points are
orthometric, the geoid named). A progress dialog whose Cancel button stops the job (nothing is
written then); the result message gives the fill percentage and warns loudly below the
minimum fill.
"""
from __future__ import annotations

from pathlib import Path

from PySide6.QtWidgets import (QAbstractSpinBox, QButtonGroup, QCheckBox, QComboBox, QDialog,
                               QDialogButtonBox, QDoubleSpinBox, QFileDialog, QFormLayout,
                               QHBoxLayout, QLineEdit, QMessageBox, QPushButton, QRadioButton)

from prismstation.errors import InputError
from prismstation.gui import settings as st
from prismstation.gui.tools._worker import run_with_progress
from prismstation.io.project import project_geoid
from prismstation.model.project import has_ground
from prismstation.ops.fit import heights_not_fixed
from prismstation.ops.dsm_export import HEIGHT_MODELS, DsmRequest
from prismstation.gui.plain import plain
from prismstation.ops.project import require_workflow
from prismstation.ops.sensors import workflows_of

#: the height models as the dialog names them (``prismstation dsm --heights``)
HEIGHT_MODEL_NAMES = {"auto": "automatic (the one the GCPs predict better)",
                      "line": "the model's parallax line", "rays": "the rays through the biases"}

def visible_window(ctx, view: str = "N") -> tuple | None:
    """The window ``(col0, row0, cols, rows)`` of ``view``'s image visible in its view, clipped
    to the image (None if nothing of the image is visible). ``ctx``: the :class:`~prismstation.gui.tools.ToolContext`."""
    iv = ctx.views.views.get(view)
    if iv is None or ctx.project is None:
        return None
    rows, cols = ctx.project.scene.views[view].shape
    x, y, w, h = iv.visible_rect()
    c0, r0 = max(int(x), 0), max(int(y), 0)
    c1, r1 = min(int(x + w) + 1, cols), min(int(y + h) + 1, rows)
    if c1 - c0 < 16 or r1 - r0 < 16:
        return None
    return (c0, r0, c1 - c0, r1 - r0)


class DsmDialog(QDialog):
    """File, extent, posting, height kind and the engine's options."""

    def __init__(self, parent, default_path: str, visible: tuple | None, reference: str | None = None,
                 *, geoid: str | None = None, orthometric: bool = False, triplet: bool = True,
                 gsd_m: float = 2.5, view: str = "N"):
        """``geoid``: the project's geoid, described (None: it cannot be used, orthometric
        heights are off); ``orthometric``: the heights kind to preselect; ``triplet`` False
        (images with RPCs): the height model, a triplet's, is off, and the extent is the ground
        every image sees or the part of it ``view`` (the first image) shows; ``visible`` is
        that view's visible window; ``gsd_m``: the images' pixel on the ground (the coarsest),
        the default posting twice it."""
        super().__init__(parent)
        self.setWindowTitle("Export DSM")
        self.visible = visible
        self.path = QLineEdit(default_path)
        browse = QPushButton("Browse…")
        browse.clicked.connect(self._browse)
        row = QHBoxLayout()
        row.addWidget(self.path, 1)
        row.addWidget(browse)
        self.whole = QRadioButton("whole image" if triplet else "the ground every image sees")
        self.area = QRadioButton(f"visible {view} area" + (f" ({visible[2]} × {visible[3]} px)" if visible else ""))
        self.area.setEnabled(visible is not None)
        (self.area if visible is not None else self.whole).setChecked(True)
        ext = QHBoxLayout()
        ext.addWidget(self.whole)
        ext.addWidget(self.area)
        self.extent_group = QButtonGroup(self)  # two independent choices in one dialog
        self.extent_group.addButton(self.whole)
        self.extent_group.addButton(self.area)
        self.ellipsoidal = QRadioButton("ellipsoidal")
        self.orthometric = QRadioButton(f"orthometric (geoid: {geoid})" if geoid else "orthometric (no usable geoid)")
        self.orthometric.setEnabled(geoid is not None)
        (self.orthometric if orthometric and geoid is not None else self.ellipsoidal).setChecked(True)
        self.height_group = QButtonGroup(self)
        self.height_group.addButton(self.ellipsoidal)
        self.height_group.addButton(self.orthometric)
        hk = QHBoxLayout()
        hk.addWidget(self.ellipsoidal)
        hk.addWidget(self.orthometric)
        # any posting the engine takes (finer than the images' pixel too: more cells, no more
        # detail); a value out of range is set to the nearest, never back to the previous one
        self.posting = QDoubleSpinBox(decimals=1, minimum=0.1, maximum=500.0, singleStep=5.0, suffix=" m")
        self.posting.setCorrectionMode(QAbstractSpinBox.CorrectionMode.CorrectToNearestValue)
        posting = max(round(2.0 * gsd_m, 1), 0.1)
        self.posting.setValue(posting)
        self.posting.setToolTip(f"grid posting; {posting:g} m = 2 × the images' {gsd_m:.2g} m pixel "
                                "(a finer posting adds cells, not detail)")
        self.uncertainty = QDoubleSpinBox(decimals=0, minimum=0.0, maximum=5000.0, singleStep=10.0, suffix=" m")
        self.uncertainty.setSpecialValueText("automatic")   # 0: from the points, or 40 m with a reference
        self.uncertainty.setToolTip("± a-priori height uncertainty of the prior: the coarsest search range")
        self.heights = QComboBox()
        for key in HEIGHT_MODELS:
            self.heights.addItem(HEIGHT_MODEL_NAMES.get(key, key), key)
        self.heights.setToolTip("heights from the model's parallax line, the rays through its biases, or the "
                                "one the GCPs predict better, left out in turn")
        self.fill = QCheckBox("fill voids by interpolation (marked 2 in the mask band)")
        self.heights.setEnabled(triplet)
        self.min_fill = QDoubleSpinBox(decimals=0, minimum=0.0, maximum=100.0, singleStep=5.0, suffix=" %")
        self.min_fill.setValue(90.0)
        self.reference = QCheckBox(f"the loaded reference DEM ({reference})" if reference else "no reference DEM loaded")
        self.reference.setEnabled(reference is not None)
        self.reference.setChecked(reference is not None)
        form = QFormLayout(self)
        form.addRow("GeoTIFF", row)
        form.addRow("Extent", ext)
        form.addRow("Posting", self.posting)
        form.addRow("Heights", hk)
        form.addRow("Height model", self.heights)
        form.addRow("Height uncertainty", self.uncertainty)
        form.addRow("Prior", self.reference)
        form.addRow("Voids", self.fill)
        form.addRow("Minimum fill", self.min_fill)
        bb = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel)
        bb.accepted.connect(self.accept)
        bb.rejected.connect(self.reject)
        form.addRow(bb)

    def _browse(self) -> None:
        p, _ = QFileDialog.getSaveFileName(self, "DSM GeoTIFF", self.path.text(), "GeoTIFF (*.tif *.tiff)")
        if p:
            self.path.setText(p)

    def accept(self) -> None:
        """OK with no file name says so and stays open (it used to close, writing nothing)."""
        if not self.path.text().strip():
            QMessageBox.warning(self, "Export DSM", "Choose the DSM GeoTIFF: a file name is needed.")
            self.path.setFocus()
            return
        super().accept()

    def request(self) -> DsmRequest:
        return DsmRequest(self.path.text().strip(), self.visible if self.area.isChecked() else None,
                          self.posting.value(), self.orthometric.isChecked(),
                          self.uncertainty.value() or None, self.fill.isChecked(),
                          self.min_fill.value(), self.heights.currentData())

    def use_reference(self) -> bool:
        """The loaded reference DEM is the prior."""
        return self.reference.isEnabled() and self.reference.isChecked()


def result_message(out) -> tuple[str, bool]:
    """The operator's summary of a written DSM (:class:`~prismstation.ops.dsm_export.DsmExport`),
    and whether it filled less than the minimum."""
    dsm, path, fill, seen, filled = out.dsm, out.path, out.fill_percent, out.seen_cells, out.filled_percent
    min_fill_percent = out.request.min_fill_percent
    rows, cols = dsm.shape
    pairs = len((dsm.info or {}).get("pairs") or [[0, 1], [0, 2], [1, 2]])     # a triplet's three
    every = (dsm.info or {}).get("seen_by") or {1: "both", 3: "all three"}.get(pairs, "all")
    text = (f"Wrote {path}: {cols} × {rows} cells at {dsm.posting_m:g} m, {dsm.height_kind} heights; "
            f"{fill:.1f} % of the {seen} cells {every} images see matched"
            + (f", {filled:.1f} % filled by interpolation" if filled else ""))
    agree = (dsm.info or {}).get("pair_agreement") or {}
    if agree:
        text += ". Pairs agree to NMAD " + ", ".join(
            "–" if a.get("nmad_m") is None else f"{a['nmad_m']:.2f}" for a in agree.values()) + " m"
    hm = (dsm.info or {}).get("heights")
    if hm:
        text += f". Heights: {'parallax line' if hm['model'] == 'line' else 'rays through the biases'} ({hm['reason']})"
    low = out.low_fill
    if low:
        text = (f"LOW FILL: only {fill:.1f} % of the seen cells matched (minimum {min_fill_percent:g} %); "
                f"the voids are 0 in the mask band. " + text)
    return text, low


class DsmTool:
    """The Export DSM action and its job (one per window)."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.job = None
        self.message = ""        # the last result message (for scripts and tests)
        self.action = ctx.add_action("Export &DSM…", self.choose,
                                     tip="Semi-global matching of the three pairs through the model → DSM GeoTIFF")
        ctx.tools_menu.addSeparator()
        ctx.tools_menu.addAction(self.action)
        ctx.files.project_opened.connect(lambda *_: self._update())

    def refusal(self) -> str | None:
        """Why the project's sensor model cannot make a DSM here, or None
        (:func:`prismstation.ops.project.require_workflow`)."""
        try:
            require_workflow(self.ctx.project, "dsm")
        except InputError as exc:
            return str(exc)
        return None

    def _update(self) -> None:
        no = self.ctx.project is not None and self.refusal()
        self.action.setEnabled(not no)
        self.action.setToolTip(no or "Semi-global matching of the three pairs through the model → DSM GeoTIFF")

    def reference(self):
        """The loaded reference DEM (:class:`~prismstation.ops.reference_heights.DemHeights`) or None."""
        return getattr(self.ctx.solver, "height_of", None)

    def default_path(self) -> Path:
        """Where the DSM goes unless the operator says otherwise: beside the project file
        (``<project>_dsm.tif``), else beside the scene, else the last import folder."""
        p = self.ctx.project
        path = self.ctx.files.path
        if path:
            return Path(path).with_name(f"{Path(path).stem}_dsm.tif")
        if p is not None and p.scene_path:
            return Path(p.scene_path).with_name("dsm.tif")
        return Path(st.value(st.Key.LAST_IMPORT_DIR) or ".") / "dsm.tif"

    def geoid(self) -> str | None:
        """The project's geoid, described (None when it cannot be used: a grid not found)."""
        try:
            g = project_geoid(self.ctx.project)
        except InputError:
            return None
        return g.describe() if hasattr(g, "describe") else "the project's"

    def choose(self) -> None:
        if self.ctx.project is None or (self.job is not None and self.job.isRunning()):
            return
        if self.refusal():
            self.ctx.status(self.refusal(), 10000)
            return
        ref = self.reference()
        name = Path(str(getattr(ref, "path", "") or "reference")).name if ref is not None else None
        kinds = [q.height_kind for q in self.ctx.project.points.values() if has_ground(q)]
        orthometric = bool(kinds) and kinds.count("orthometric") >= kinds.count("ellipsoidal")
        sc = self.ctx.project.scene
        view = "N" if sc.is_triplet else next(iter(sc.views))   # images with RPCs: the first one's
        dlg = DsmDialog(self.ctx.widget, str(self.default_path()), visible_window(self.ctx, view), name,
                        geoid=self.geoid(), orthometric=orthometric, triplet=sc.is_triplet, view=view,
                        gsd_m=max(v.pixel_size_m for v in sc.views.values()))
        if dlg.exec() == QDialog.DialogCode.Accepted:
            self.start(dlg.request(), use_reference=dlg.use_reference())

    def start(self, req: DsmRequest, *, use_reference: bool = False):
        """Compute and write the DSM of ``req`` in a worker, with the loaded reference DEM as
        the prior when ``use_reference``; returns the Job (result: the
        :class:`~prismstation.ops.dsm_export.DsmExport`)."""
        sol, p = self.ctx.solver.solution, self.ctx.project
        if sol is None or p is None:
            self.ctx.status("A DSM needs a fitted model", 8000)
            return None
        if self.refusal():
            self.ctx.status(self.refusal(), 10000)
            return None
        ref = self.reference() if use_reference else None

        def work(progress):
            return workflows_of(p).export_dsm(sol, p, req, reference=ref, progress=progress)

        def done(out):
            self.ctx.outputs["dsm"] = str(out.path)  # (Validate DSM offers it next)
            self.message, low = result_message(out)
            unfixed = heights_not_fixed(sol)  # as `prismstation dsm` says it before its status 3
            if unfixed:
                self.message, low = f"HEIGHTS NOT FIXED: {unfixed}. " + self.message, True
            self.ctx.status(self.message, 30000 if low else 15000)
            if self.ctx.interactive:
                (QMessageBox.warning if low else QMessageBox.information)(self.ctx.widget, "DSM", plain(self.message))

        self.job = run_with_progress(self.ctx, "DSM", work, done)
        return self.job


def install(ctx) -> None:
    ctx.tools["dsm"] = DsmTool(ctx)
