"""Tools ▸ Orthoimage…: the views' orthoimages through the fitted model, made in a worker by the
same export as ``prismstation ortho`` (:func:`prismstation.ops.ortho.export_orthos`), and a dock
that shows an ortho with the project's points on it.

The dialog takes the views, the heights (the loaded reference DEM, a DEM or DSM file, or a
constant height), the DEM's height kind, the extent (each whole image, or the ground under the
part of the reference view on screen), the posting and the kernel. A progress dialog whose
Cancel stops the job (nothing is written then); the result message gives each file and its
expected planimetric accuracy.

The *Orthoimage* dock shows an ortho (one of those just made, or any opened) with every point
of known ground at its known position — GCPs and ICPs in their colours, labelled — so that where
the ortho is off shows at a glance; *Check at the points* runs
:func:`prismstation.ops.ortho_validate.validate_ortho` in a worker and draws, for each point, an
arrow from its known position to where the ortho shows it (exaggerated by the factor shown), and
the RMSE per kind beside the ortho's expected accuracy.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pyqtgraph as pg
from PySide6.QtWidgets import (QAbstractSpinBox, QButtonGroup, QCheckBox, QComboBox, QDialog,
                               QDialogButtonBox, QDoubleSpinBox, QFileDialog, QFormLayout, QHBoxLayout,
                               QLabel, QLineEdit, QMessageBox, QPushButton, QRadioButton, QVBoxLayout, QWidget)

from prismstation.errors import PrismError
from prismstation.gui import settings as st
from prismstation.gui.image_view import ImageView
from prismstation.gui.markers import Markers
from prismstation.gui.overlays import MEASURED_SYMBOL, Curve, LabelLayer
from prismstation.gui.palette import BLUNDER_RGB, qcolor
from prismstation.gui.tools._worker import run_with_progress
from prismstation.gui.tools.dsm_tool import visible_window
from prismstation.io.ortho import read_ortho_info
from prismstation.io.raster import RasterSource
from prismstation.ops.ortho import DEM_KINDS, RESAMPLINGS, OrthoRequest, default_posting, export_orthos
from prismstation.ops.ortho_validate import validate_ortho
from prismstation.ops.predict import known_ground

DEM_KIND_NAMES = {"auto": "as the file says (else orthometric)", "orthometric": "orthometric (above the geoid)",
                  "ellipsoidal": "ellipsoidal"}


class OrthoDialog(QDialog):
    """File, views, heights, extent, posting and kernel."""

    def __init__(self, parent, default_path: str, views, reference_view: str, visible: tuple | None,
                 reference: str | None, posting: float):
        super().__init__(parent)
        self.setWindowTitle("Orthoimage")
        self.visible = visible
        self.path = QLineEdit(default_path)
        browse = QPushButton("Browse…")
        browse.clicked.connect(self._browse)
        row = QHBoxLayout()
        row.addWidget(self.path, 1)
        row.addWidget(browse)
        self.views = {}
        vrow = QHBoxLayout()
        for v in views:
            cb = QCheckBox(v)
            cb.setChecked(v == reference_view)
            self.views[v] = cb
            vrow.addWidget(cb)
        vrow.addStretch(1)
        self.use_reference = QRadioButton(f"the loaded reference DEM ({reference})" if reference
                                          else "the loaded reference DEM (none loaded)")
        self.use_reference.setEnabled(reference is not None)
        self.use_file = QRadioButton("a DEM or DSM file")
        self.use_constant = QRadioButton("a constant height (relief then moves the ortho sideways)")
        self.source_group = QButtonGroup(self)
        for b in (self.use_reference, self.use_file, self.use_constant):
            self.source_group.addButton(b)
        (self.use_reference if reference is not None else self.use_file).setChecked(True)
        self.dem_path = QLineEdit()
        self.dem_path.setPlaceholderText("the project's DSM, SRTM, Copernicus…")
        dem_browse = QPushButton("Browse…")
        dem_browse.clicked.connect(self._browse_dem)
        frow = QHBoxLayout()
        frow.addWidget(self.use_file)
        frow.addWidget(self.dem_path, 1)
        frow.addWidget(dem_browse)
        self.height = QDoubleSpinBox(decimals=1, minimum=-500.0, maximum=9000.0, singleStep=10.0, suffix=" m")
        self.height.setToolTip("orthometric height (above the geoid) of every cell")
        crow = QHBoxLayout()
        crow.addWidget(self.use_constant)
        crow.addWidget(self.height)
        self.dem_kind = QComboBox()
        for k in DEM_KINDS:
            self.dem_kind.addItem(DEM_KIND_NAMES[k], k)
        self.whole = QRadioButton("each whole image")
        self.area = QRadioButton(f"the visible {reference_view} area"
                                 + (f" ({visible[2]} × {visible[3]} px)" if visible else ""))
        self.area.setEnabled(visible is not None)
        self.whole.setChecked(True)
        self.extent_group = QButtonGroup(self)
        self.extent_group.addButton(self.whole)
        self.extent_group.addButton(self.area)
        erow = QHBoxLayout()
        erow.addWidget(self.whole)
        erow.addWidget(self.area)
        self.posting = QDoubleSpinBox(decimals=2, minimum=0.05, maximum=500.0, singleStep=0.5, suffix=" m")
        self.posting.setCorrectionMode(QAbstractSpinBox.CorrectionMode.CorrectToNearestValue)
        self.posting.setValue(posting)
        self.resampling = QComboBox()
        self.resampling.addItems(RESAMPLINGS)
        self.show_result = QCheckBox("show it with the project's points")
        self.show_result.setChecked(True)
        form = QFormLayout(self)
        form.addRow("GeoTIFF", row)
        form.addRow("Views", vrow)
        heights = QVBoxLayout()
        heights.addWidget(self.use_reference)
        heights.addLayout(frow)
        heights.addLayout(crow)
        form.addRow("Heights", heights)
        form.addRow("DEM heights", self.dem_kind)
        form.addRow("Extent", erow)
        form.addRow("Posting", self.posting)
        form.addRow("Resampling", self.resampling)
        form.addRow("", self.show_result)
        bb = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel)
        bb.accepted.connect(self.accept)
        bb.rejected.connect(self.reject)
        form.addRow(bb)
        self.reference = reference

    def _browse(self) -> None:
        p, _ = QFileDialog.getSaveFileName(self, "Orthoimage GeoTIFF", self.path.text(), "GeoTIFF (*.tif *.tiff)")
        if p:
            self.path.setText(p)

    def _browse_dem(self) -> None:
        p, _ = QFileDialog.getOpenFileName(self, "DEM or DSM", self.dem_path.text(),
                                           "Rasters (*.tif *.tiff *.hgt *.dem *.img);;All files (*)")
        if p:
            self.dem_path.setText(p)
            self.use_file.setChecked(True)

    def request(self, reference_path: str | None = None) -> OrthoRequest:
        """The :class:`~prismstation.ops.ortho.OrthoRequest` of the dialog; ``reference_path``
        the loaded reference DEM's file."""
        views = tuple(v for v, cb in self.views.items() if cb.isChecked()) or None
        dem = height = None
        if self.use_reference.isChecked():
            dem = reference_path
        elif self.use_file.isChecked():
            dem = self.dem_path.text().strip() or None
        else:
            height = self.height.value()
        return OrthoRequest(self.path.text(), views, dem, self.dem_kind.currentData(), None, height,
                            self.posting.value(), self.visible if self.area.isChecked() else None,
                            self.resampling.currentText())


def result_message(out) -> str:
    """The operator's summary of :class:`~prismstation.ops.ortho.OrthoExport`."""
    lines = []
    for o in out.orthos:
        a = o.accuracy
        acc = (f"expected accuracy {a.expected_sigma_m:.2f} m" if a.expected_sigma_m is not None
               else "expected accuracy unknown")
        lines.append(f"Wrote {o.path}: view {o.view}, {o.shape[1]} × {o.shape[0]} cells at "
                     f"{abs(o.transform[0]):g} m, {o.valid_percent:.0f} % with data; {acc}")
    lines += [f"Warning: {w}" for w in out.warnings]
    return "\n".join(lines)


class OrthoViewer(QWidget):
    """An ortho on screen with the project's points at their known ground positions, and the
    check of the ortho at them (module docstring)."""

    def __init__(self, tool):
        super().__init__(tool.ctx.widget)
        self.tool = tool
        self.path: str | None = None
        self.info: dict | None = None
        self.source: RasterSource | None = None
        self.validation = None
        lay = QVBoxLayout(self)
        lay.setContentsMargins(4, 4, 4, 4)
        row = QHBoxLayout()
        self.choice = QComboBox()
        self.choice.currentIndexChanged.connect(lambda i: self.show_ortho(self.choice.itemData(i)))
        open_button = QPushButton("Open…")
        open_button.clicked.connect(self._open)
        self.check = QPushButton("Check at the points")
        self.check.setToolTip("Where the ortho shows each GCP and ICP against its known position")
        self.check.clicked.connect(self.validate)
        row.addWidget(self.choice, 1)
        row.addWidget(open_button)
        row.addWidget(self.check)
        lay.addLayout(row)
        self.view = ImageView(self)
        lay.addWidget(self.view, 1)
        self.summary = QLabel("")
        self.summary.setWordWrap(True)
        lay.addWidget(self.summary)
        self.points = {k: Markers(MEASURED_SYMBOL, 19, pg.mkPen(qcolor(k), width=2)) for k in ("GCP", "ICP")}
        self.missing = Markers("x", 13, pg.mkPen(qcolor(BLUNDER_RGB), width=2))
        self.arrows = {k: Curve(connect="pairs", pen=pg.mkPen(qcolor(k), width=2)) for k in ("GCP", "ICP")}
        self.labels = LabelLayer()
        for z, item in enumerate([*self.arrows.values(), *self.points.values(), self.missing, self.labels]):
            item.setZValue(20 + z)
            self.view.vb.addItem(item)
        self.exaggeration = 1.0

    # ------------------------------------------------------------------ orthos
    def set_orthos(self, paths) -> None:
        """Offer ``paths`` (the first shown)."""
        self.choice.blockSignals(True)
        self.choice.clear()
        for p in paths:
            self.choice.addItem(Path(p).name, str(p))
        self.choice.blockSignals(False)
        if paths:
            self.show_ortho(str(paths[0]))

    def _open(self) -> None:
        p, _ = QFileDialog.getOpenFileName(self, "Orthoimage", str(Path(self.path).parent) if self.path else "",
                                           "GeoTIFF (*.tif *.tiff)")
        if p:
            self.choice.addItem(Path(p).name, p)
            self.choice.setCurrentIndex(self.choice.count() - 1)

    def show_ortho(self, path) -> None:
        """Show the ortho at ``path`` with the project's points on it (a file that is no ortho of
        prismstation is said in the status bar)."""
        if not path:
            return
        try:
            info = read_ortho_info(path)
            source = RasterSource(path)
        except PrismError as exc:
            self.tool.ctx.status(str(exc), 10000)
            return
        self.release()
        self.path, self.info, self.source, self.validation = str(path), info, source, None
        self.view.set_source(source)
        self.refresh_points()
        tags = info["tags"]
        exp = tags.get("ORTHO_EXPECTED_SIGMA_M", "unknown")
        self.summary.setText(f"{Path(path).name}: view {tags.get('ORTHO_VIEW', '?')} on "
                             f"{tags.get('ORTHO_DEM', 'unknown heights')}; expected planimetric accuracy "
                             f"{exp}{' m' if exp != 'unknown' else ''}")

    def to_cells(self, en) -> np.ndarray:
        """Ortho pixel ``(x, y)`` ``(n, 2)`` of map points ``en``."""
        a, _, c, _, e, f = self.info["transform"]
        en = np.asarray(en, float).reshape(-1, 2)
        return np.column_stack([(en[:, 0] - c) / a, (en[:, 1] - f) / e])

    def refresh_points(self) -> None:
        """The project's points of known ground at their known positions (and the check's arrows,
        when there is one)."""
        project = self.tool.ctx.project
        for m in (*self.points.values(), self.missing):
            m.clear()
        for c in self.arrows.values():
            c.setData([], [])
        if self.info is None or project is None:
            self.labels.set_labels([])
            return
        ground = known_ground(project)
        labels = []
        for kind, m in self.points.items():
            ids = [pid for pid in ground if project.points[pid].kind == kind]
            xy = self.to_cells([ground[pid][:2] for pid in ids]) if ids else np.zeros((0, 2))
            m.setData(xy)
            labels += [(x, y, pid, qcolor(kind)) for (x, y), pid in zip(xy, ids)]
        self.labels.set_labels(labels)
        if self.validation is not None:
            self._draw_check()

    def _draw_check(self) -> None:
        v = self.validation
        found = [p for p in v.points if p.found]
        d = max([float(np.hypot(*p.d)) for p in found] + [1e-6])
        # the largest arrow about 40 cells long, by a round factor
        k = max(1.0, 10.0 ** np.floor(np.log10(max(40.0 * v.posting_m / d, 1.0))))
        self.exaggeration = k
        for kind, curve in self.arrows.items():
            pts = [p for p in found if p.kind == kind]
            if not pts:
                curve.setData([], [])
                continue
            a = self.to_cells([p.known for p in pts])
            b = self.to_cells([np.add(p.known, k * np.asarray(p.d)) for p in pts])
            seg = np.empty((2 * len(pts), 2))
            seg[0::2], seg[1::2] = a, b
            curve.setData(seg[:, 0], seg[:, 1])
        gone = [p for p in v.points if not p.found]
        self.missing.setData(self.to_cells([p.known for p in gone]) if gone else np.zeros((0, 2)))
        parts = [f"{kind} {s['rmse_m']:.2f} m RMS ({s['n']})" + (f", {s['not_found']} not found" if s["not_found"] else "")
                 for kind, s in v.stats.items() if s["n"] or s["not_found"]]
        exp = "unknown" if v.expected_sigma_m is None else f"{v.expected_sigma_m:.2f} m"
        self.summary.setText(f"View {v.view}, where the ortho shows the points: " + "; ".join(parts)
                             + f" — expected {exp}. Arrows × {k:g}.")

    def validate(self):
        """Check the shown ortho at the project's GCPs and ICPs in a worker; returns the Job."""
        sol, p, path = self.tool.ctx.solver.solution, self.tool.ctx.project, self.path
        if sol is None or p is None or path is None:
            self.tool.ctx.status("Checking an ortho needs a fitted model and an ortho shown", 8000)
            return None

        def done(val):
            if self.path == path:
                self.validation = val
                self._draw_check()
        self.job = run_with_progress(self.tool.ctx, "Ortho check",
                                     lambda progress: validate_ortho(sol, p, path, progress=progress), done)
        return self.job

    def release(self) -> None:
        """Let go of the shown ortho (its file handles closed)."""
        self.view.set_source(None)
        if self.source is not None:
            self.source.close()
        self.source = self.path = self.info = self.validation = None


class OrthoTool:
    """The Orthoimage action, its job and its dock (one per window)."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.job = None
        self.message = ""          # the last result message (for scripts and tests)
        self.viewer = OrthoViewer(self)
        self.dock = ctx.add_dock("ortho", "Orthoimage", self.viewer)
        self.action = ctx.add_action("&Orthoimage…", self.choose,
                                     tip="Each view resampled through the fitted model onto a DEM → GeoTIFF")
        ctx.tools_menu.addAction(self.action)
        ctx.files.project_opened.connect(lambda *_: self._project_opened())
        ctx.solver.solution_changed.connect(lambda *_: self._solution_changed())

    def _project_opened(self) -> None:
        self.viewer.release()
        self.viewer.set_orthos([])
        self.viewer.refresh_points()

    def _solution_changed(self) -> None:
        if self.viewer.validation is not None:      # a check of an older fit is not shown
            self.viewer.validation = None
            self.viewer.summary.setText("")
        if self.viewer.info is not None:
            self.viewer.refresh_points()

    def reference(self):
        """The loaded reference DEM (:class:`~prismstation.ops.reference_heights.DemHeights`) or None."""
        return getattr(self.ctx.solver, "height_of", None)

    def default_path(self) -> Path:
        """Beside the project file (``<project>_ortho.tif``), else beside the scene, else the
        last import folder."""
        p, path = self.ctx.project, self.ctx.files.path
        if path:
            return Path(path).with_name(f"{Path(path).stem}_ortho.tif")
        if p is not None and p.scene_path:
            return Path(p.scene_path).with_name("ortho.tif")
        return Path(st.value(st.Key.LAST_IMPORT_DIR) or ".") / "ortho.tif"

    def choose(self) -> None:
        p = self.ctx.project
        if p is None or (self.job is not None and self.job.isRunning()):
            return
        ref = self.reference()
        name = Path(str(getattr(ref, "path", "") or "reference")).name if ref is not None else None
        scene = p.scene
        dlg = OrthoDialog(self.ctx.widget, str(self.default_path()), list(scene.views), scene.reference_view,
                          visible_window(self.ctx, scene.reference_view), name, default_posting(scene))
        if dlg.exec() == QDialog.DialogCode.Accepted and dlg.path.text():
            self.start(dlg.request(str(ref.path) if ref is not None and getattr(ref, "path", None) else None),
                       show=dlg.show_result.isChecked())

    def start(self, req: OrthoRequest, *, show: bool = True):
        """Make and write the orthos of ``req`` in a worker; returns the Job (result: the
        :class:`~prismstation.ops.ortho.OrthoExport`). ``show``: the first in the dock after."""
        sol, p = self.ctx.solver.solution, self.ctx.project
        if sol is None or p is None:
            self.ctx.status("An orthoimage needs a fitted model", 8000)
            return None
        path = self.ctx.files.path

        def work(progress):
            return export_orthos(sol, p, req, project_path=path, progress=progress)

        def done(out):
            self.message = result_message(out)
            self.ctx.status(self.message.splitlines()[0], 15000)
            if show:
                self.viewer.set_orthos([o.path for o in out.orthos])
                self.dock.show()
                self.dock.raise_()
            if self.ctx.interactive:
                (QMessageBox.warning if out.warnings else QMessageBox.information)(
                    self.ctx.widget, "Orthoimage", self.message)

        self.job = run_with_progress(self.ctx, "Orthoimage", work, done)
        return self.job

    def shutdown(self) -> None:
        """The window is closing: the shown ortho's files are let go."""
        self.viewer.release()


def install(ctx) -> None:
    ctx.tools["ortho"] = OrthoTool(ctx)
