"""Live plots of a fitted :class:`~prismstation.core.models.solution.Solution`.

Four pyqtgraph plots in a 2 × 2 grid, each a ``pg.PlotWidget`` whose items are created once and
only get new data on :meth:`PlotsWidget.set_solution` (no rebuilding):

(a) ellipsoidal height of GCPs and ICPs vs F−B parallax with the fitted and the theoretical
    parallax line (Gonçalves 2008, Fig. 4);
(b) height minus the theoretical prediction ``c1_theory·py`` vs parallax with the fitted line
    in the same form (Fig. 5);
(c) residual vectors (measured − predicted) in the image space of the reference view (N),
    exaggerated, drawn from the measured position (x = column, y = row, pixels, y down);
(d) standardised residual of each GCP (on the normal scale) against the one blunder threshold
    ``Settings.blunder_threshold``; the blunders magenta.

The live widget lays them out with the residual vectors (square: x and y at one scale) at the
right, two rows tall, and names the symbols once, in the bar below the plots: legends inside
the plots covered their data.

The same drawing serves the report writer: :class:`PlotData` is built from a Solution or from
the report dict of :func:`prismstation.io.report.report_dict`.
"""
from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtWidgets import (QCheckBox, QComboBox, QDoubleSpinBox, QGridLayout, QHBoxLayout, QLabel,
                               QStackedWidget, QTabWidget, QVBoxLayout, QWidget)

from prismstation.gui.fit_checks import alpha_of
from prismstation.gui.markers import Scatter
from prismstation.gui.plain import plain_block
from prismstation.gui.palette import BLUNDER_RGB, FIT_RGB, KIND_RGB, THEORY_RGB, qcolor
from prismstation.gui.plot_data import PlotData, auto_exaggeration, blunder_text, data_ranges, line_x, segments
from prismstation.gui.plot_figures import legend_below
from prismstation.gui.text_label import TextLabel

__all__ = ["PlotsWidget", "PlotData", "PLOT_NAMES", "auto_exaggeration"]

GCP_COLOR, ICP_COLOR = KIND_RGB["GCP"], KIND_RGB["ICP"]  # one colour per kind: gui/palette.py
FIT_COLOR, THEORY_COLOR, BLUNDER_COLOR = FIT_RGB, THEORY_RGB, BLUNDER_RGB
PLOT_NAMES = ("height", "height_minus_theory", "vectors", "std_residuals")
PLOT_TITLES = {
    "height": "Height vs F−B parallax",
    "height_minus_theory": "Height − theory vs parallax",
    "vectors": "Residual vectors, view {view}",
    "std_residuals": "Standardised residuals of the {fitted}",
}
GRID_CELLS = {"height": (0, 0), "height_minus_theory": (0, 1), "std_residuals": (1, 0, 1, 2),
              "vectors": (0, 2, 2, 1)}
"""(row, column[, rows, columns]) of each plot in the live widget's grid."""
_LEGEND_HTML = (f"<span style='color:{qcolor(KIND_RGB['GCP']).name()}'>●</span> GCP&nbsp;&nbsp; "
                f"<span style='color:{qcolor(KIND_RGB['ICP']).name()}'>▽</span> ICP&nbsp;&nbsp; "
                f"<span style='color:{qcolor(FIT_RGB).name()}'>━</span> fitted line&nbsp;&nbsp; "
                f"<span style='color:{qcolor(THEORY_RGB).name()}'>╍</span> theoretical (eq. 4)&nbsp;&nbsp; "
                f"<span style='color:{qcolor(BLUNDER_RGB).name()}'>■ ◯</span> blunder")
TAB_NAMES = {"height": "h vs parallax", "height_minus_theory": "h − theory",
             "vectors": "Residual vectors", "std_residuals": "Std. residuals"}


class PlotsWidget(QWidget):
    """The four live plots of a Solution (see the module docstring).

    Parameters
    ----------
    parent : QWidget, optional
    grid : bool
        Draw grid lines (off by default: they dominate the repaint time).
    legends : bool
        A legend inside each plot (report figures); the live widget has one line of legend
        below the plots instead.
    tabs : bool
        One tab per plot instead of a 2 × 2 grid (only the visible plot repaints). Without it
        the grid turns into tabs while the widget is shorter than :data:`COMPACT_HEIGHT`
        (a laptop screen: four plots 80 px tall say nothing).
    own_exaggeration : bool
        Show the plot's own exaggeration control, in image pixels drawn per pixel of residual.
        Without it the window's one control for the images and the plots sets it
        (:meth:`set_exaggeration`) in screen pixels per pixel of residual, as on the images:
        a vector has the same length on screen in the plot and over the image.

    Signals
    -------
    point_clicked(str) : the id of a point clicked in any plot (for drive-to).
    """

    point_clicked = Signal(str)
    COMPACT_HEIGHT = 340  # px

    def __init__(self, parent=None, *, grid: bool = False, tabs: bool = False,
                 own_exaggeration: bool = True, legends: bool = False):
        super().__init__(parent)
        self._data = PlotData()
        self._exaggeration = 100.0
        self._screen_k = not own_exaggeration  # exaggeration in screen px per px of residual
        self._shown: dict = {}  # id(item) -> what it shows (see _set)
        self._framed: dict = {}  # plot -> the range last set from the data (see _apply_ranges)
        self.plots: dict[str, pg.PlotWidget] = {}
        self._grid_box = QWidget()
        cells = self._cells = QGridLayout(self._grid_box)
        cells.setContentsMargins(0, 0, 0, 0)
        cells.setSpacing(2)
        self.tabs = QTabWidget()
        self._fixed_tabs = tabs
        self._compact = tabs
        for name in PLOT_NAMES:
            pw = pg.PlotWidget(background="w")
            if grid:  # pyqtgraph's grid costs ~10 ms a repaint per axis: reports only
                pw.getPlotItem().showGrid(x=True, y=True, alpha=0.25)
            pw.setMinimumSize(140, 80)
            self.plots[name] = pw
            if tabs:
                self.tabs.addTab(pw, TAB_NAMES[name])
            else:
                cells.addWidget(pw, *GRID_CELLS[name])
            # ranges are set from the data in one step (auto-range would paint twice); a
            # plot the operator zoomed keeps its range until the "A" button is clicked
            vb = pw.getPlotItem().getViewBox()
            vb.disableAutoRange()
            vb.sigRangeChangedManually.connect(lambda *_, n=name: self._follow.__setitem__(n, False))
            pw.getPlotItem().autoBtn.clicked.connect(lambda *_, n=name: self._refollow(n))
        for c in range(3):
            cells.setColumnStretch(c, 1)
        self._follow = dict.fromkeys(PLOT_NAMES, True)
        self._hidden: set = set()  # plots not shown (show_parallax)
        self._legends = legends
        self._build_items()
        if self._screen_k:  # the vectors keep their screen length as the plot resizes or zooms
            self.plots["vectors"].getPlotItem().getViewBox().sigTransformChanged.connect(
                lambda *_: self._update_vectors())
        self.auto_box = QCheckBox("auto")
        self.auto_box.setChecked(True)
        self.spin = QDoubleSpinBox()
        self.spin.setRange(1.0, 1e6)
        self.spin.setDecimals(0)
        self.spin.setValue(self._exaggeration)
        self.spin.setPrefix("×")
        self.spin.valueChanged.connect(self._on_spin)
        self.auto_box.toggled.connect(self._on_auto)
        bar = QHBoxLayout()
        bar.setContentsMargins(4, 0, 4, 0)
        label = QLabel("Residual vector exaggeration")
        for w in (label, self.spin, self.auto_box):
            bar.addWidget(w)
            w.setVisible(own_exaggeration)
        # the image whose residual vectors are drawn (several images: any of them)
        self.view_box = QComboBox()
        self.view_box.setToolTip("The image whose residual vectors the plot shows")
        self.view_box.setSizeAdjustPolicy(QComboBox.SizeAdjustPolicy.AdjustToContents)
        self.view_box.setVisible(False)
        self.view_box.activated.connect(self._on_view_chosen)
        self._solution, self._vector_view = None, None  # (None: the default view)
        bar.addWidget(self.view_box)
        self.legend = QLabel(_LEGEND_HTML)
        self.legend.setVisible(not legends)
        bar.addWidget(self.legend)
        self.summary = TextLabel(stretch=True, align=Qt.AlignmentFlag.AlignRight)  # no relayout
        bar.addWidget(self.summary, 1)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        self._stack = QStackedWidget()
        self._stack.addWidget(self._grid_box)
        self._stack.addWidget(self.tabs)
        self._stack.setCurrentWidget(self.tabs if tabs else self._grid_box)
        lay.addWidget(self._stack, 1)
        lay.addLayout(bar)

    def resizeEvent(self, ev) -> None:
        super().resizeEvent(ev)
        if not self._fixed_tabs and (self.height() < self.COMPACT_HEIGHT) != self._compact:
            QTimer.singleShot(0, lambda: self._arrange(self.height() < self.COMPACT_HEIGHT))

    def show_parallax(self, on: bool) -> None:
        """Show the two height–parallax plots (off for a model whose points are intersected
        from rays: it has no parallax line)."""
        self._hidden = set() if on else {"height", "height_minus_theory"}
        for name in ("height", "height_minus_theory"):
            i = self.tabs.indexOf(self.plots[name])
            if i >= 0:
                self.tabs.setTabVisible(i, on)
            if not self._compact:
                self.plots[name].setVisible(on)

    def _arrange(self, compact: bool) -> None:
        """The four plots in tabs (``compact``) or in the grid (:data:`GRID_CELLS`)."""
        if compact == self._compact:
            return
        self._compact = compact
        for name in PLOT_NAMES:
            if compact:
                self.tabs.addTab(self.plots[name], TAB_NAMES[name])
            else:
                self._cells.addWidget(self.plots[name], *GRID_CELLS[name])
        self._stack.setCurrentWidget(self.tabs if compact else self._grid_box)
        for name, pw in self.plots.items():
            if compact:
                self.tabs.setTabVisible(self.tabs.indexOf(pw), name not in self._hidden)
            pw.setVisible((not compact or pw is self.tabs.currentWidget()) and name not in self._hidden)

    # ------------------------------------------------------------------ construction
    # Plain pyqtgraph items, not PlotDataItems (``PlotWidget.plot``): a PlotDataItem wraps a
    # curve and a scatter and re-processes both at every setData, several times the cost.
    def _scatter(self, pw, color, symbol, name, size=8, filled=True):
        brush = pg.mkBrush(*color) if filled else pg.mkBrush(255, 255, 255, 0)
        item = Scatter(pen=pg.mkPen(color, width=1.5), brush=brush, symbol=symbol, size=size,
                       name=name, hoverable=True,  # tool tip: id, values
                       tip=lambda x, y, data: plain_block(f"{data}: {x:.2f}, {y:.2f}"))
        item.sigClicked.connect(self._on_clicked)
        pw.addItem(item)
        return item

    @staticmethod
    def _curve(pw, pen, name=None, connect="all"):
        item = pg.PlotCurveItem(pen=pen, name=name, connect=connect)
        pw.addItem(item)
        return item

    def _build_items(self) -> None:
        p = self.plots
        for name in ("height", "height_minus_theory"):
            pi = p[name].getPlotItem()
            if self._legends:
                legend_below(pi, labelTextSize="9pt", labelTextColor=(30, 30, 30))
            pi.setLabel("bottom", "F−B parallax", units="px")
        p["height"].setLabel("left", "h (ellipsoidal)", units="m")
        p["height_minus_theory"].setLabel("left", "h − c1ₜₕ·py", units="m")
        dash = Qt.PenStyle.DashLine
        self.fit_line = self._curve(p["height"], pg.mkPen(FIT_COLOR, width=1.5), "fitted line")
        self.theory_line = self._curve(p["height"], pg.mkPen(THEORY_COLOR, width=1.5, style=dash),
                                       "theoretical (eq. 4)")
        self.h_gcp = self._scatter(p["height"], GCP_COLOR, "o", "GCP")
        self.h_icp = self._scatter(p["height"], ICP_COLOR, "t", "ICP", filled=False)
        self.d_fit_line = self._curve(p["height_minus_theory"], pg.mkPen(FIT_COLOR, width=1.5),
                                      "fitted − theoretical")
        zero = pg.InfiniteLine(0.0, angle=0, pen=pg.mkPen(THEORY_COLOR, width=1, style=dash))
        p["height_minus_theory"].addItem(zero)
        self.d_gcp = self._scatter(p["height_minus_theory"], GCP_COLOR, "o", "GCP")
        self.d_icp = self._scatter(p["height_minus_theory"], ICP_COLOR, "t", "ICP", filled=False)

        pv = p["vectors"].getPlotItem()
        pv.invertY(True)
        pv.setAspectLocked(True)
        pv.setLabel("bottom", "x (column)", units="px")
        pv.setLabel("left", "y (row)", units="px")
        if self._legends:
            legend_below(pv, labelTextSize="9pt", labelTextColor=(30, 30, 30))
        self.v_gcp_seg = self._curve(pv, pg.mkPen(GCP_COLOR, width=2), connect="pairs")
        self.v_icp_seg = self._curve(pv, pg.mkPen(ICP_COLOR, width=2), connect="pairs")
        self.v_tie_seg = self._curve(pv, pg.mkPen(KIND_RGB["TIE"], width=2), connect="pairs")
        self.v_tie = self._scatter(p["vectors"], KIND_RGB["TIE"], "+", "TIE", size=7)  # (models that fit them)
        self.v_gcp = self._scatter(p["vectors"], GCP_COLOR, "o", "GCP", size=6)
        self.v_icp = self._scatter(p["vectors"], ICP_COLOR, "t", "ICP", size=7, filled=False)
        self.frame = self._curve(pv, pg.mkPen((150, 150, 150), width=1, style=dash))

        ps = p["std_residuals"].getPlotItem()
        ps.setLabel("left", "|standardised residual|")
        ps.setLabel("bottom", "GCP")
        self.stems = self._curve(ps, pg.mkPen(GCP_COLOR, width=3), connect="pairs")
        self.std_pts = self._scatter(p["std_residuals"], GCP_COLOR, "o", "GCP", size=7)
        self.blunder_pt = self._scatter(p["std_residuals"], BLUNDER_COLOR, "s", "blunder", size=12)
        # the one blunder threshold of every fit (the values are on the normal scale)
        self.threshold_line = pg.InfiniteLine(3.29, angle=0, pen=pg.mkPen(BLUNDER_COLOR, width=1.5, style=dash),
                                              label="blunder threshold {value:.2f}",
                                              labelOpts={"position": 0.99, "color": BLUNDER_COLOR,
                                                         "fill": (255, 255, 255, 210),  # over the stems
                                                         "anchors": [(1, 0), (1, 0)]})  # under it
        ps.addItem(self.threshold_line)
        self.blunder_label = pg.TextItem("", color=BLUNDER_COLOR, anchor=(0.5, 1.2))
        ps.addItem(self.blunder_label)
        # the blunders (if any) ringed in the other plots too
        self.blunder_rings = {name: self._scatter(p[name], BLUNDER_COLOR, "o", None, size=16,
                                                  filled=False)
                              for name in ("height", "height_minus_theory", "vectors")}
        for pw in p.values():
            for ax in ("left", "bottom"):
                axis = pw.getPlotItem().getAxis(ax)
                axis.enableAutoSIPrefix(False)
                axis.setTextPen((40, 40, 40))
                axis.setPen((110, 110, 110))
            # fixed axis sizes: tick labels that change width would relayout and repaint again
            pw.getPlotItem().getAxis("left").setWidth(58)
            pw.getPlotItem().getAxis("bottom").setHeight(38)
        self._titles: dict = {}
        self._set_titles()

    def _set_titles(self) -> None:
        for name, pw in self.plots.items():
            title = PLOT_TITLES[name].format(view=self._data.view,
                                             fitted="GCPs and tie points" if self._data.ties else "GCPs")
            if name == "vectors":
                title += f" (×{self._exaggeration:g})"
            if self._titles.get(name) != title:
                pw.setTitle(title, size="9pt", color=(30, 30, 30))
                self._titles[name] = title
                if name == "std_residuals":     # the axis names what it counts
                    pw.getPlotItem().setLabel("bottom", "point" if self._data.ties else "GCP")

    # ------------------------------------------------------------------ public
    def set_solution(self, solution) -> None:
        """Show ``solution`` (a :class:`~prismstation.core.models.solution.Solution` or None), the residual
        vectors of the image chosen in :attr:`view_box` (by default :func:`.plot_data.vector_view`)."""
        self._solution = solution
        data = PlotData.from_solution(solution, self._vector_view)
        views = list(solution.bias) if solution is not None else []
        box = self.view_box
        if [box.itemText(i) for i in range(box.count())] != views:
            box.clear()
            box.addItems(views)
        if box.currentText() != data.view:
            box.setCurrentText(data.view)
        box.setVisible(len(views) > 1)
        self.set_plot_data(data)

    def _on_view_chosen(self, index: int) -> None:
        self._vector_view = self.view_box.itemText(index) or None
        self.set_solution(self._solution)

    def set_report(self, report: dict) -> None:
        """Show a report dict (:func:`prismstation.io.report.report_dict`)."""
        self.set_plot_data(PlotData.from_report(report))

    def set_plot_data(self, data: PlotData) -> None:
        """Update every item from ``data`` (items are reused, never rebuilt)."""
        self._data = data
        d = data
        if self.auto_box.isChecked():
            self._exaggeration = auto_exaggeration(d)
            if self.spin.value() != round(self._exaggeration, self.spin.decimals()):
                self.spin.blockSignals(True)
                self.spin.setValue(self._exaggeration)
                self.spin.blockSignals(False)
        self._set(self.h_gcp, d.gcp_py, d.gcp_h, data=list(d.gcp_ids))
        self._set(self.h_icp, d.icp_py, d.icp_h, data=list(d.icp_ids))
        x = line_x(d)
        if d.c0 is not None and d.c1 is not None and x.size:
            self._set(self.fit_line, x, d.c0 + d.c1 * x)
            self._set(self.d_fit_line, x, d.c0 + (d.c1 - d.c1_theory) * x)
        else:
            self._set(self.fit_line, [], [])
            self._set(self.d_fit_line, [], [])
        if d.c1_theory is not None and x.size:
            self._set(self.theory_line, x, d.c1_theory * x)
            self._set(self.d_gcp, d.gcp_py, d.gcp_h - d.c1_theory * d.gcp_py, data=list(d.gcp_ids))
            self._set(self.d_icp, d.icp_py, d.icp_h - d.c1_theory * d.icp_py, data=list(d.icp_ids))
        else:
            for item in (self.theory_line, self.d_gcp, self.d_icp):
                self._set(item, [], [])
        self._update_vectors()
        n = len(d.std_ids)
        xs = np.arange(1, n + 1, dtype=float)
        stem_x = np.repeat(xs, 2)
        stem_y = np.zeros(2 * n)
        stem_y[1::2] = d.std_values
        self._set(self.stems, stem_x, stem_y)
        self._set(self.std_pts, xs, d.std_values, data=list(d.std_ids))
        self._once("threshold", d.threshold, self.threshold_line.setValue)
        self._once("threshold text", d.threshold,  # (α computed only when the threshold changes)
                   lambda t: self.threshold_line.label.setFormat(
                       f"blunder threshold {{value:.2f}} (α = {alpha_of(t):.2g})"))
        flagged = [i for i, pid in enumerate(d.std_ids) if pid in d.blunders]
        if flagged:
            top_i = max(flagged, key=lambda i: d.std_values[i])
            self._set(self.blunder_pt, xs[flagged], d.std_values[flagged],
                      data=[d.std_ids[i] for i in flagged])
            self._once("blunder", (blunder_text([d.std_ids[i] for i in flagged]), xs[top_i], d.std_values[top_i],
                                   xs[top_i] > (n + 1) / 2),
                       self._place_blunder_label)
        else:
            self._set(self.blunder_pt, [], [])
            self._once("blunder", None, lambda v: self.blunder_label.setText(""))
        ax = self.plots["std_residuals"].getPlotItem().getAxis("bottom")
        self._once("std ticks", [list(zip(xs, d.std_ids))] if 0 < n <= 25 else None, ax.setTicks)
        top = max(d.threshold * 1.25, float(np.max(d.std_values)) * 1.15 if n else 0.0)
        self._update_rings()
        self._std_range = ((0.3, n + 0.7), (0.0, top))
        self._apply_ranges()
        self.summary.setText((f"{len(d.vec_gcp_ids)} GCP, {len(d.vec_icp_ids)} ICP, {len(d.vec_tie_ids)} tie points "
                              f"in {d.view}" if d.ties else f"{len(d.gcp_ids)} GCP, {len(d.icp_ids)} ICP with parallax")
                             + (f"; blunder: {', '.join(d.blunders)}" if d.blunders else ""))
        self._set_titles()

    def _place_blunder_label(self, v) -> None:
        """The flagged ids above the highest blunder's stem, leaning into the plot."""
        text, x, y, right_half = v
        self.blunder_label.setText(text)
        self.blunder_label.setAnchor((1.0 if right_half else 0.0, 1.2))
        self.blunder_label.setPos(x, y)

    def _set(self, item, x, y, data=None) -> None:
        """``item.setData(x, y[, data=...])`` unless it already shows exactly that: pyqtgraph
        rebuilds an item on every ``setData`` (~0.3 ms), and a click changes few of them."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        key = (x.tobytes(), y.tobytes(), None if data is None else tuple(data))
        if self._shown.get(id(item)) == key:
            return
        self._shown[id(item)] = key
        if data is None:
            item.setData(x, y)
        else:
            item.setData(x, y, data=data)
        item.setVisible(len(x) > 0)  # an empty item hidden costs a repaint nothing

    def _once(self, key: str, value, apply) -> None:
        """``apply(value)`` unless ``value`` is what ``key`` was last set to (no repaint)."""
        if key in self._shown and self._shown[key] == value:
            return
        self._shown[key] = value
        apply(value)

    def set_exaggeration(self, k: float | None) -> None:
        """Residual vectors drawn ``k`` times their length; ``None`` returns to automatic."""
        if k is None:
            self.auto_box.setChecked(True)
        else:
            self.spin.setValue(float(k))

    @property
    def exaggeration(self) -> float:
        return self._exaggeration

    # ------------------------------------------------------------------ internals
    def _update_vectors(self) -> None:
        d, k = self._data, self._exaggeration
        if self._screen_k:  # screen px per px: times the image px per screen px of the plot
            px = self.plots["vectors"].getPlotItem().getViewBox().viewPixelSize()[0]
            k *= px if np.isfinite(px) and px > 0 else 1.0
        self._set(self.v_tie_seg, *segments(d.vec_tie_xy, d.vec_tie_v, k))
        self._set(self.v_tie, d.vec_tie_xy[:, 0], d.vec_tie_xy[:, 1], data=list(d.vec_tie_ids))
        self._set(self.v_gcp_seg, *segments(d.vec_gcp_xy, d.vec_gcp_v, k))
        self._set(self.v_icp_seg, *segments(d.vec_icp_xy, d.vec_icp_v, k))
        self._set(self.v_gcp, d.vec_gcp_xy[:, 0], d.vec_gcp_xy[:, 1], data=list(d.vec_gcp_ids))
        self._set(self.v_icp, d.vec_icp_xy[:, 0], d.vec_icp_xy[:, 1], data=list(d.vec_icp_ids))
        if d.image_shape:
            r, c = d.image_shape[:2]
            self._set(self.frame, [0, c, c, 0, 0], [0, 0, r, r, 0])
        else:
            self._set(self.frame, [], [])

    def _ranges(self) -> dict:
        """``{plot: ((x0, x1), (y0, y1))}`` covering the data (plots with data only)."""
        segs = [np.column_stack(item.getData()) for item in (self.v_gcp_seg, self.v_icp_seg, self.v_tie_seg)
                if item.getData()[0] is not None and len(item.getData()[0])]
        return data_ranges(self._data, segs, getattr(self, "_std_range", ((0, 1), (0, 4))))

    def _apply_ranges(self, only=None) -> None:
        """Frame each followed plot's data. A range that still frames the data well (holds it,
        at most 30 % to spare per axis) is kept: the axes do not twitch at every click, and an
        unchanged plot is not redrawn."""
        for name, (xr, yr) in self._ranges().items():
            if self._follow[name] and (only is None or name == only):
                old = self._framed.get(name)
                if only is None and old is not None and all(
                        o[0] <= n[0] and n[1] <= o[1] and n[1] - n[0] >= 0.7 * (o[1] - o[0])
                        for o, n in zip(old, (xr, yr))):
                    continue
                self._framed[name] = (tuple(xr), tuple(yr))
                vb = self.plots[name].getPlotItem().getViewBox()
                vb.setRange(xRange=xr, yRange=yr, padding=0, disableAutoRange=True)
                vb.prepareForPaint()  # apply the new range now, not during the paint (which
                # would then schedule a second one)

    def _refollow(self, name: str) -> None:
        self._follow[name] = True
        self._framed.pop(name, None)
        self.plots[name].getPlotItem().getViewBox().disableAutoRange()
        self._apply_ranges(name)

    def _update_rings(self) -> None:
        d, b = self._data, self._data.blunders
        pos = {"height": (d.gcp_ids, d.gcp_py, d.gcp_h),
               "height_minus_theory": (d.gcp_ids, d.gcp_py,
                                       d.gcp_h - (d.c1_theory or 0.0) * d.gcp_py),
               "vectors": (d.vec_gcp_ids, d.vec_gcp_xy[:, 0], d.vec_gcp_xy[:, 1])}
        for name, (ids, x, y) in pos.items():
            idx = [] if name == "height_minus_theory" and d.c1_theory is None else \
                [i for i, pid in enumerate(ids) if pid in b]
            self._set(self.blunder_rings[name], x[idx], y[idx], data=[ids[i] for i in idx])

    def _on_spin(self, value: float) -> None:
        self.auto_box.blockSignals(True)
        self.auto_box.setChecked(False)
        self.auto_box.blockSignals(False)
        self._exaggeration = float(value)
        self._update_vectors()
        self._set_titles()

    def _on_auto(self, on: bool) -> None:
        if on:
            self.set_plot_data(self._data)

    def _on_clicked(self, item, points, *_):
        if len(points):
            pid = points[0].data()
            if pid is not None:
                self.point_clicked.emit(str(pid))
