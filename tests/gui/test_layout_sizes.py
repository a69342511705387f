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
