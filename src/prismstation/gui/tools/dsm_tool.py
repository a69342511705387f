"""Tools ▸ Export DSM…: the triplet's DSM as a GeoTIFF.

The whole N image or the area visible in the N view, at a chosen posting, with ellipsoidal or
orthometric heights (through the project's geoid), computed in a worker by the same engine as
``prismstation dsm`` (:func:`prismstation.ops.dsm.make_dsm`: semi-global matching of the
three pairs, coarse to fine) with the engine's options: the a-priori height uncertainty of
the prior, void filling, the minimum fill, and the loaded reference DEM as the prior. A
progress dialog whose Cancel button stops the job (nothing is written then); the result
message gives the fill percentage and warns loudly below the minimum fill. The file is
written by :func:`prismstation.io.dsm.write_dsm` (COG with a vertical CRS, mask and
pairs-agreeing bands).
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from PySide6.QtWidgets import (QButtonGroup, QCheckBox, QDialog, QDialogButtonBox, QDoubleSpinBox,
                               QFileDialog, QFormLayout, QHBoxLayout, QLineEdit, QMessageBox,
                               QPushButton, QRadioButton)

from prismstation.gui import settings as st
from prismstation.gui.tools._worker import run_with_progress

TOOL_CONTEXT = True  # install() gets a ToolContext


@dataclass(frozen=True)
class DsmRequest:
    """What to export: ``window`` (col0, row0, cols, rows) N-image pixels or None for all;
    ``height_uncertainty_m`` the a-priori ± of the prior (None: the engine's default);
    ``min_fill_percent`` below which the result warns; ``use_reference``: the loaded
    reference DEM is the prior."""

    path: str
    window: tuple | None
    posting_m: float
    orthometric: bool
    height_uncertainty_m: float | None = None
    fill: bool = False
    min_fill_percent: float = 90.0
    use_reference: bool = False


def visible_window(ctx) -> tuple | None:
    """The N-image window ``(col0, row0, cols, rows)`` visible in the N view, clipped to the
    image (None if nothing of the image is visible). ``ctx``: anything with ``views`` and
    ``project`` (a tool context or the window)."""
    iv = ctx.views.views.get("N")
    if iv is None or ctx.project is None:
        return None
    rows, cols = ctx.project.scene.views["N"].shape
    x, y, w, h = iv.visible_rect()
    c0, r0 = max(int(x), 0), max(int(y), 0)
    c1, r1 = min(int(x + w) + 1, cols), min(int(y + h) + 1, rows)
    if c1 - c0 < 16 or r1 - r0 < 16:
        return None
    return (c0, r0, c1 - c0, r1 - r0)


class DsmDialog(QDialog):
    """File, extent, posting, height kind and the engine's options."""

    def __init__(self, parent, default_path: str, visible: tuple | None, reference: str | None = None):
        super().__init__(parent)
        self.setWindowTitle("Export DSM")
        self.visible = visible
        self.path = QLineEdit(default_path)
        browse = QPushButton("Browse…")
        browse.clicked.connect(self._browse)
        row = QHBoxLayout()
        row.addWidget(self.path, 1)
        row.addWidget(browse)
        self.whole = QRadioButton("whole image")
        self.area = QRadioButton("visible N area" + (f" ({visible[2]} × {visible[3]} px)" if visible else ""))
        self.area.setEnabled(visible is not None)
        (self.area if visible is not None else self.whole).setChecked(True)
        ext = QHBoxLayout()
        ext.addWidget(self.whole)
        ext.addWidget(self.area)
        self.extent_group = QButtonGroup(self)  # two independent choices in one dialog
        self.extent_group.addButton(self.whole)
        self.extent_group.addButton(self.area)
        self.ellipsoidal = QRadioButton("ellipsoidal")
        self.orthometric = QRadioButton("orthometric (geoid)")
        self.ellipsoidal.setChecked(True)
        self.height_group = QButtonGroup(self)
        self.height_group.addButton(self.ellipsoidal)
        self.height_group.addButton(self.orthometric)
        hk = QHBoxLayout()
        hk.addWidget(self.ellipsoidal)
        hk.addWidget(self.orthometric)
        self.posting = QDoubleSpinBox(decimals=1, minimum=2.5, maximum=500.0, singleStep=5.0, suffix=" m")
        self.posting.setValue(5.0)
        self.uncertainty = QDoubleSpinBox(decimals=0, minimum=0.0, maximum=5000.0, singleStep=10.0, suffix=" m")
        self.uncertainty.setSpecialValueText("automatic")   # 0: from the points, or 40 m with a reference
        self.uncertainty.setToolTip("± a-priori height uncertainty of the prior: the coarsest search range")
        self.fill = QCheckBox("fill voids by interpolation (marked 2 in the mask band)")
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

    def request(self) -> DsmRequest:
        return DsmRequest(self.path.text(), self.visible if self.area.isChecked() else None,
                          self.posting.value(), self.orthometric.isChecked(),
                          self.uncertainty.value() or None, self.fill.isChecked(),
                          self.min_fill.value(), self.reference.isEnabled() and self.reference.isChecked())


def result_message(path: str, dsm, min_fill_percent: float) -> tuple[str, bool]:
    """The operator's summary of a written DSM, and whether it filled less than the minimum."""
    fill = 100.0 * dsm.fill_fraction
    seen = int(dsm.seen.sum()) if dsm.seen is not None else 0
    filled = 100.0 * int(((dsm.mask == 2) & dsm.seen).sum()) / max(seen, 1) if dsm.mask is not None else 0.0
    rows, cols = dsm.heights.shape
    text = (f"Wrote {path}: {cols} × {rows} cells at {dsm.posting_m:g} m, {dsm.height_kind} heights; "
            f"{fill:.1f} % of the {seen} cells all three images see matched"
            + (f", {filled:.1f} % filled by interpolation" if filled else ""))
    hm = (dsm.info or {}).get("heights")
    if hm:
        text += f". Heights: {'parallax line' if hm['model'] == 'line' else 'rays through the biases'} ({hm['reason']})"
    low = fill < min_fill_percent
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

    def reference(self):
        """The loaded reference DEM (:class:`~prismstation.ops.reference_heights.DemHeights`) or None."""
        return getattr(self.ctx.solver, "height_of", None)

    def choose(self) -> None:
        if self.ctx.project is None or (self.job is not None and self.job.isRunning()):
            return
        path = getattr(self.ctx.files, "path", None)
        folder = Path(path).parent if path else Path(st.value(st.Key.LAST_IMPORT_DIR) or ".")
        ref = self.reference()
        name = Path(str(getattr(ref, "path", "") or "reference")).name if ref is not None else None
        dlg = DsmDialog(self.ctx.widget, str(folder / "dsm.tif"), visible_window(self.ctx), name)
        if dlg.exec() == QDialog.DialogCode.Accepted and dlg.path.text():
            self.start(dlg.request())

    def start(self, req: DsmRequest):
        """Compute and write the DSM of ``req`` in a worker; returns the Job (result: the Dsm)."""
        from prismstation.io.dsm import write_dsm
        from prismstation.io.project import project_geoid
        from prismstation.ops.dsm import make_dsm
        from prismstation.ops.progress import checkpoint
        sol, p = self.ctx.solver.solution, self.ctx.project
        if sol is None or p is None:
            self.ctx.status("A DSM needs a fitted model", 8000)
            return None
        geoid = project_geoid(p) if req.orthometric else None
        ref = self.reference() if req.use_reference else None
        reference = None if ref is None else (ref.grid.heights, tuple(ref.grid.transform)[:6])

        def work(progress):
            dsm = make_dsm(sol, req.window, posting_m=req.posting_m, orthometric_geoid=geoid,
                           reference=reference, height_uncertainty_m=req.height_uncertainty_m,
                           fill=req.fill, progress=progress)
            checkpoint(progress, 0.99, "writing")
            write_dsm(req.path, dsm)
            if not progress(1.0, "written"):     # cancelled while writing: leave no file
                os.unlink(req.path)
                checkpoint(progress, 1.0)
            return dsm

        def done(dsm):
            self.message, low = result_message(req.path, dsm, req.min_fill_percent)
            self.ctx.status(self.message, 30000 if low else 15000)
            if getattr(self.ctx, "interactive", False):
                (QMessageBox.warning if low else QMessageBox.information)(self.ctx.widget, "DSM", self.message)

        self.job = run_with_progress(self.ctx, "DSM", work, done)
        return self.job


def install(ctx) -> None:
    ctx.tools["dsm"] = DsmTool(ctx)
