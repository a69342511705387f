"""Tools ▸ Export DSM… : dense matching of F and B through the fitted model → GeoTIFF (issue 4 item 3).

The whole N image or the area visible in the N view, at a chosen posting, with ellipsoidal or
orthometric heights (through the project's geoid), computed in a worker
(:func:`prismstation.ops.dsm.make_dsm`: semi-global matching of the three pairs) with a
cancellable progress dialog, written by :func:`prismstation.io.dsm.write_dsm` (COG with a vertical
CRS, mask and pairs-agreeing bands).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from PySide6.QtWidgets import (QButtonGroup, QDialog, QDialogButtonBox, QDoubleSpinBox, QFileDialog,
                               QFormLayout, QHBoxLayout, QLineEdit, QPushButton, QRadioButton)

from prismstation.gui import settings as st
from prismstation.gui.tools._worker import run_with_progress


@dataclass(frozen=True)
class DsmRequest:
    """What to export: ``window`` (col0, row0, cols, rows) N-image pixels or None for all."""

    path: str
    window: tuple | None
    posting_m: float
    orthometric: bool


def visible_window(window) -> tuple | None:
    """The N-image window ``(col0, row0, cols, rows)`` visible in the N view, clipped to the
    image (None if nothing of the image is visible)."""
    iv = window.views.views.get("N")
    if iv is None or window.project is None:
        return None
    rows, cols = window.project.scene.views["N"].shape
    x, y, w, h = iv.visible_rect()
    c0, r0 = max(int(x), 0), max(int(y), 0)
    c1, r1 = min(int(x + w) + 1, cols), min(int(y + h) + 1, rows)
    if c1 - c0 < 16 or r1 - r0 < 16:
        return None
    return (c0, r0, c1 - c0, r1 - r0)


class DsmDialog(QDialog):
    def __init__(self, parent, default_path: str, visible: tuple | None):
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
        self.posting.setValue(10.0)
        form = QFormLayout(self)
        form.addRow("GeoTIFF", row)
        form.addRow("Extent", ext)
        form.addRow("Posting", self.posting)
        form.addRow("Heights", hk)
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
                          self.posting.value(), self.orthometric.isChecked())


class DsmTool:
    def __init__(self, window):
        self.w = window
        self.job = None
        self.a_dsm = window._act("Export &DSM…", self.choose,
                                 tip="Dense matching of F and B through the model → DSM GeoTIFF")
        window.tools_menu.addSeparator()
        window.tools_menu.addAction(self.a_dsm)

    def choose(self) -> None:
        p = self.w.project
        if p is None:
            return
        folder = Path(self.w.files.path).parent if getattr(self.w.files, "path", None) else Path(
            st.value(st.Key.LAST_IMPORT_DIR) or ".")
        dlg = DsmDialog(self.w, str(folder / "dsm.tif"), visible_window(self.w))
        if dlg.exec() == QDialog.DialogCode.Accepted and dlg.path.text():
            self.start(dlg.request())

    def start(self, req: DsmRequest):
        """Compute and write the DSM of ``req`` in a worker; returns the Job (result: the Dsm)."""
        from prismstation.io.dsm import write_dsm
        from prismstation.io.project import project_geoid
        from prismstation.ops.dsm import make_dsm
        sol, p = self.w.solver.solution, self.w.project
        if sol is None or p is None:
            self.w.statusBar().showMessage("A DSM needs a fitted model", 8000)
            return None
        geoid = project_geoid(p) if req.orthometric else None

        def work(progress):
            dsm = make_dsm(sol, req.window, posting_m=req.posting_m, orthometric_geoid=geoid,
                           progress=lambda f, m="": progress(f, m))
            write_dsm(req.path, dsm)
            return dsm

        def done(dsm):
            self.w.statusBar().showMessage(
                f"Wrote {req.path}: {dsm.heights.shape[1]} × {dsm.heights.shape[0]} cells at {req.posting_m:g} m, "
                f"{dsm.height_kind} heights, {dsm.fill_fraction:.1%} of the cells all three images see matched", 15000)

        self.job = run_with_progress(self.w, "DSM", work, done)
        return self.job


def install(window) -> None:
    window.dsm_tool = DsmTool(window)
