"""The window's panels at the sizes operators use (1280 × 720 to 1920 × 1080), driven through
menus, keys and clicks: what each panel shows is whole and readable — plots with their data
uncovered, the residual vectors using their plot's width, the model panel when a tool's panel
opens, the contrast histogram, the guide's pictures."""
from __future__ import annotations

import pytest
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QTabBar

from tests.gui.test_operator import key
from tests.gui.test_layout import action

SIZES = [(1280, 720), (1600, 1000), (1920, 1080)]


def lay_out(qtbot, win, size):
    win.resize(*size)
    win.default_layout()
    qtbot.wait(100)
    assert (win.width(), win.height()) == size


def whole(widget) -> bool:
    """The widget is shown entirely: no part scrolled away or clipped by a parent, nor outside
    the window (its rectangle clipped by every ancestor's is still all of it)."""
    if not widget.isVisible():
        return False
    top = widget.window()
    rect = widget.rect().translated(widget.mapTo(top, widget.rect().topLeft()))
    clip = rect
    w = widget.parentWidget()
    while w is not None:
        clip = clip.intersected(w.rect().translated(w.mapTo(top, w.rect().topLeft()))
                                if w is not top else top.rect())
        if w is top:
            break
        w = w.parentWidget()
    return clip == rect


def click_tab(qtbot, win, title):
    bar = next(b for b in win.findChildren(QTabBar) if b.isVisible()
               and title in [b.tabText(i) for i in range(b.count())])
    i = [bar.tabText(i) for i in range(bar.count())].index(title)
    qtbot.mouseClick(bar, Qt.MouseButton.LeftButton, pos=bar.tabRect(i).center())
    qtbot.wait(50)


def test_plots_keep_their_data_uncovered_and_the_vectors_use_their_width(qtbot, window):
    win = window
    lay_out(qtbot, win, (1600, 1000))
    plots = win.plots
    assert not plots._compact
    for name, pw in plots.plots.items():   # no legend over the data: one line below the plots
        assert pw.getPlotItem().legend is None, name
    assert whole(plots.legend) and "ICP" in plots.legend.text()
    vb = plots.plots["vectors"].getPlotItem().getViewBox()
    cols = win.views.views["N"].source.width
    used = cols / vb.viewPixelSize()[0] / vb.width()   # the image's width on screen / the plot's
    assert used > 0.7, f"the residual vectors use {used:.0%} of their plot's width"
    # the vectors have the same screen length as on the images: ×k screen px per px
    k = win.exaggeration.value()
    ends = plots.v_gcp_seg.getData()
    r = next(r for r in win.solver.solution.points if r.kind == "GCP" and "N" in r.residual_px)
    i = [p.id for p in win.solver.solution.points if p.kind == "GCP" and "N" in p.residual_px].index(r.id)
    dx = (ends[0][2 * i + 1] - ends[0][2 * i]) / vb.viewPixelSize()[0]
    assert dx == pytest.approx(k * r.residual_px["N"][0], rel=1e-6)


@pytest.mark.parametrize("size", SIZES)
def test_a_tool_panel_opened_leaves_the_model_panel_readable(qtbot, window, size):
    """Opening Transforms squeezed the model panel to one line (1600 × 1000)."""
    win = window
    lay_out(qtbot, win, size)
    rows = win.panel.text.viewport().height() / win.panel.sections._row_height()
    action(win, "Tools ▸ Transforms").trigger()
    qtbot.wait(100)
    assert win.docks["transforms"].isVisible()
    after = win.panel.text.viewport().height() / win.panel.sections._row_height()
    assert after >= min(rows, 6), f"the model panel shows {after:.1f} lines (was {rows:.1f})"
    assert (win.width(), win.height()) == size


@pytest.mark.parametrize("size", SIZES)
def test_the_contrast_histogram_is_whole(qtbot, window, size):
    win = window
    lay_out(qtbot, win, size)
    click_tab(qtbot, win, "Contrast")
    panel = win.contrast_tabs.currentWidget()
    assert whole(panel.plot) and panel.plot.height() >= 40, panel.plot.geometry()
    assert whole(panel.presets) and whole(panel.label)
    click_tab(qtbot, win, "B")
    assert whole(win.contrast_tabs.currentWidget().plot)


def test_the_guide_viewer_shows_its_pictures(qtbot, window):
    from PySide6.QtGui import QTextDocument
    win = window
    key(qtbot, win, "F1")
    viewer = win.guide_viewer
    qtbot.waitUntil(viewer.isVisible, timeout=3000)
    qtbot.wait(50)
    doc = viewer.browser.document()
    layout = doc.documentLayout()
    shown = {}
    block = doc.begin()
    while block.isValid():
        it = block.begin()
        while not it.atEnd():
            fmt = it.fragment().charFormat()
            if fmt.isImageFormat():
                name = fmt.toImageFormat().name()
                pic = doc.resource(QTextDocument.ResourceType.ImageResource, name)
                shown[name] = (layout.blockBoundingRect(block).height(), pic)
            it += 1
        block = block.next()
    assert "start_page.png" in shown and "screenshot.png" in shown
    for name, (height, pic) in shown.items():   # drawn, at the page's width and its own aspect
        assert pic is not None and not pic.isNull(), name
        assert height > 0.5 * min(pic.height(), viewer.browser.viewport().width() * pic.height() / pic.width()), name
    assert viewer.browser.horizontalScrollBar().maximum() == 0
    viewer.close()


def _two_rasters(folder, crs):
    """A small DSM and a reference 2 m below it, 10 m cells, on the project's CRS."""
    import numpy as np
    import rasterio
    from rasterio.transform import from_origin
    y, x = np.mgrid[0:60, 0:80]
    h = (300 + 20 * np.sin(x / 9.0) * np.cos(y / 7.0)).astype("float32")
    paths = []
    for name, arr in (("dsm.tif", h), ("ref.tif", h - 2.0)):
        with rasterio.open(folder / name, "w", driver="GTiff", width=80, height=60, count=1,
                           dtype="float32", crs=crs, transform=from_origin(540000, 4563000, 10, 10)) as ds:
            ds.write(arr, 1)
        paths.append(str(folder / name))
    return paths


@pytest.mark.parametrize("size", SIZES)
def test_the_validation_and_residual_sd_docks_are_whole(qtbot, window, size, tmp_path):
    """The residual-SD title was cut at the dock's edge; the validation's difference map and
    histogram were squeezed to nothing in a laptop's bottom dock. Each part shows whole and
    the plots keep a readable size (one tab each where the dock is short)."""
    win = window
    lay_out(qtbot, win, size)
    action(win, "Tools ▸ Residual SD").trigger()
    qtbot.wait(50)
    tool = win.tools["dsm_validation"]
    title = tool.sd_panel.findChild(type(tool.panel.title))
    assert whole(title) and title.height() >= title.heightForWidth(title.width()), title.text()
    dsm, ref = _two_rasters(tmp_path, win.project.scene.crs)
    job = tool.start(dsm, ref, progress_dialog=False)
    qtbot.waitUntil(lambda: tool.panel.validation is not None, timeout=30000)
    assert job is not None
    qtbot.wait(100)
    panel = tool.panel
    parts = {"Statistics": panel.table, "Difference map": panel.map, "Histogram": panel.hist}
    for name, w in parts.items():
        if panel._compact:
            click_tab(qtbot, win, name)
        assert whole(w), (size, name, w.geometry())
        if w is not panel.table:
            assert w.width() >= 160 and w.height() >= 130, (size, name, w.size())
    assert abs(panel.validation.overall.bias - 2.0) < 1e-3
    assert (win.width(), win.height()) == size
