"""Interactive contrast stretch for one :class:`~prismstation.gui.image_view.ImageView`.

Percentile presets and a histogram (from the source's coarse overview, never a full read) with a
draggable pair of levels. The levels apply to the view's overview and tiles alike through
``ImageView.set_levels``; the panel follows levels set elsewhere through ``levels_changed``.
"""
from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtWidgets import QComboBox, QHBoxLayout, QLabel, QVBoxLayout, QWidget

PRESETS = {
    "0.5–99.5 %": (0.5, 99.5),
    "2–98 %": (2.0, 98.0),
    "min–max": (0.0, 100.0),
}
"""Preset name -> (low percentile, high percentile)."""


def percentile_levels(view, low: float, high: float) -> tuple[float, float]:
    """Levels ``(lo, hi)`` at two percentiles of the view's source (coarse overview statistics)."""
    st = view.source.statistics((low, high))
    return st.percentiles[float(low)], st.percentiles[float(high)]


class ContrastPanel(QWidget):
    """Histogram with draggable levels and percentile presets, bound to one ImageView.

    Parameters
    ----------
    view : ImageView
        The view whose display levels this panel sets; the histogram follows the view's source
        (``source_ready``).
    """

    def __init__(self, view, parent=None):
        super().__init__(parent)
        self.view = view
        self.presets = QComboBox()
        self.presets.addItems(list(PRESETS) + ["custom"])
        self.presets.activated.connect(self._on_preset)
        self.label = QLabel()
        self.plot = pg.PlotWidget(background="w")
        self.plot.setMinimumHeight(40)  # the dock shares the loupes' height: 60-100 px
        self.plot.hideAxis("left")
        self.plot.setMouseEnabled(x=False, y=False)
        self.plot.setMenuEnabled(False)
        self.curve = self.plot.plot(stepMode="center", fillLevel=0, brush=(60, 60, 160, 120),
                                    pen=(40, 40, 120))
        self.region = pg.LinearRegionItem(orientation="vertical", brush=(255, 180, 0, 50))
        self.region.setZValue(10)
        self.plot.addItem(self.region)
        self.region.sigRegionChanged.connect(self._on_region)
        # the controls beside the histogram, not above it: the dock shares the loupes' height
        # (60-100 px), and a row on top left the histogram cut off
        self.presets.setToolTip("Stretch: the levels at two percentiles of the image, or drag "
                                "the region on the histogram")
        side = QVBoxLayout()
        side.setSpacing(2)
        side.addWidget(self.presets)
        side.addWidget(self.label)
        side.addStretch(1)
        layout = QHBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.setSpacing(4)
        layout.addWidget(self.plot, 1)
        layout.addLayout(side)
        self._syncing = False
        view.levels_changed.connect(self._on_view_levels)
        view.source_ready.connect(self.refresh)
        self.refresh()

    def refresh(self) -> None:
        """Reload the histogram from the view's current source."""
        if self.view.source is None or not self.view.is_ready():
            self.curve.setData([0, 1], [0])
            return
        st = self.view.source.statistics(())
        counts = st.histogram.astype(float)
        self.curve.setData(st.bin_edges, np.log1p(counts))
        self.plot.setXRange(st.bin_edges[0], st.bin_edges[-1], padding=0.02)
        self._on_view_levels(*self.view.levels())

    def levels(self) -> tuple[float, float]:
        return self.view.levels()

    def apply_preset(self, name: str) -> tuple[float, float]:
        """Set the view's levels from a preset of :data:`PRESETS`; returns the levels."""
        lo, hi = percentile_levels(self.view, *PRESETS[name])
        self.presets.setCurrentText(name)
        self.view.set_levels(lo, hi)
        return lo, hi

    def _on_preset(self, index: int) -> None:
        name = self.presets.itemText(index)
        if name in PRESETS:
            self.apply_preset(name)

    def _on_region(self) -> None:
        if self._syncing:
            return
        lo, hi = self.region.getRegion()
        self.presets.setCurrentText("custom")
        self.view.set_levels(lo, hi)

    def _on_view_levels(self, lo: float, hi: float) -> None:
        self._syncing = True
        try:
            self.region.setRegion((lo, hi))
        finally:
            self._syncing = False
        self.label.setText(f"{lo:.6g} – {hi:.6g}")
