"""Transfer in the real window through real input: the candidates drive F and B to themselves,
*Transfer this point* (Ctrl+T) for a point measured in one view, the prior height from the
reference DEM, and calibrated σ — against the simulator's truth."""
from __future__ import annotations

import re

import numpy as np
import pytest
from PySide6.QtCore import Qt

from tests.gui.test_operator import click_image

SHIFT = Qt.KeyboardModifier.ShiftModifier


def _new_point_in_n(qtbot, window, xy):
    window.set_current(None)
    qtbot.keyClick(window, Qt.Key.Key_Insert)            # New point
    pid = window.current
    window.views.views["N"].center_on(*xy, 0.5)
    click_image(qtbot, window, "N", *xy, SHIFT)
    return pid


def test_candidates_drive_the_views_and_carry_a_believable_sigma(qtbot, window, truth):
    tool = window.tools["transfer"]
    t = [t for t in truth.values() if t["kind"] == "ICP"][1]
    for v in "FB":                                       # at the overview
        window.views.views[v].fit()
        assert window.views.views[v].scale() > 1.5
    pid = _new_point_in_n(qtbot, window, t["image"]["N"])  # N at 0.5 image px per screen px
    qtbot.waitUntil(lambda: bool(tool.candidates), timeout=10000)
    clicked = window.project.measurement(pid, "N")       # a click lands on a screen pixel:
    off_n = np.subtract((clicked.x, clicked.y), t["image"]["N"])  # up to ½ px from the truth
    for v, c in tool.candidates.items():
        assert c.ok
        cx, cy = window.views.views[v].center()
        assert np.hypot(cx - c.x, cy - c.y) < 0.5, v     # driven to its candidate ...
        assert window.views.views[v].scale() == pytest.approx(0.5, rel=1e-3), v  # ... at N's zoom
        # the truth of the point clicked (same GSD and orientation: N's offset carries over)
        err = np.subtract((c.x, c.y), np.add(t["image"][v], off_n))
        assert np.hypot(*err) < 0.6
        m = c.match          # σ: with the relief the patch cannot follow, not the formal 0.02 px
        assert m.sigma_x > m.formal_sigma_x and m.sigma_y > 3 * m.formal_sigma_y
        assert np.all(np.abs(err) < 4 * np.array([m.sigma_x, m.sigma_y]))
    first = tool.candidates[tool.panel.table.item(0, 0).text()].match
    assert tool.panel.table.item(0, 5).text() == f"{first.sigma_y:.3f}"   # the dock shows it
    assert window.project.measurement(pid, "F") is None


def test_a_point_placed_at_the_overview_is_shown_in_detail(qtbot, window, truth):
    """Every view at the overview, a point clicked in N: the views go to the point and its
    candidates at one image pixel per screen pixel, not left at the overview."""
    tool = window.tools["transfer"]
    t = [t for t in truth.values() if t["kind"] == "ICP"][3]
    window.views.fit_all()
    window.set_current(None)
    qtbot.keyClick(window, Qt.Key.Key_Insert)            # New point
    pid = window.current
    assert window.views.views["N"].scale() > 1.5
    click_image(qtbot, window, "N", *t["image"]["N"], SHIFT)
    qtbot.waitUntil(lambda: bool(tool.candidates), timeout=10000)
    assert set(tool.candidates) == {"F", "B"}
    m = window.project.measurement(pid, "N")
    for v in "NFB":
        iv = window.views.views[v]
        x, y = (m.x, m.y) if v == "N" else (tool.candidates[v].x, tool.candidates[v].y)
        assert iv.scale() == pytest.approx(1.0, rel=1e-3), v
        assert np.hypot(*np.subtract(iv.center(), (x, y))) < 0.5, v


def test_automatic_tie_points_from_the_menu_end_with_a_summary(qtbot, window):
    """Tools ▸ Automatic tie points…, the dialog answered: the ties are added in one step,
    numbered on from the project's tie ids, and the status line says how many of the grid
    points were added, not found and why, rejected, and the across-track RMS."""
    from PySide6.QtCore import QTimer
    from PySide6.QtWidgets import QApplication, QDialog, QSpinBox

    tool = window.tools["transfer"]
    p = window.project
    before, depth = set(p.points), window.undo_stack.count()
    action = next(a for a in window.tools_menu.actions() if a.text() == "Automatic tie &points…")

    def answer():
        dlg = QApplication.activeModalWidget()
        if not isinstance(dlg, QDialog):
            QTimer.singleShot(50, answer)
            return
        dlg.findChild(QSpinBox).setValue(4)
        dlg.accept()
    QTimer.singleShot(50, answer)
    action.trigger()
    qtbot.waitUntil(lambda: bool(tool.summary), timeout=60000)
    new = sorted(set(p.points) - before)
    status = window.statusBar().currentMessage()
    assert status == f"Automatic tie points: {tool.summary}"
    added = int(tool.summary.split(" of ")[0])
    assert added == len(new) and "of 16 grid points added" in tool.summary
    assert window.undo_stack.count() == depth + (1 if new else 0)
    numbers = [int(i[1:]) for i in before if i.startswith("T") and i[1:].isdigit()]
    assert [int(i[1:]) for i in new] == list(range(max(numbers, default=0) + 1,
                                                   max(numbers, default=0) + 1 + len(new)))
    not_found = re.search(r"; (\d+) not found in F and B \(([^)]*)\)", tool.summary)
    blunders = re.search(r"; (\d+) rejected as blunders", tool.summary)
    n_nf = int(not_found.group(1)) if not_found else 0
    assert added + n_nf + (int(blunders.group(1)) if blunders else 0) == 16
    if not_found:   # each reason counted: the counts add up to the points not found
        assert sum(int(w.split()[0]) for w in not_found.group(2).split(", ")) == n_nf
    assert re.search(r"across-track RMS (\d+\.\d\d) px\.$", tool.summary)
    print(f"\n{tool.summary}")


def test_transfer_this_point_from_the_menu_key(qtbot, window, truth):
    tool = window.tools["transfer"]
    tool.a_auto.setChecked(False)
    t = [t for t in truth.values() if t["kind"] == "ICP"][2]
    pid = _new_point_in_n(qtbot, window, t["image"]["N"])
    qtbot.wait(50)
    assert not tool.candidates and tool.a_this.isEnabled()
    assert tool.a_this in window.tools_menu.actions()
    qtbot.keyClick(window, Qt.Key.Key_T, Qt.KeyboardModifier.ControlModifier)   # Ctrl+T
    qtbot.waitUntil(lambda: bool(tool.candidates), timeout=10000)
    assert tool.pid == pid and set(tool.candidates) == {"F", "B"}
    qtbot.keyClick(window.views.views["N"].graphics, Qt.Key.Key_Return)
    clicked = window.project.measurement(pid, "N")       # the click's own ½ px carries over
    off_n = np.subtract((clicked.x, clicked.y), t["image"]["N"])
    for v in "FB":
        m = window.project.measurement(pid, v)
        assert np.hypot(*np.subtract((m.x, m.y), np.add(t["image"][v], off_n))) < 0.6
    assert not tool.a_this.isEnabled()                   # measured everywhere now


def test_prior_height_from_the_reference_dem(qtbot, window, truth, sim):
    tool = window.tools["transfer"]
    sol = window.solver.solution
    t = [t for t in truth.values() if t["kind"] == "TIE"][0]
    h0, r0 = tool.prior_height(sol, "N", *t["image"]["N"])
    assert r0 >= 3 * 50.0                                # the mean height: the spread of heights
    window.load_reference_dem(sim / "srtm.tif", wait=True)
    qtbot.waitUntil(lambda: window.views.height_of is not None and not window.solver.busy(), timeout=10000)
    qtbot.wait(20)
    h, r = tool.prior_height(sol, "N", *t["image"]["N"])
    assert r < r0 and r == max(3 * window.views.predictions.sigma_dem, 50.0)
    assert abs(h - t["h"]) < max(3 * window.views.predictions.sigma_dem, 30.0)
