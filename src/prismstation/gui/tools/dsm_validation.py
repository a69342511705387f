"""Accuracy assessment in the window (Tadono et al. 2008).

- A "Residual SD" dock: per view, the standard deviation of the image residuals (pixels) of
  the GCPs and of the ICPs of the current Solution (Tadono et al. 2008, Table 1), refreshed after every fit.
- Tools ▸ Validate DSM…: a DSM against a reference DSM (any resolution / CRS, heights of one
  kind through a geoid, optional class mask) with
  :func:`prismstation.ops.validate.validate_dsm_files` in a worker; a "DSM validation" dock
  shows the statistics (overall and per class), the difference map over shaded relief, its
  histogram, and exports the numbers as JSON or CSV.
"""
from __future__ import annotations

from html import escape
import csv
import os
from pathlib import Path

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (QComboBox, QDialog, QDialogButtonBox, QDoubleSpinBox, QFileDialog,
                               QFormLayout, QHBoxLayout, QLabel, QLineEdit, QMessageBox,
                               QPushButton, QSplitter, QStackedWidget, QTableWidget, QTableWidgetItem, QTabWidget,
                               QVBoxLayout, QWidget)

from prismstation.core.surfaces.dsmstats import hillshade, histogram, residual_sd_by_view
from prismstation.errors import PrismError
from prismstation.gui.titles import fit_title
from prismstation.gui.tools._worker import Job, run_with_progress
from prismstation.io.atomic import scratch_file, write_atomic
from prismstation.io.csvtable import text_cell
from prismstation.io.dem import read_dem
from prismstation.io.dsm import recorded_height_kind
from prismstation.io.formatting import fixed
from prismstation.io.geoid import ConstantGeoid, GridGeoid, find_grid
from prismstation.io.georef import crs_name
from prismstation.io.jsonfile import write_json
from prismstation.ops.validate import validate_dsm_files

STAT_COLUMNS = ("count", "bias", "sd", "rmse", "min", "max", "median", "nmad")


def _item(text, left=False) -> QTableWidgetItem:
    it = QTableWidgetItem(text)
    it.setTextAlignment((Qt.AlignmentFlag.AlignLeft if left else Qt.AlignmentFlag.AlignRight)
                        | Qt.AlignmentFlag.AlignVCenter)
    it.setFlags(it.flags() & ~Qt.ItemFlag.ItemIsEditable)
    return it


def _table(cols) -> QTableWidget:
    t = QTableWidget(0, len(cols))
    t.setHorizontalHeaderLabels(list(cols))
    t.verticalHeader().setVisible(False)
    t.verticalHeader().setDefaultSectionSize(22)
    return t


# ---------------------------------------------------------------------- residual SD per view
def residual_sd_rows(solution):
    """``{kind: tuple[ViewResidualSD]}`` for GCP and ICP image residuals of ``solution``."""
    out = {}
    for kind in ("GCP", "ICP"):
        views, res = [], []
        for p in solution.points:
            if p.kind != kind:
                continue
            for v, r in p.residual_px.items():
                views.append(v)
                res.append(r)
        out[kind] = residual_sd_by_view(views, np.array(res, float).reshape(-1, 2)) if views else ()
    return out


class ResidualSDPanel(QWidget):
    HEAD = ("View", "GCP n", "GCP SD x", "GCP SD y", "ICP n", "ICP SD x", "ICP SD y")

    def __init__(self, ctx):
        super().__init__(ctx.widget)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(4, 4, 4, 4)
        title = QLabel("<b>SD of image residuals (px) — as Tadono et al. 2008, Table 1</b>")
        title.setWordWrap(True)  # (a narrow dock cut it)
        lay.addWidget(title)
        self.table = _table(self.HEAD)
        lay.addWidget(self.table)
        self.solution = None
        ctx.solver.solution_changed.connect(self.set_solution)

    def set_solution(self, sol) -> None:
        """Show ``sol``'s figures — only while visible (a hidden dock catches up when shown:
        this runs after every click)."""
        self.solution = sol
        if self.isVisible():
            self._fill()

    def showEvent(self, ev) -> None:
        super().showEvent(ev)
        self._fill()

    def _fill(self) -> None:
        sol = self.solution
        self.table.setRowCount(0)
        if sol is None:
            return
        rows = residual_sd_rows(sol)
        views = list(dict.fromkeys([r.view for k in rows for r in rows[k]]))
        self.table.setRowCount(len(views))
        for i, v in enumerate(views):
            cells = [v]
            for kind in ("GCP", "ICP"):
                r = next((r for r in rows[kind] if r.view == v), None)
                cells += ["0", "—", "—"] if r is None else [str(r.n_points), fixed(r.sd_x, 3), fixed(r.sd_y, 3)]
            for c, text in enumerate(cells):
                self.table.setItem(i, c, _item(text, c == 0))
        self.table.resizeColumnsToContents()


# ---------------------------------------------------------------------- DSM validation
def run_validation(dsm, reference, *, dsm_height="ellipsoidal", reference_height="ellipsoidal",
                   geoid=None, mask=None):
    """Worker body: ``(validation, info, difference (rows, cols) m, shaded relief [0, 1])``."""
    tmp = str(scratch_file("dsmdiff", ".tif"))  # (a killed run's: removed first)
    try:
        val, info = validate_dsm_files(dsm, reference, dsm_height=dsm_height,
                                       reference_height=reference_height, geoid=geoid,
                                       mask_path=mask, diff_out=tmp)
        diff = read_dem(tmp, what="difference").heights
    finally:
        try:
            os.remove(tmp)
        except OSError:
            pass
    info.pop("difference_raster", None)
    grid = read_dem(dsm, what="DSM")
    cell = float(np.sqrt(abs(grid.transform.a * grid.transform.e)))
    relief = hillshade(grid.heights, cell) if min(grid.shape) >= 2 else np.ones(grid.shape)
    return val, info, diff, relief


def shaded_difference(diff, relief, limit=None) -> np.ndarray:
    """RGB (rows, cols, 3) uint8: ``diff`` on a blue–white–red scale of ±``limit`` metres
    (default its 98th |d| percentile), darkened by the shaded ``relief``; no data grey."""
    ok = np.isfinite(diff)
    if limit is None:
        limit = float(np.percentile(np.abs(diff[ok]), 98)) if ok.any() else 1.0
    limit = max(limit, 1e-6)
    cmap = pg.ColorMap([0.0, 0.5, 1.0], [(33, 102, 172), (247, 247, 247), (178, 24, 43)])
    t = np.clip((np.where(ok, diff, 0.0) / limit + 1) / 2, 0, 1)
    rgb = cmap.map(t.ravel(), mode="float")[:, :3].reshape(diff.shape + (3,))
    fin = np.isfinite(relief)
    shade = np.ones(diff.shape)
    if fin.any():   # stretch the relief to its 2–98 % range so gentle terrain still shows
        lo, hi = np.percentile(relief[fin], [2, 98])
        shade = np.where(fin, np.clip((relief - lo) / max(hi - lo, 1e-6), 0, 1), 1.0)
    rgb = rgb * (0.3 + 0.7 * shade)[..., None]
    rgb[~ok] = 0.5
    return np.clip(rgb * 255, 0, 255).astype(np.uint8)


def prefill(project, project_path, last: dict, exported: str | None = None) -> dict:
    """What the dialog starts from: the DSM the window ``exported`` last (when given: since the
    last validation), the last run's choices, else the project's — its DSM (``<project>_dsm.tif``,
    the DSM tool's default, or ``dsm.tif`` beside the project or the scene), its reference DEM
    (SRTM-like: orthometric where the file does not say) and its geoid (a grid's path, or the
    constant). The heights' kinds the files record are read by the dialog."""
    out = {"dsm_height": "ellipsoidal", "reference_height": "ellipsoidal", "geoid_constant": 0.0}
    if project is not None:
        folders = [Path(p).parent for p in (project_path, project.scene_path) if p]
        named = [Path(project_path).with_name(f"{Path(project_path).stem}_dsm.tif")] if project_path else []
        for cand in named + [f / "dsm.tif" for f in folders]:
            if cand.is_file():
                out["dsm"] = str(cand)
                break
        if project.reference_dem:
            out.update(reference=project.reference_dem, reference_height="orthometric")
        g = project.geoid or {}
        if g.get("kind") == "grid":
            grid = Path(g.get("path", ""))
            out["geoid_grid"] = str(grid if grid.is_absolute() or not folders else folders[-1] / grid)
        elif g.get("kind") == "auto":
            grid = find_grid()
            out.update({"geoid_grid": str(grid)} if grid else {"geoid_constant": float(g.get("value") or 0.0)})
        elif g.get("value") is not None:
            out["geoid_constant"] = float(g["value"])
    out = {**out, **{k: v for k, v in last.items() if v not in ("", None)}}
    if exported:
        out["dsm"] = str(exported)
    return out


class DsmDialog(QDialog):
    def __init__(self, parent, last: dict):
        super().__init__(parent)
        self.setWindowTitle("Validate DSM")
        fit_title(self)
        f = QFormLayout(self)
        self.paths = {}
        for key, label in (("dsm", "DSM"), ("reference", "Reference DSM"), ("mask", "Class mask (optional)"),
                           ("geoid_grid", "Geoid grid (optional)")):
            e = QLineEdit(last.get(key, ""))
            b = QPushButton("…")
            b.clicked.connect(lambda *_, e=e, t=label: self._browse(e, t))
            row = QHBoxLayout()
            row.addWidget(e, 1)
            row.addWidget(b)
            f.addRow(label, row)
            self.paths[key] = e
        self.kinds, self.kind_notes = {}, {}
        for key, label in (("dsm_height", "DSM heights"), ("reference_height", "Reference heights")):
            c = QComboBox()
            c.addItems(["ellipsoidal", "orthometric"])
            c.setCurrentText(last.get(key, "ellipsoidal"))
            note = QLabel("")
            note.setStyleSheet("color: #555")
            row = QHBoxLayout()
            row.addWidget(c)
            row.addWidget(note, 1)
            f.addRow(label, row)
            self.kinds[key], self.kind_notes[key] = c, note
        for path_key, kind_key in (("dsm", "dsm_height"), ("reference", "reference_height")):
            self.paths[path_key].textChanged.connect(lambda text, k=kind_key: self._kind_from_file(k, text))
            self._kind_from_file(kind_key, self.paths[path_key].text())
        self.geoid_constant = QDoubleSpinBox()
        self.geoid_constant.setRange(-200, 200)
        self.geoid_constant.setDecimals(3)
        self.geoid_constant.setSuffix(" m")
        self.geoid_constant.setValue(last.get("geoid_constant", 0.0))
        f.addRow("Geoid undulation (no grid)", self.geoid_constant)
        bb = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel)
        bb.accepted.connect(self.accept)
        bb.rejected.connect(self.reject)
        f.addRow(bb)

    def _kind_from_file(self, key: str, path: str) -> None:
        """The heights' kind as the file records it (a DSM written here does: its vertical CRS),
        shown and not asked; where the file does not say, the operator chooses."""
        path = path.strip()
        kind = recorded_height_kind(path) if path and Path(path).is_file() else None
        combo, note = self.kinds[key], self.kind_notes[key]
        if kind is not None:
            combo.setCurrentText(kind)
        combo.setEnabled(kind is None)
        note.setText("recorded in the file" if kind is not None else
                     "the file does not say: choose" if path else "")

    def _browse(self, edit, title) -> None:
        p, _ = QFileDialog.getOpenFileName(self, title, edit.text(), "Rasters (*.tif *.tiff *.img *.vrt);;All (*)")
        if p:
            edit.setText(p)

    def values(self) -> dict:
        out = {k: e.text().strip() for k, e in self.paths.items()}
        out.update({k: c.currentText() for k, c in self.kinds.items()})
        out["geoid_constant"] = self.geoid_constant.value()
        return out


class DsmResultPanel(QWidget):
    """The statistics (title, table, colour scale, export buttons) and the two plots (the
    difference map, its histogram): the statistics above the plots side by side where the dock
    is tall, one tab each where it is short (a bottom dock on a laptop squeezed the plots to
    nothing, then to slivers)."""

    COMPACT_HEIGHT = 420  # px: below this the three parts go in tabs

    def __init__(self, parent=None):
        super().__init__(parent)
        self.validation = self.info = self.diff = None
        self.stats = QWidget()
        lay = QVBoxLayout(self.stats)
        lay.setContentsMargins(0, 0, 0, 0)
        self.title = QLabel("No DSM validated yet (Tools ▸ Validate DSM…)")
        self.title.setWordWrap(True)
        lay.addWidget(self.title)
        self.table = _table(("Cells",) + STAT_COLUMNS)
        self.table.setFixedHeight(66)  # the header and a row (then: its rows, at most 130 px)
        lay.addWidget(self.table)
        self.map = pg.PlotWidget()
        self.map.setTitle("DSM − reference over shaded relief", size="9pt")
        self.map.setAspectLocked(True)
        self.map.invertY(True)
        self.map_item = pg.ImageItem(axisOrder="row-major")
        self.map.addItem(self.map_item)
        self.hist = pg.PlotWidget()
        self.hist.setTitle("Histogram of DSM − reference", size="9pt")
        self.hist.setLabel("bottom", "difference (m)")
        self.hist.setLabel("left", "cells")
        for p in (self.map, self.hist):
            p.setBackground("w")
            p.setMinimumSize(160, 130)
        row = QHBoxLayout()
        self.legend = QLabel("")
        row.addWidget(self.legend, 1)
        self.b_json = QPushButton("Export JSON…")
        self.b_csv = QPushButton("Export CSV…")
        self.b_json.clicked.connect(lambda: self._export("json"))
        self.b_csv.clicked.connect(lambda: self._export("csv"))
        for b in (self.b_json, self.b_csv):
            b.setEnabled(False)
            row.addWidget(b)
        lay.addLayout(row)
        lay.addStretch(1)
        self.full = QWidget()
        full = QVBoxLayout(self.full)
        full.setContentsMargins(0, 0, 0, 0)
        self.split = QSplitter(Qt.Orientation.Horizontal)
        full.addWidget(self.split, 1)
        self.tabs = QTabWidget()
        self.tabs.setDocumentMode(True)
        self._stack = QStackedWidget()
        self._stack.addWidget(self.full)
        self._stack.addWidget(self.tabs)
        outer = QVBoxLayout(self)
        outer.setContentsMargins(4, 4, 4, 4)
        outer.addWidget(self._stack)
        self._compact = None
        self._arrange(False)

    def _arrange(self, compact: bool) -> None:
        """The three parts in tabs (``compact``) or the statistics above the two plots."""
        if compact == self._compact:
            return
        self._compact = compact
        if compact:
            for w, name in ((self.stats, "Statistics"), (self.map, "Difference map"), (self.hist, "Histogram")):
                self.tabs.addTab(w, name)
        else:
            self.tabs.clear()  # (the pages are kept: they move back)
            self.full.layout().insertWidget(0, self.stats)
            self.split.addWidget(self.map)
            self.split.addWidget(self.hist)
            for w in (self.stats, self.map, self.hist):
                w.show()
        self._stack.setCurrentWidget(self.tabs if compact else self.full)

    def resizeEvent(self, ev) -> None:
        """Judged on what the dock shows (its scroll area's viewport), not on this panel."""
        super().resizeEvent(ev)
        area = self.parentWidget() if self.parentWidget() is not None else self
        self._arrange(area.height() < self.COMPACT_HEIGHT)

    def rows(self):
        """``[(label, DiffStats)]``: overall first, then one per class."""
        v = self.validation
        return [("all", v.overall)] + [(f"class {k}", s) for k, s in sorted(v.per_class.items())]

    def show_result(self, val, info, diff, relief) -> None:
        self.validation, self.info, self.diff = val, info, diff
        self.title.setText(f"<b>{escape(os.path.basename(info['dsm']))}</b> − "
                           f"<b>{escape(os.path.basename(info['reference']))}</b>"
                           f" on the DSM grid ({info['grid']['width']} × {info['grid']['height']}, "
                           f"{crs_name(info['grid']['crs'])}), heights {info['heights']['compared_as']}")
        pct = sorted(val.overall.percentiles)
        head = ["Cells"] + list(STAT_COLUMNS) + [f"P{p:g}" for p in pct]
        self.table.clear()
        self.table.setColumnCount(len(head))
        self.table.setHorizontalHeaderLabels(head)
        rows = self.rows()
        self.table.setRowCount(len(rows))
        for i, (label, s) in enumerate(rows):
            cells = [label, str(s.count)] + [fixed(getattr(s, k), 3) for k in STAT_COLUMNS[1:]] \
                + [fixed(s.percentiles.get(p, float("nan")), 3) for p in pct]
            for c, text in enumerate(cells):
                self.table.setItem(i, c, _item(text, c == 0))
        self.table.resizeColumnsToContents()
        t = self.table  # as tall as its rows (with room for the side scroll bar), no taller
        need = (t.horizontalHeader().height() + sum(t.rowHeight(i) for i in range(t.rowCount()))
                + 2 * t.frameWidth() + t.horizontalScrollBar().sizeHint().height())
        t.setFixedHeight(min(need, 130))
        ok = np.isfinite(diff)
        limit = float(np.percentile(np.abs(diff[ok]), 98)) if ok.any() else 1.0
        self.map_item.setImage(shaded_difference(diff, relief, limit))
        self.map.autoRange()
        self.legend.setText(f"<span style='color:#2166ac'>■</span> −{limit:.2f} m … "
                            f"<span style='color:#b2182b'>■</span> +{limit:.2f} m")
        counts, edges = histogram(diff, bins=60)
        self.hist.clear()
        self.hist.addItem(pg.BarGraphItem(x0=edges[:-1], x1=edges[1:], height=counts,
                                          brush=(70, 110, 170), pen=(40, 60, 100)))
        self.hist.addItem(pg.InfiniteLine(val.overall.bias, pen=pg.mkPen("#b2182b", width=2),
                                          label=f"bias {val.overall.bias:.2f} m",
                                          labelOpts={"position": 0.9, "color": "#b2182b"}))
        for b in (self.b_json, self.b_csv):
            b.setEnabled(True)

    def _export(self, kind: str) -> None:
        p, _ = QFileDialog.getSaveFileName(self, "Export DSM validation", f"dsm_validation.{kind}",
                                           f"{kind.upper()} (*.{kind})")
        if p:
            try:
                self.export(p, kind)
            except (PrismError, OSError) as exc:  # a full disk, a folder that cannot be written
                QMessageBox.warning(self, "Export DSM validation", str(exc))

    def export(self, path, kind: str | None = None) -> None:
        """Write the statistics as JSON (with the inputs) or CSV (one row per cell set),
        atomically (a failure is a ``WriteError``, no file)."""
        import io

        kind = kind or ("csv" if str(path).lower().endswith(".csv") else "json")
        if kind == "json":
            write_json(path, {"validation": self.validation.as_dict(), "inputs": self.info})
            return
        pct = sorted(self.validation.overall.percentiles)
        apct = sorted(self.validation.overall.abs_percentiles)
        buf = io.StringIO(newline="")
        w = csv.writer(buf)
        w.writerow(["cells"] + list(STAT_COLUMNS) + [f"p{p:g}" for p in pct]
                   + [f"abs_p{p:g}" for p in apct])
        for label, s in self.rows():
            w.writerow([text_cell(label)] + [getattr(s, k) for k in STAT_COLUMNS]
                       + [s.percentiles[p] for p in pct] + [s.abs_percentiles[p] for p in apct])
        write_atomic(path, buf.getvalue(), keep_backup=False)


class DsmValidationTool:
    def __init__(self, ctx):
        self.ctx = ctx
        self.sd_panel = ResidualSDPanel(ctx)
        self.sd_dock = ctx.add_dock("residual_sd", "Residual SD", self.sd_panel,
                                    Qt.DockWidgetArea.RightDockWidgetArea)
        self.panel = DsmResultPanel(ctx.widget)
        self.dock = ctx.add_dock("dsm_validation", "DSM validation", self.panel,
                                 Qt.DockWidgetArea.BottomDockWidgetArea)
        self.dock.hide()
        self.job: Job | None = None
        self.last: dict = {}
        ctx.tools_menu.addAction("Validate DSM…", self.open_dialog)
        ctx.tools_menu.addAction(self.sd_dock.toggleViewAction())
        ctx.tools_menu.addAction(self.dock.toggleViewAction())

    def open_dialog(self) -> None:
        exported = self.ctx.outputs.pop("dsm", None)  # written since the last validation: offered once
        d = DsmDialog(self.ctx.widget, prefill(self.ctx.project, self.ctx.files.path, self.last, exported))
        if d.exec() == QDialog.DialogCode.Accepted:
            self.start(**d.values())

    def start(self, dsm, reference, dsm_height="ellipsoidal", reference_height="ellipsoidal",
              mask="", geoid_grid="", geoid_constant=0.0, progress_dialog=True) -> Job | None:
        """Validate in a worker (returns the Job); the result appears in the "DSM validation" dock."""

        self.last = dict(dsm=dsm, reference=reference, dsm_height=dsm_height,
                         reference_height=reference_height, mask=mask, geoid_grid=geoid_grid,
                         geoid_constant=geoid_constant)
        if not dsm or not reference:
            self.ctx.status("Validate DSM: choose a DSM and a reference", 10000)
            return None
        geoid = None
        if dsm_height != reference_height:
            geoid = GridGeoid(geoid_grid) if geoid_grid else ConstantGeoid(float(geoid_constant))
        self.job = run_with_progress(
            self.ctx, "Validate DSM",
            lambda progress: run_validation(dsm, reference, dsm_height=dsm_height,
                                            reference_height=reference_height, geoid=geoid,
                                            mask=mask or None),
            self._done, on_failed=self._failed, dialog=progress_dialog)
        return self.job

    def _failed(self, error: str) -> None:
        self.panel.title.setText(f"<span style='color:#b91c1c'>Validation failed: {escape(error)}</span>")
        self.dock.show()

    def _done(self, result) -> None:
        self.panel.show_result(*result)
        self.dock.show()
        self.dock.raise_()
        o = result[0].overall
        self.ctx.status(
            f"DSM − reference: bias {o.bias:.2f} m, SD {o.sd:.2f} m, RMSE {o.rmse:.2f} m, "
            f"NMAD {o.nmad:.2f} m over {o.count} cells", 15000)


def install(ctx) -> None:
    ctx.tools["dsm_validation"] = DsmValidationTool(ctx)
