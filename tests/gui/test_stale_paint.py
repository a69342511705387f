"""Stale paint and text, through real input: what the screen shows after an edit, an undo or
a redo is what a fresh render of the window shows (labels, status bar, progress, another
project's coordinates)."""
from __future__ import annotations

import numpy as np
import pytest

from tests.gui.test_editing import YELLOW, count_colour, measure_new_tie_in_n, screen_pixels
from tests.gui.test_operator import key, settle


def assert_screen_is_fresh(win, view, x, y, half=60):
    """The screen (backing store) around image ``(x, y)`` of ``view`` — a box wide enough for
    a label beside its marker — is what a fresh render of the window shows."""
    shown = screen_pixels(win, view, x, y, half)
    fresh = screen_pixels(win, view, x, y, half, fresh=True)
    bad = np.argwhere(np.any(shown != fresh, axis=-1))
    assert not len(bad), f"{view}: {len(bad)} stale pixels, e.g. at {(bad[:5] - half).tolist()} px"


@pytest.mark.parametrize("scale", [1.0, 0.25])
def test_undo_and_redo_of_a_placement_repaint_the_whole_label(qtbot, window, scale):
    """Undoing a placement left the last digit of "T71" in F and B; after redo the label read
    "T7": zoomed in past ~2×, a label's own repaint was dropped (its bounding rectangle of
    ±1e9 px overflowed Qt's integer screen coordinates) and it showed only where other items
    repainted."""
    win = window
    pid, pred = measure_new_tie_in_n(qtbot, win)
    for v, xy in pred.items():
        win.views.views[v].center_on(*xy, scale)
    qtbot.wait(50)
    for v, xy in pred.items():
        assert_screen_is_fresh(win, v, *xy)
    for step in ("Ctrl+Z", "Ctrl+Shift+Z", "Ctrl+Z"):   # undo the placement, redo, undo
        key(qtbot, win, step)
        settle(qtbot, win)
        qtbot.wait(50)
        for v, xy in pred.items():
            assert_screen_is_fresh(win, v, *xy)


def test_labels_off_and_on_at_every_zoom(qtbot, window):
    """Ctrl+L takes every label off the screen and puts it back, zoomed out and in (zoomed in
    past ~2× the labels' own repaint was dropped: they stayed)."""
    win = window
    pid, pred = measure_new_tie_in_n(qtbot, win)
    x, y = pred["F"]
    iv = win.views.views["F"]
    for scale in (2.0, 1.0, 0.25, 0.1):
        iv.center_on(x, y, scale)
        qtbot.wait(50)
        with_labels = screen_pixels(win, "F", x, y, 60)
        key(qtbot, win, "Ctrl+L")
        qtbot.wait(50)
        assert_screen_is_fresh(win, "F", x, y)
        assert count_colour(with_labels, YELLOW) > count_colour(screen_pixels(win, "F", x, y, 60), YELLOW)
        key(qtbot, win, "Ctrl+L")
        qtbot.wait(50)
        assert_screen_is_fresh(win, "F", x, y)
        assert np.array_equal(screen_pixels(win, "F", x, y, 60), with_labels), scale


def test_a_good_edit_takes_an_old_error_off_the_status_bar(qtbot, window):
    from tests.gui.test_editing import type_into_cell
    from tests.gui.test_operator import click_image
    win = window
    type_into_cell(qtbot, win, "G2", "E (m)", "abc")
    assert "'abc' is not a number" in win.statusBar().currentMessage()
    win.set_current("G2", drive=True)
    m = win.project.measurement("G2", "N")
    click_image(qtbot, win, "N", m.x + 0.6, m.y)         # a good edit: G2 moved in N
    settle(qtbot, win)
    assert win.project.measurement("G2", "N") != m
    assert "not a number" not in win.statusBar().currentMessage()
    type_into_cell(qtbot, win, "G2", "E (m)", "abc")
    key(qtbot, win, "Ctrl+Z")                            # an undo is an edit too
    assert win.statusBar().currentMessage() == ""


def test_opening_another_project_shows_none_of_the_previous_ones_figures(qtbot, window, demo_master):
    from PySide6.QtCore import QPoint

    from prismstation.gui.app import wait_settled
    win = window
    other = str(demo_master.path)
    assert win.open_project(other, recover=False)             # now a recent file
    assert win.open_project(win.demo.path, recover=False)
    assert wait_settled(win)
    vp = win.views.views["N"].graphics.viewport()
    qtbot.mouseMove(vp, QPoint(vp.width() // 2, vp.height() // 2))   # the cursor over N
    qtbot.waitUntil(lambda: win.status_xy["N"].text().startswith("N  x ")
                    and "—" not in win.status_ground.text(), timeout=3000)
    action = next(a for a in win.recent_menu.actions() if a.text() == other)
    action.trigger()                                          # File ▸ Recent ▸ the other one
    qtbot.waitUntil(lambda: str(win.files.path) == other, timeout=5000)
    assert [lab.text() for lab in win.status_xy.values()] == ["N  —", "F  —", "B  —"]
    assert win.status_ground.text() == "E —  N —  h —"
