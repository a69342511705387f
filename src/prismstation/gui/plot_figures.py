"""The live plots drawn as the report's figures, and legends that never cover the data.

:func:`render_images` draws each plot of a :class:`~prismstation.gui.plots.PlotsWidget` as a
picture (``{name: QImage}``) by a hidden copy, :func:`figure_widget`, laid out at the figure's
size: antialiased, with a grid and a legend under each plot (:func:`legend_below`) naming only
what the figure draws. The live widget is not disturbed.
"""
from __future__ import annotations

import pyqtgraph as pg
import shiboken6
from PySide6.QtCore import Qt
from PySide6.QtGui import QFont, QImage


def legend_below(plot_item, columns: int = 4, **style) -> pg.LegendItem:
    """A legend in a row of its own under ``plot_item``'s bottom axis — never over the data
    (inside the plot it hid points where they gathered) — listing the items added with a name
    from now on, in ``columns`` columns. ``style``: pyqtgraph's legend options."""
    legend = pg.LegendItem(offset=None, colCount=columns, **style)
    plot_item.layout.addItem(legend, 4, 1)
    plot_item.layout.setAlignment(legend, Qt.AlignmentFlag.AlignHCenter)
    plot_item.legend = legend  # (PlotItem.addItem lists named items in it)
    return legend


def _drawn(item) -> bool:
    """Whether a plot item has anything to draw (a legend lists only those)."""
    if isinstance(item, pg.ScatterPlotItem):
        return len(item.data) > 0
    x = getattr(item, "xData", None)
    return x is not None and len(x) > 0


def figure_widget(plots):
    """A hidden copy of ``plots`` (a PlotsWidget) drawn as the report's figures are:
    antialiased, a grid, each legend under its plot naming only what it draws. The caller
    deletes it."""
    smooth = pg.getConfigOption("antialias")
    pg.setConfigOptions(antialias=True)  # items read it when created
    try:
        tmp = type(plots)(grid=True, legends=True)  # (a PlotsWidget: plots imports this module)
    finally:
        pg.setConfigOptions(antialias=smooth)
    tmp.setAttribute(Qt.WidgetAttribute.WA_DontShowOnScreen, True)
    if not plots.auto_box.isChecked() and not plots._screen_k:
        tmp.set_exaggeration(plots._exaggeration)
    tmp.set_plot_data(plots._data)
    for pw in tmp.plots.values():
        legend = pw.getPlotItem().legend
        for sample, _ in list(legend.items) if legend is not None else ():
            if not _drawn(sample.item):
                legend.removeItem(sample.item)
    return tmp


def render_images(plots, size=(900, 560)) -> dict:
    """Each plot of ``plots`` as a QImage of ``size`` pixels: ``{name: QImage}``."""
    from PySide6.QtWidgets import QApplication
    tmp = figure_widget(plots)
    try:
        for name in tmp._titles:
            tmp.plots[name].setTitle(tmp._titles[name], size="12pt", color=(30, 30, 30))
        font = QFont()
        font.setPointSizeF(10.5)
        for pw in tmp.plots.values():
            pw.setFixedSize(int(size[0]), int(size[1]))
            for side, extent in (("left", 74), ("bottom", 46)):
                axis = pw.getPlotItem().getAxis(side)
                axis.setTickFont(font)
                axis.label.setFont(font)
                axis.setWidth(extent) if side == "left" else axis.setHeight(extent)
        tmp.adjustSize()
        tmp.show()
        QApplication.processEvents()
        return {name: pw.grab().toImage().convertToFormat(QImage.Format.Format_RGB32)
                for name, pw in tmp.plots.items()}
    finally:
        tmp.hide()
        shiboken6.delete(tmp)  # now: deleteLater waits for the event loop (a script has none,
        # and a report's figures are ~26 MB of widgets and pictures)
