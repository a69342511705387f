"""Editing through the real window: stale markers, the status bar, stray clicks, measuring modes
and the point editor — driven by mouse, keys and the table's editors."""
from __future__ import annotations

import math

import numpy as np
from PySide6.QtCore import QPoint, QPointF, Qt
from PySide6.QtGui import QGuiApplication

from prismstation.gui import commands as cmd
from prismstation.gui.palette import KIND_RGB
from tests.gui.test_operator import click_image, key, settle


def screen_pixels(win, view, x, y, half=16, fresh=False):
    """RGB pixels the window shows on screen (its backing store, not a fresh render) in a
    box of ±``half`` screen px around image ``(x, y)`` of ``view``: what the operator sees.
    ``fresh``: the same box of the window rendered anew (what it should show)."""
    iv = win.views.views[view]
    vp = iv.graphics.viewport()
    c = vp.mapTo(win, iv.map_to_viewport(x, y).toPoint())
    img = (win.grab() if fresh else QGuiApplication.primaryScreen().grabWindow(win.winId())).toImage()
    out = np.array([[img.pixelColor(c.x() + i, c.y() + j).getRgb()[:3]
                     for i in range(-half, half + 1)] for j in range(-half, half + 1)])
    return out


def assert_no_ghost(win, view, x, y):
    """The screen around image ``(x, y)`` of ``view`` is what a fresh render shows."""
    assert np.array_equal(screen_pixels(win, view, x, y), screen_pixels(win, view, x, y, fresh=True)), view


def count_colour(px, rgb, tol=40):
    return int(np.sum(np.all(np.abs(px - np.array(rgb)) <= tol, axis=-1)))


MAGENTA = (255, 0, 255)


def drag_marker(qtbot, win, view, x, y, dx, dy):
    """Press on the marker at image ``(x, y)`` of ``view`` and drag it ``(dx, dy)`` screen px."""
    iv = win.views.views[view]
    vp = iv.graphics.viewport()
    start = iv.map_to_viewport(x, y).toPoint() + QPoint(3, 2)
    n = 10
    qtbot.wait(600)
    qtbot.mousePress(vp, Qt.MouseButton.LeftButton, pos=start)
    for i in range(1, n + 1):
        qtbot.wait(25)
        qtbot.mouseMove(vp, start + QPoint(round(dx * i / n), round(dy * i / n)))
    qtbot.mouseRelease(vp, Qt.MouseButton.LeftButton, pos=start + QPoint(dx, dy))


def test_undoing_a_blunder_drag_clears_magenta_in_the_other_views(qtbot, window):
    """A marker dragged in F becomes a blunder (magenta in N, F, B); after
    Ctrl+Z the screen of N and B no longer shows it magenta (it did until a pan)."""
    win = window
    assert not any(r.blunder for r in win.solver.solution.points)
    m = win.project.measurement("G3", "F")
    win.views.views["F"].center_on(m.x, m.y, 1.0)
    drag_marker(qtbot, win, "F", m.x, m.y, 40, -30)
    settle(qtbot, win)
    assert {r.id for r in win.solver.solution.points if r.blunder} == {"G3"}
    qtbot.wait(50)
    for v in ("N", "B"):
        xy = win.project.measurement("G3", v)
        assert count_colour(screen_pixels(win, v, xy.x, xy.y), MAGENTA) > 10, v
    key(qtbot, win, "Ctrl+Z")
    settle(qtbot, win)
    qtbot.wait(50)
    assert not any(r.blunder for r in win.solver.solution.points)
    for v in ("N", "B"):
        xy = win.project.measurement("G3", v)
        assert count_colour(screen_pixels(win, v, xy.x, xy.y), MAGENTA) == 0, v
        assert_no_ghost(win, v, xy.x, xy.y)


YELLOW = KIND_RGB["TIE"]  # tie points (markers, predictions, labels); the images are grey


def free_spot(win, view="N"):
    """Image (x, y) in ``view`` at least 60 px from every measured marker."""
    ov = win.views.overlays[view]
    return next((x, y) for x in range(150, 650, 37) for y in range(150, 650, 41)
                if ov.nearest(x, y, 60) is None)


def measure_new_tie_in_n(qtbot, win):
    """Insert a tie point and click it in N; returns its id and its predicted positions in F
    and B (at the mean height), each view centred on it and showing it in yellow."""
    for iv in win.views.views.values():
        iv.set_scale(1.0)
    x, y = free_spot(win)
    win.views.views["N"].center_on(x, y)
    key(qtbot, win, "Insert")
    pid = win.current
    click_image(qtbot, win, "N", x, y)
    settle(qtbot, win)
    pred = {v: win.views.point_position(pid, v) for v in ("F", "B")}
    for v, xy in pred.items():
        assert win.project.measurement(pid, v) is None and xy is not None
        win.views.views[v].center_on(*xy)
    qtbot.wait(50)
    for v, xy in pred.items():
        assert count_colour(screen_pixels(win, v, *xy), YELLOW) > 10
    return pid, pred


def test_undoing_a_points_creation_leaves_no_ghost_in_the_other_views(qtbot, window):
    """The predicted markers of an undone point stayed on screen in F and B."""
    win = window
    pid, pred = measure_new_tie_in_n(qtbot, win)
    for _ in range(2):                   # the click, then the creation
        key(qtbot, win, "Ctrl+Z")
    settle(qtbot, win)
    qtbot.wait(50)
    assert pid not in win.project.points
    assert win.current is None           # no current point that no longer exists
    for v, xy in pred.items():
        assert count_colour(screen_pixels(win, v, *xy), YELLOW) == 0, v
        assert_no_ghost(win, v, *xy)


def test_deleting_a_points_only_measurement_leaves_no_ghost(qtbot, window):
    """Del on a point's only measurement left its predictions on screen."""
    win = window
    pid, pred = measure_new_tie_in_n(qtbot, win)
    n = win.project.measurement(pid, "N")
    iv = win.views.views["N"]
    qtbot.mouseMove(iv.graphics.viewport(), iv.map_to_viewport(n.x + 30, n.y).toPoint())
    key(qtbot, win, "Del")               # in the view under the cursor
    settle(qtbot, win)
    qtbot.wait(50)
    assert win.project.measurement(pid, "N") is None and pid in win.project.points
    assert count_colour(screen_pixels(win, "N", n.x, n.y), YELLOW) == 0
    assert_no_ghost(win, "N", n.x, n.y)
    for v, xy in pred.items():
        assert count_colour(screen_pixels(win, v, *xy), YELLOW) == 0, v
        assert_no_ghost(win, v, *xy)


# ---------------------------------------------------------------------------- status bar (bug 7)
def test_status_bar_shows_whole_coordinates_even_of_16000_row_images(qtbot, window):
    win = window
    win.statusBar().clearMessage()  # (a message in the status bar has the views' fields' room)
    for size in ((1280, 720), (1600, 1000), (1920, 1080)):
        win.resize(*size)
        qtbot.wait(30)
        iv = win.views.views["N"]
        qtbot.mouseMove(iv.graphics.viewport(), iv.map_to_viewport(412.3, 377.8).toPoint())
        qtbot.wait(20)
        labels = list(win.status_xy.values()) + [win.status_ground, win.measure_mode.label]
        for lab in labels:
            assert lab.text() != "N  —" or lab is not win.status_xy["N"]
            assert lab.shown_text() == lab.text(), (size, lab.text())
        # a 16,000-row scene, the cursor off its top-left corner in F
        win.views.cursor_info.emit("N", 14999.9, 16383.7, {"F": (-1234.5, -16001.2), "B": (99999.9, 15999.9)},
                                   (523456.7, 4567890.1, -123.4))
        for lab in labels:
            assert "…" not in lab.shown_text() and lab.shown_text() == lab.text(), (size, lab.text())
            assert lab.isVisible() and win.rect().contains(lab.mapTo(win, lab.rect().bottomRight()))
        assert win.status_xy["N"].text() == "N  x 14999.9  y 16383.7"
        assert win.status_xy["F"].text() == "F  x -1234.5  y -16001.2"


# ---------------------------------------------------------------------------- stray click (bug 8)
def test_a_click_with_no_current_point_creates_nothing(qtbot, window):
    win = window
    win.set_current(None)
    n_points, n_steps = len(win.project.points), win.undo_stack.count()
    xy = free_spot(win)
    win.views.views["N"].center_on(*xy, 1.0)
    click_image(qtbot, win, "N", *xy)
    qtbot.wait(50)
    assert len(win.project.points) == n_points and win.undo_stack.count() == n_steps
    assert win.current is None
    assert "No current point" in win.statusBar().currentMessage()
    from PySide6.QtWidgets import QToolTip
    qtbot.waitUntil(lambda: QToolTip.isVisible() and "press C" in QToolTip.text(), timeout=2000)  # at the click
    assert win.tools["transfer"].pid is None          # no transfer started either
    assert win.measure_mode.label.text() == "Mode: measure (no point)"


# ---------------------------------------------------------------------------- modes (item 10)
def test_modes_by_key_and_toolbar_show_in_cursor_and_status_bar(qtbot, window):
    from PySide6.QtWidgets import QToolBar
    win = window
    mm = win.measure_mode
    vp = win.views.views["N"].graphics.viewport()
    assert mm.mode == "measure" and vp.cursor().shape() == Qt.CursorShape.CrossCursor

    # navigate (V): a click places nothing, a drag on a marker pans instead of moving it
    win.set_current("G2", drive=True)
    key(qtbot, win, "V")
    assert mm.mode == "navigate" and mm.label.text() == "Mode: navigate"
    assert vp.cursor().shape() == Qt.CursorShape.OpenHandCursor
    assert mm.actions["navigate"].isChecked()
    before = dict(win.project.measurements)
    n_steps = win.undo_stack.count()
    m = win.project.measurement("G2", "N")
    qtbot.wait(600)
    click_image(qtbot, win, "N", m.x + 40, m.y + 40)
    centre = win.views.views["N"].center()
    drag_marker(qtbot, win, "N", m.x, m.y, 40, 30)
    assert dict(win.project.measurements) == before and win.undo_stack.count() == n_steps
    assert win.views.views["N"].center() != centre            # it panned

    # create (the toolbar button): a click makes a tie point, then the mode measures it
    tb = win.findChild(QToolBar, "toolbar_main")
    qtbot.mouseClick(tb.widgetForAction(mm.actions["create"]), Qt.MouseButton.LeftButton)
    assert mm.mode == "create" and mm.label.text() == "Mode: create point"
    assert vp.cursor().shape() == Qt.CursorShape.BitmapCursor
    xy = free_spot(win)
    win.views.views["N"].center_on(*xy, 1.0)
    qtbot.wait(600)
    click_image(qtbot, win, "N", *xy)
    pid = win.current
    assert pid not in before and win.project.points[pid].kind == "TIE"
    assert mm.mode == "measure" and mm.label.text() == f"Mode: measure {pid}"
    assert vp.cursor().shape() == Qt.CursorShape.CrossCursor
    settle(qtbot, win)
    f = win.views.point_position(pid, "F")
    win.views.views["F"].center_on(*f, 1.0)
    click_image(qtbot, win, "F", *f)                           # measure (M): the current point
    assert win.project.measurement(pid, "F") is not None and win.current == pid
    key(qtbot, win, "M")
    assert mm.actions["measure"].isChecked()
    # the menu lists the modes with their keys
    texts = [a.text() for a in win.edit_menu.actions()]
    assert {"&Create point", "&Measure point", "Na&vigate"} <= set(texts)


# ---------------------------------------------------------------------------- point editor (item 9)
def type_into_cell(qtbot, win, pid, column, text):
    """Double-click the cell, select what is there, type ``text``, Enter."""
    from PySide6.QtWidgets import QApplication, QLineEdit
    from prismstation.gui.point_table import COLUMNS
    t, m = win.table, win.table_model
    idx = m.index(m.row_of(pid), COLUMNS.index(column))
    t.scrollTo(idx)
    pos = t.visualRect(idx).center()
    qtbot.mouseClick(t.viewport(), Qt.MouseButton.LeftButton, pos=pos)  # a double click's first half
    qtbot.mouseDClick(t.viewport(), Qt.MouseButton.LeftButton, pos=pos)
    editor = QApplication.focusWidget()
    assert isinstance(editor, QLineEdit), editor
    qtbot.keyClick(editor, Qt.Key.Key_A, Qt.KeyboardModifier.ControlModifier)
    qtbot.keyClick(editor, Qt.Key.Key_Backspace)
    qtbot.keyClicks(editor, text)
    qtbot.keyClick(editor, Qt.Key.Key_Return)
    qtbot.wait(10)


def choose_kind(qtbot, win, pid, kind):
    """Double-click the Kind cell, choose ``kind`` in its list by keyboard, Enter."""
    from PySide6.QtWidgets import QApplication, QComboBox
    from prismstation.gui.point_table import COLUMNS
    t, m = win.table, win.table_model
    idx = m.index(m.row_of(pid), COLUMNS.index("Kind"))
    t.scrollTo(idx)
    pos = t.visualRect(idx).center()
    qtbot.mouseClick(t.viewport(), Qt.MouseButton.LeftButton, pos=pos)
    qtbot.mouseDClick(t.viewport(), Qt.MouseButton.LeftButton, pos=pos)
    box = QApplication.focusWidget()
    assert isinstance(box, QComboBox), box
    qtbot.keyClicks(box, kind[0])                # the first letter picks the item
    assert box.currentText() == kind
    qtbot.keyClick(box, Qt.Key.Key_Return)
    qtbot.wait(10)


def test_typing_coordinates_sigma_kind_and_id_in_the_table(qtbot, window):
    win = window
    p, m = win.project, win.table_model
    g9 = p.points["G9"]
    key(qtbot, win, "Insert")
    tie = win.current
    n0 = win.undo_stack.count()
    type_into_cell(qtbot, win, "G9", "E (m)", f"{g9.E + 12.5:.3f}")
    assert p.points["G9"].E == round(g9.E + 12.5, 3) and p.points["G9"].N == g9.N
    assert win.undo_stack.count() == n0 + 1 and win.undo_stack.undoText() == "G9: E"
    type_into_cell(qtbot, win, "G9", "σ plan (m)", "0,25")       # a decimal comma
    type_into_cell(qtbot, win, "G9", "σ h (m)", "0.4")
    assert (p.points["G9"].sigma_xy_m, p.points["G9"].sigma_h_m) == (0.25, 0.4)
    settle(qtbot, win)
    assert m.cell("G9", "σ plan (m)") == "0.250" and m.cell("G9", "E (m)") == f"{g9.E + 12.5:.3f}"
    choose_kind(qtbot, win, "G9", "ICP")
    assert p.points["G9"].kind == "ICP"
    assert win.undo_stack.count() == n0 + 4                      # one step per edit

    # refused, with the reason in the status bar; nothing changes
    choose_kind(qtbot, win, tie, "GCP")          # a tie point without coordinates
    assert "needs E, N and H" in win.statusBar().currentMessage()
    from PySide6.QtWidgets import QToolTip
    qtbot.waitUntil(lambda: QToolTip.isVisible() and "needs E, N" in QToolTip.text(), timeout=2000)  # beside the cell
    type_into_cell(qtbot, win, "G2", "H (m)", "")
    assert "needs E, N and H" in win.statusBar().currentMessage()
    type_into_cell(qtbot, win, "G2", "E (m)", "abc")
    assert "'abc' is not a number" in win.statusBar().currentMessage()
    type_into_cell(qtbot, win, "G2", "ID", "G3")
    assert "already exists" in win.statusBar().currentMessage()
    assert win.undo_stack.count() == n0 + 4

    # rename: the measurements follow, the point stays current; undo gives the old id back
    ms = {v: win.project.measurement("G2", v) for v in ("N", "F", "B")}
    win.set_current("G2", drive=False)
    type_into_cell(qtbot, win, "G2", "ID", "G2a")
    assert "G2" not in p.points and p.points["G2a"].kind == "GCP"
    assert all((p.measurement("G2a", v).x, p.measurement("G2a", v).y) == (ms[v].x, ms[v].y) for v in ms)
    assert win.current == "G2a"
    settle(qtbot, win)
    assert m.row_of("G2a") >= 0 and m.row_of("G2") < 0
    win.table.setFocus()
    for _ in range(5):
        key(qtbot, win, "Ctrl+Z")
    settle(qtbot, win)
    assert "G2a" not in p.points and all(p.measurement("G2", v) == ms[v] for v in ms)
    assert p.points["G9"].E == g9.E and p.points["G9"].kind == g9.kind and p.points["G9"].sigma_xy_m is None
    assert win.undo_stack.count() == n0 + 5 and win.undo_stack.index() == n0


def test_paste_points_and_cells_each_one_step(qtbot, window):
    from prismstation.gui.point_table import COLUMNS
    win = window
    p, t, m = win.project, win.table, win.table_model
    g2 = p.points["G2"]
    clip = QGuiApplication.clipboard()
    clip.setText(f"P100\t{g2.E + 40:.3f}\t{g2.N - 30:.3f}\t{g2.H + 2:.3f}\n"
                 f"G2\t{g2.E + 1:.3f}\t{g2.N:.3f}\t{g2.H:.3f}\t0.3\t0.5\n")
    n0 = win.undo_stack.count()
    idx = m.index(0, 0)
    qtbot.mouseClick(t.viewport(), Qt.MouseButton.LeftButton, pos=t.visualRect(idx).center())
    qtbot.keyClick(t, Qt.Key.Key_V, Qt.KeyboardModifier.ControlModifier)
    assert p.points["P100"].kind == "GCP" and p.points["P100"].E == round(g2.E + 40, 3)
    assert p.points["P100"].height_kind == g2.height_kind
    assert p.points["G2"].E == round(g2.E + 1, 3) and p.points["G2"].sigma_h_m == 0.5
    assert win.undo_stack.count() == n0 + 1 and win.undo_stack.undoText() == "Paste 2 points"
    settle(qtbot, win)
    assert all(v is not None for v in (win.views.point_position("P100", v) for v in "NFB"))

    # numbers into the E cell of a tie point's row: E N H from there
    win.measure_mode.set_mode("navigate")
    key(qtbot, win, "Insert")
    tie = win.current
    settle(qtbot, win)
    idx = m.index(m.row_of(tie), COLUMNS.index("E (m)"))
    t.scrollTo(idx)
    qtbot.mouseClick(t.viewport(), Qt.MouseButton.LeftButton, pos=t.visualRect(idx).center())
    clip.setText("541000.5 4561000.25 612.0\n")
    qtbot.keyClick(t, Qt.Key.Key_V, Qt.KeyboardModifier.ControlModifier)
    assert (p.points[tie].E, p.points[tie].N, p.points[tie].H) == (541000.5, 4561000.25, 612.0)
    assert win.undo_stack.undoText() == "Paste 1 point"
    key(qtbot, win, "Ctrl+Z")
    assert math.isnan(p.points[tie].E)
    key(qtbot, win, "Ctrl+Z")                   # (the new point)
    key(qtbot, win, "Ctrl+Z")
    assert "P100" not in p.points and p.points["G2"] == g2


def test_new_gcp_by_coordinates_then_measured(qtbot, window):
    from PySide6.QtCore import QTimer
    from PySide6.QtWidgets import QApplication
    win, demo = window, window.demo
    g = win.project.points["G9"]           # known ground, not measured: the truth is known
    win.undo_stack.push(cmd.DeletePoint(win.project, "G9"))  # to be added again by coordinates
    settle(qtbot, win)
    typed = []

    def fill():
        dlg = QApplication.activeModalWidget()
        dlg.id_edit.selectAll()
        qtbot.keyClicks(dlg.id_edit, "K1")
        for w, v in ((dlg.e, g.E), (dlg.n, g.N), (dlg.h, g.H)):
            w.setFocus()
            qtbot.keyClicks(w, f"{v:.3f}")
        dlg.s_xy.setFocus()
        qtbot.keyClicks(dlg.s_xy, "0.2")
        typed.append(True)
        qtbot.keyClick(dlg.s_xy, Qt.Key.Key_Return)
    QTimer.singleShot(200, fill)
    win.point_editor.a_new_gcp.trigger()
    assert typed
    p = win.project
    assert p.points["K1"].kind == "GCP" and p.points["K1"].sigma_xy_m == 0.2
    assert p.points["K1"].height_kind == g.height_kind
    assert abs(p.points["K1"].E - g.E) < 1e-3
    assert win.current == "K1" and win.measure_mode.mode == "measure"
    settle(qtbot, win)
    for v, (x, y) in demo.truth["G9"].items():      # predicted where it is, then clicked there
        px, py = win.views.point_position("K1", v)
        assert math.hypot(px - x, py - y) < 3.0
        win.views.views[v].center_on(x, y, 1.0)
        qtbot.wait(600)
        click_image(qtbot, win, v, x, y)
    settle(qtbot, win)
    assert win.table_model.cell("K1", "Views") == "N F B"
    assert win.solver.solution.point("K1").residual_px


def test_edits_typed_in_the_table_are_saved_and_reopened(qtbot, window):
    win = window
    type_into_cell(qtbot, win, "I3", "σ h (m)", "0.75")
    type_into_cell(qtbot, win, "I3", "N (m)", "4560123.456")
    type_into_cell(qtbot, win, "I3", "ID", "I3b")
    type_into_cell(qtbot, win, "I2", "ID", "CMV2")         # the mode keys go into the cell
    assert "CMV2" in win.project.points and win.measure_mode.mode == "measure"
    key(qtbot, win, "Ctrl+S")
    assert win.undo_stack.isClean()
    assert win.open_project(win.demo.path, recover=False)
    settle(qtbot, win)
    p = win.project
    assert "I3" not in p.points and p.points["I3b"].sigma_h_m == 0.75 and p.points["I3b"].N == 4560123.456
    assert {v for (pid, v) in p.measurements if pid == "I3b"} == {"N", "F", "B"}
    assert win.table_model.cell("I3b", "σ h (m)") == "0.750"


def test_enter_in_a_cell_commits_the_edit_even_with_a_transfer_pending(qtbot, window):
    """Enter and Esc are window shortcuts while a transfer waits (accept, reject): in a cell
    being edited they commit or cancel the edit, and leave the transfer alone."""
    win = window
    tool = win.tools["transfer"]
    tool.a_accept.setEnabled(True)            # as when candidates are shown
    tool.a_reject.setEnabled(True)
    fired = []
    tool.a_accept.triggered.connect(lambda *_: fired.append("accept"))
    tool.a_reject.triggered.connect(lambda *_: fired.append("reject"))
    type_into_cell(qtbot, win, "I2", "σ plan (m)", "0.3")
    assert win.project.points["I2"].sigma_xy_m == 0.3 and fired == []
    choose_kind(qtbot, win, "I2", "GCP")
    assert win.project.points["I2"].kind == "GCP" and fired == []


def test_insert_then_a_click_on_another_marker_leaves_no_empty_point(qtbot, window):
    win = window
    n0 = win.undo_stack.count()
    key(qtbot, win, "Insert")
    pid = win.current
    assert pid in win.project.points and win.undo_stack.count() == n0 + 1
    m = win.project.measurement("G3", "N")
    win.views.views["N"].center_on(m.x, m.y, 1.0)
    qtbot.wait(20)
    click_image(qtbot, win, "N", m.x + 1, m.y)  # on G3's marker: picks G3
    assert win.current == "G3"
    assert pid not in win.project.points and win.undo_stack.index() == n0
    settle(qtbot, win)
    assert win.table_model.row_of(pid) < 0
    # a point given something before it is left stays
    key(qtbot, win, "Insert")
    kept = win.current
    settle(qtbot, win)
    type_into_cell(qtbot, win, kept, "E (m)", "1000")
    win.set_current("G3", drive=False)
    assert kept in win.project.points
