"""Start page, accuracy strip, one palette, loupe labels, model tool tips and the user guide,
through the real window."""
from __future__ import annotations

import math

import pytest

from PySide6.QtCore import Qt

from tests.gui.test_layout import action
from tests.qt_windows import close_windows, new_window


@pytest.fixture()
def bare_window(qtbot):
    win = new_window(qtbot, (1280, 720))
    yield win
    close_windows(qtbot, win)


def test_start_page_without_a_project_then_the_work_area(qtbot, bare_window, demo):
    win = bare_window
    if True:
        assert win.central.currentWidget() is win.start_page
        assert not any(d.isVisible() for d in win.docks.values())  # no meaningless controls
        assert not win.toolbar.isVisible()
        sp = win.start_page
        assert not sp.buttons["demo"].isVisible()  # no demo maker given
        opened = []
        win.files.open_project = lambda *a, **k: opened.append(a) or False
        qtbot.mouseClick(sp.buttons["open"], Qt.MouseButton.LeftButton)
        assert opened == [()]
        win.files.open_project = type(win.files).open_project.__get__(win.files)
        assert win.open_project(demo.path, recover=False)
        assert win.central.currentWidget() is not win.start_page
        assert win.docks["model"].isVisible() and win.docks["points"].isVisible()
        assert win.toolbar.isVisible()
        sp.set_recent([str(demo.path)])
        assert sp.recent.item(0).data(Qt.ItemDataRole.UserRole) == str(demo.path)


def test_accuracy_strip_shows_the_icp_rmse_of_the_fit(window):
    win = window
    sol = win.solver.solution
    g = sol.stats["ground"]["ICP"]
    vals = {f: lab.text() for f, lab in win.accuracy.values.items()}
    assert vals["E"] == f"{g.x.rms:.2f} m" and vals["N"] == f"{g.y.rms:.2f} m"
    assert vals["plan"] == f"{g.planimetric_rms:.2f} m"
    assert math.isclose(g.planimetric_rms, math.hypot(g.x.rms, g.y.rms), rel_tol=1e-9)
    assert vals["h"] == f"{sol.stats['height']['ICP'].rms:.2f} m"
    assert vals["σ0"] == f"{sol.bias[sol.reference_view].sigma0:.3f} px"
    assert "12 ICP" in win.accuracy.count.text()


def test_one_exaggeration_control_for_images_and_plots(window):
    win = window
    assert win.exaggeration.parent() is win.accuracy  # in the strip, not the toolbar
    win.exaggeration.setValue(75)
    assert win.plots.exaggeration == 75
    assert [ov.exaggeration for ov in win.views.overlays.values()] == [75, 75, 75]
    assert not win.plots.spin.isVisibleTo(win.plots)  # the plots' own control is not shown


def test_one_colour_per_kind(window):
    from prismstation.gui import overlays, plots
    from prismstation.gui.palette import KIND_RGB, qcolor
    for k in ("GCP", "ICP", "TIE"):
        assert overlays.KIND_COLORS[k] == qcolor(k)
    assert plots.GCP_COLOR == KIND_RGB["GCP"] and plots.ICP_COLOR == KIND_RGB["ICP"]
    assert plots.BLUNDER_COLOR not in KIND_RGB.values()


def test_loupes_are_labelled_and_model_settings_explained(window):
    win = window
    assert [lp.label for lp in win.loupes.values()] == ["N", "F", "B"]
    p = win.panel
    for w in (p.bias, p.parallax, p.sigma, p.threshold, p.geoid, p.geoid_button):
        assert len(w.toolTip()) > 20


def test_help_user_guide_opens_the_guide(qtbot, window):
    win = window
    action(win, "Help ▸ User guide").trigger()
    viewer = win.guide_viewer
    assert viewer.isVisible()
    assert "prismstation user guide" in viewer.browser.toPlainText()
    qtbot.wait(20)
    assert viewer.browser.horizontalScrollBar().maximum() == 0  # pictures fit the page
    viewer.close()


def test_open_the_demo_from_the_start_page(qtbot, bare_window, demo):
    win = bare_window
    calls = []

    def make_demo(progress=None):  # stands for cli.demo.ensure_demo (the real one takes ~40 s)
        calls.append(progress(0.5, "simulating"))
        return demo.path

    win.demo_maker = make_demo
    win.start_page.set_demo_available(True)
    assert win.start_page.buttons["demo"].isVisible()
    qtbot.mouseClick(win.start_page.buttons["demo"], Qt.MouseButton.LeftButton)
    qtbot.waitUntil(lambda: win.project is not None, timeout=10000)
    assert calls == [True] and win.files.path == demo.path
    assert win.central.currentWidget() is not win.start_page


def test_kind_buttons_carry_their_colour(window):
    from PySide6.QtGui import QColor
    from prismstation.gui.palette import qcolor
    for k, a in window.a_kind.items():
        img = a.icon().pixmap(16, 16).toImage()
        assert QColor(img.pixel(8, 8)) == qcolor(k)
        assert window.toolbar.widgetForAction(a).text() == k


def test_no_stray_tab_bar_over_the_menu_bar_after_the_start_page(qtbot, bare_window, demo, tmp_path):
    """Opening a project from the start page restores the docks; Qt left tab bars of groups it
    no longer lays out visible at the window's top-left corner, over File and Edit (seen with
    the dock layout a previous session saved)."""
    from PySide6.QtWidgets import QTabBar
    from prismstation.gui.app import take_screenshot
    from prismstation.gui.window_layout import hide_stray_tab_bars
    win = bare_window
    assert win.open_project(demo.path, recover=False)
    take_screenshot(win, tmp_path / "w.png", size=(1280, 720))   # layout, settle, paint
    stray = QTabBar(win)                                        # what Qt left behind
    stray.addTab("Points")
    stray.setGeometry(0, 0, 100, 26)
    stray.show()
    hide_stray_tab_bars(win)
    assert not stray.isVisible()
    menu = win.menuBar().geometry()
    on_screen = [b for b in win.findChildren(QTabBar, options=Qt.FindChildOption.FindDirectChildrenOnly)
                 if b.isVisible() and b.geometry().intersects(win.rect())]   # what the user sees
    assert on_screen, "the Loupe / Contrast group keeps its tabs"
    for b in on_screen:
        assert not b.geometry().intersects(menu), [b.tabText(i) for i in range(b.count())]
        assert b.count() >= 2
