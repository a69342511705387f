"""What the window says when the fit does not stand: a parallax model that does not fit the
GCPs (model panel and accuracy strip), and one blunder threshold shown the same everywhere —
driven through the model panel's controls and clicks on the images."""
from __future__ import annotations

import pyqtgraph as pg
import pytest
from PySide6.QtCore import Qt

from prismstation.core.models.solution import critical_value
from prismstation.gui.accuracy_strip import WARN_COLOR
from tests.gui.test_operator import click_image, key, settle
from tests.qt_windows import close_windows, open_window


def choose(qtbot, combo, text):
    """Open the combo box's list with a click and click ``text`` in it."""
    qtbot.mouseClick(combo, Qt.MouseButton.LeftButton)
    view = combo.view()
    qtbot.waitUntil(view.isVisible, timeout=2000)
    rect = view.visualRect(view.model().index(combo.findText(text), 0))
    qtbot.mouseMove(view.viewport(), rect.center())             # the list follows the pointer
    qtbot.mouseClick(view.viewport(), Qt.MouseButton.LeftButton, pos=rect.center())
    qtbot.waitUntil(lambda: not view.isVisible(), timeout=2000)
    assert combo.currentText() == text


@pytest.fixture()
def demo_window(qtbot, real_demo):
    win = open_window(qtbot, real_demo, size=(1600, 1000))
    yield win
    close_windows(qtbot, win)


def test_a_parallax_model_that_does_not_fit_the_gcps_is_said_so(qtbot, demo_window):
    """On the demo, the 'theoretical' model gave ICP heights 60 m off with no word."""
    win = demo_window
    strip = win.accuracy
    assert strip.warning.text() == "" and "does not fit" not in win.panel.plain_text()
    choose(qtbot, win.panel.parallax, "theoretical")
    settle(qtbot, win)
    assert win.solver.solution.model.parallax.used == "theoretical"
    text = win.panel.plain_text()
    assert "The 'theoretical' parallax model does not fit the GCPs" in text, text
    assert "— does not fit the GCPs" in text                       # in the parallax section's title
    assert strip.warning.isVisible() and strip.warning.text().startswith("⚠ h from the 'theoretical'")
    assert "parallax model does not fit" in strip.warning.shown_text()  # (the wording that fits)
    assert "does not fit the GCPs" in strip.warning.toolTip()
    assert strip.values["h"]._color.name() == WARN_COLOR
    sections = win.panel.sections
    for size in ((1280, 720), (1600, 1000), (1920, 1080)):          # said whole at every size
        win.resize(*size)
        win.default_layout()
        qtbot.wait(50)
        assert "…" not in strip.warning.shown_text() and strip.warning.shown_text().startswith("⚠ h"), size
        seen = win.panel.text.viewport().width()
        for text, sev in sections._notes:                           # wrapped inside what shows
            r = sections._note_rect(text, sev == "bad")
            assert 4 + sections.PAD + r.width() <= seen, (size, text, r.width(), seen)
    win.resize(1600, 1000)
    choose(qtbot, win.panel.parallax, "offset")                     # c1 from the geometry fits
    settle(qtbot, win)
    assert strip.warning.text() == "" and strip.values["h"]._color is None
    assert "The 'offset' parallax model fits the GCPs" in win.panel.plain_text()
    key(qtbot, win, "Ctrl+Z")
    key(qtbot, win, "Ctrl+Z")
    settle(qtbot, win)
    assert win.solver.solution.model.parallax.used == "line" and strip.warning.text() == ""
    assert "parallax model fits" not in win.panel.plain_text()


def test_one_blunder_threshold_everywhere_and_a_gcp_beyond_it_is_flagged(qtbot, window):
    """The panel said 3.29, the plot drew 3.29, 4.44 and 5.96, and a GCP at |w| ≈ 4 was not
    flagged. Now: a GCP moved by clicks until its standardised residual passes 3.29 but stays
    under the old critical value is flagged, and 3.29 is the one line of the plot."""
    win = window
    thr = win.solver.solution.settings.blunder_threshold
    assert thr == 3.29
    win.set_current("G3", drive=True)
    m = win.project.measurement("G3", "N")
    iv = win.views.views["N"]
    iv.center_on(m.x, m.y, 0.25)                       # 4 screen px per image px: fine clicks
    r = None
    for dx in [0.25 * k for k in range(2, 40)]:
        click_image(qtbot, win, "N", m.x + dx, m.y)
        settle(qtbot, win)
        r = win.solver.solution.point("G3")
        if r.std_residual > thr:
            break
    assert thr < r.std_residual < 4.4, r.std_residual
    sol = win.solver.solution
    assert [p.id for p in sol.points if p.blunder] == ["G3"]
    assert win.table_model.is_blunder("G3")
    assert win.table_model.cell("G3", "std. res.") == f"{r.std_residual:.2f}"
    text = win.panel.plain_text()
    assert f"Blunder: G3 — standardised residual {r.std_residual:.2f} > 3.29" in text
    assert "Blunder test — threshold 3.29 (α = 0.001) for every fit" in text
    dof = sol.bias["N"].lsq.dof
    assert f"N bias, redundancy {dof}: |w| > {critical_value(thr, dof):.2f}" in text  # the reason
    ps = win.plots.plots["std_residuals"].getPlotItem()
    lines = [i for i in ps.items if isinstance(i, pg.InfiniteLine) and i.isVisible()]
    assert [ln.value() for ln in lines] == [thr]
    assert lines[0].label.toPlainText() == "blunder threshold 3.29 (α = 0.001)"
    bx, by = win.plots.blunder_pt.getData()
    assert list(by) == [r.std_residual]
    key(qtbot, win, "Ctrl+Z")
    settle(qtbot, win)
    assert not win.table_model.is_blunder("G3") or win.solver.solution.point("G3").std_residual > thr
