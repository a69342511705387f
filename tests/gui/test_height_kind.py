"""One height-kind rule for every way a point enters the project — typed into the table,
pasted, by coordinates, imported from a CSV or another tool's file — the project's kind unless
the operator says otherwise, shown in the table's Height column; driven through the real window.

The project is orthometric (heights above a 55 m geoid, as the demo's): a height stored as
ellipsoidal by mistake sits 55 m off, which is what an operator once got without a word."""
from __future__ import annotations

import pytest
from PySide6.QtCore import Qt, QTimer
from PySide6.QtGui import QGuiApplication
from PySide6.QtWidgets import QApplication, QDialogButtonBox

from tests.gui.sim_project import copy_sim, make_sim
from tests.gui.test_editing import type_into_cell
from tests.gui.test_operator import click_image, key, settle
from tests.qt_windows import close_windows, open_window


@pytest.fixture(scope="module")
def sim_master(tmp_path_factory):
    return make_sim(tmp_path_factory.mktemp("ortho"))


@pytest.fixture()
def win(qtbot, sim_master, tmp_path):
    d = copy_sim(sim_master, tmp_path / "sim")
    w = open_window(qtbot, d / "p.prismproj")
    w.sim = d
    yield w
    close_windows(qtbot, w)


def choose_in_cell(qtbot, win, pid, column, text):
    """Double-click the cell, pick ``text`` in its list by its first letter, Enter."""
    from PySide6.QtWidgets import QComboBox
    from prismstation.gui.point_table import COLUMNS
    t, m = win.table, win.table_model
    idx = m.index(m.row_of(pid), COLUMNS.index(column))
    t.scrollTo(idx)
    pos = t.visualRect(idx).center()
    qtbot.mouseClick(t.viewport(), Qt.MouseButton.LeftButton, pos=pos)
    qtbot.mouseDClick(t.viewport(), Qt.MouseButton.LeftButton, pos=pos)
    box = QApplication.focusWidget()
    assert isinstance(box, QComboBox), box
    qtbot.keyClicks(box, text[0])
    assert box.currentText() == text
    qtbot.keyClick(box, Qt.Key.Key_Return)
    qtbot.wait(10)


def import_through_the_dialog(qtbot, win, path, height_kind=None):
    """Ctrl+I, type the file's path and Enter, optionally choose the height kind, Import."""
    seen = {}

    def drive():
        dlg = QApplication.activeModalWidget()
        seen["default"] = dlg.height_kind.currentText()
        dlg.path_edit.setFocus()
        qtbot.keyClicks(dlg.path_edit, str(path))
        qtbot.keyClick(dlg.path_edit, Qt.Key.Key_Return)
        if height_kind is not None:
            dlg.height_kind.setCurrentText(height_kind)
            dlg.refresh()
        seen["errors"] = dlg.errors()
        qtbot.mouseClick(dlg.buttons.button(QDialogButtonBox.StandardButton.Ok), Qt.MouseButton.LeftButton)
    QTimer.singleShot(300, drive)
    key(qtbot, win, "Ctrl+I")
    activate(qtbot, win)
    return seen


def activate(qtbot, win):
    """Offscreen, a closed dialog hands the activation back to no window (a window manager
    gives it to the main window): the keys and editors that follow need it."""
    win.activateWindow()
    qtbot.waitUntil(lambda: QApplication.activeWindow() is win, timeout=2000)


def test_every_way_in_takes_the_projects_height_kind(qtbot, win):
    p = win.project
    assert p.height_kind() == "orthometric"
    g = p.points["G02"]
    E, N, H = g.E + 300.0, g.N + 200.0, g.H + 5.0

    # typed into the table: a new tie point, and a tie point of the file (stored "ellipsoidal"
    # with no height before)
    key(qtbot, win, "Insert")
    tie = win.current
    settle(qtbot, win)
    for col, v in (("E (m)", E), ("N (m)", N), ("H (m)", H)):
        type_into_cell(qtbot, win, tie, col, f"{v:.3f}")
    assert p.points[tie].H == round(H, 3) and p.points[tie].height_kind == "orthometric"
    assert p.points["T01"].height_kind == "ellipsoidal" and p.points["T01"].H != p.points["T01"].H
    assert win.table_model.cell("T01", "Height") == ""          # no height, no kind shown
    for col, v in (("E (m)", E + 10), ("N (m)", N), ("H (m)", H)):
        type_into_cell(qtbot, win, "T01", col, f"{v:.3f}")
    assert p.points["T01"].height_kind == "orthometric"
    settle(qtbot, win)
    assert win.table_model.cell("T01", "Height") == "orthometric"

    # pasted rows of new points
    QGuiApplication.clipboard().setText(f"Q1\t{E + 20:.3f}\t{N:.3f}\t{H:.3f}\n")
    win.table.setFocus()
    key(qtbot, win.table, "Ctrl+V")
    assert p.points["Q1"].height_kind == "orthometric"

    # by coordinates (the dialog offers the project's kind)
    offered = []

    def fill():
        dlg = QApplication.activeModalWidget()
        offered.append(dlg.height_kind.currentText())
        for w, v in ((dlg.e, E + 30), (dlg.n, N), (dlg.h, H)):
            w.setFocus()
            qtbot.keyClicks(w, f"{v:.3f}")
        qtbot.keyClick(dlg.h, Qt.Key.Key_Return)
    QTimer.singleShot(300, fill)
    key(qtbot, win, "Ctrl+Shift+N")
    activate(qtbot, win)
    new = win.current
    assert offered == ["orthometric"] and p.points[new].height_kind == "orthometric"

    # imported: a CSV without a height-kind column, another tool's file (OpenDroneMap)
    csv = win.sim / "more.csv"
    csv.write_text(f"id,E,N,H\nR1,{E + 40:.3f},{N:.3f},{H:.3f}\n")
    seen = import_through_the_dialog(qtbot, win, csv)
    assert seen == {"default": "orthometric", "errors": []}
    assert p.points["R1"].height_kind == "orthometric"
    odm = win.sim / "gcp_list.txt"
    n_x, n_y = p.measurement("G02", "N").x, p.measurement("G02", "N").y
    odm.write_text(f"EPSG:32629\n{E + 50:.3f} {N:.3f} {H:.3f} {n_x - 0.5:.2f} {n_y - 0.5:.2f} N.tif R2\n")
    seen = import_through_the_dialog(qtbot, win, odm)
    assert seen["default"] == "orthometric" and not seen["errors"], seen
    assert p.points["R2"].height_kind == "orthometric"

    # unless the operator says otherwise: the dialog's choice, the table's Height cell; an H of
    # the other kind is tinted in the table, with the reason
    seen = import_through_the_dialog(qtbot, win, _csv(win, "R3", E + 60, N, H), height_kind="ellipsoidal")
    assert p.points["R3"].height_kind == "ellipsoidal"
    choose_in_cell(qtbot, win, "Q1", "Height", "ellipsoidal")
    assert p.points["Q1"].height_kind == "ellipsoidal"
    assert win.undo_stack.undoText() == "Q1: Height"
    settle(qtbot, win)
    m = win.table_model
    from prismstation.gui.point_table import COLUMNS
    tip = m.data(m.index(m.row_of("Q1"), COLUMNS.index("Height")), Qt.ItemDataRole.ToolTipRole)
    assert "ellipsoidal while most points of the project are orthometric" in tip
    assert m.data(m.index(m.row_of("G02"), COLUMNS.index("Height")), Qt.ItemDataRole.ToolTipRole) is None


def _csv(win, pid, E, N, H):
    path = win.sim / f"{pid}.csv"
    path.write_text(f"id,E,N,H\n{pid},{E:.3f},{N:.3f},{H:.3f}\n")
    return path


def test_a_height_typed_for_a_new_point_is_not_55_m_off(qtbot, win):
    """The report's case: a new point measured in N, F and B, its E, N, H typed into the table
    (orthometric, as every point of the project), made an ICP. Stored as ellipsoidal it was
    55 m off (dh = 55 m, the ICP height RMSE 1.6 → 8.6 m); now its dh is the check point's."""
    p = win.project
    win.tools["transfer"].a_auto.setChecked(False)      # every view clicked by hand
    ref = next(pid for pid, pt in p.points.items() if pt.kind == "ICP"
               and all(p.measurement(pid, v) for v in "NFB"))
    r = p.points[ref]
    key(qtbot, win, "Insert")
    pid = win.current
    for v in "NFB":
        m = p.measurement(ref, v)
        win.views.views[v].center_on(m.x, m.y, 1.0)
        qtbot.wait(300)
        click_image(qtbot, win, v, m.x, m.y, Qt.KeyboardModifier.ShiftModifier)  # on its marker
    settle(qtbot, win)
    assert all(p.measurement(pid, v) for v in "NFB")
    for col, val in (("E (m)", r.E), ("N (m)", r.N), ("H (m)", r.H)):
        type_into_cell(qtbot, win, pid, col, f"{val:.3f}")
    win.set_current(pid, drive=False)
    key(qtbot, win, "Ctrl+2")                           # make it an ICP
    settle(qtbot, win)
    sol = win.solver.solution
    dh_new, dh_ref = sol.point(pid).ground_residual[2], sol.point(ref).ground_residual[2]
    print(f"dh of the new ICP {dh_new:+.2f} m, of {ref} measured in the file {dh_ref:+.2f} m; "
          f"ICP height RMSE {sol.stats['height']['ICP'].rms:.2f} m")
    assert p.points[pid].height_kind == "orthometric"
    assert abs(dh_new - dh_ref) < 3.0                    # the clicks' half pixel, not 55 m
    assert float(win.table_model.cell(pid, "dh (m)")) == pytest.approx(dh_new, abs=0.01)
    # what the ellipsoidal mistake gave: the geoid's 55 m
    choose_in_cell(qtbot, win, pid, "Height", "ellipsoidal")
    settle(qtbot, win)
    assert abs(win.solver.solution.point(pid).ground_residual[2] - dh_new) == pytest.approx(55.0, abs=0.5)


def test_the_id_column_stays_in_view_when_the_table_scrolls_sideways(qtbot, win):
    t = win.table
    win.docks["points"].show()
    t.horizontalScrollBar().setValue(t.horizontalScrollBar().maximum())   # to σ h, far right
    qtbot.wait(50)
    assert t.horizontalScrollBar().value() > t.columnWidth(0)             # column 0 scrolled away
    row = t.rowAt(t.viewport().height() // 2)
    pid = t.source_model.ids[row]
    idx = t.source_model.index(row, 0)
    at = t.frozen.viewport().mapTo(t, t.frozen.visualRect(idx).center())
    assert t.childAt(at) is t.frozen.viewport()                          # the IDs are on top
    assert t.frozen.indexAt(t.frozen.visualRect(idx).center()).data() == pid
    # a click on an ID selects its point; a double click renames it there
    qtbot.mouseClick(t.frozen.viewport(), Qt.MouseButton.LeftButton, pos=t.frozen.visualRect(idx).center())
    assert win.current == pid
    qtbot.mouseDClick(t.frozen.viewport(), Qt.MouseButton.LeftButton, pos=t.frozen.visualRect(idx).center())
    from PySide6.QtWidgets import QLineEdit
    editor = QApplication.focusWidget()
    assert isinstance(editor, QLineEdit), editor
    qtbot.keyClick(editor, Qt.Key.Key_A, Qt.KeyboardModifier.ControlModifier)
    qtbot.keyClicks(editor, pid + "x")
    qtbot.keyClick(editor, Qt.Key.Key_Return)
    qtbot.wait(10)                                   # (the delegate commits on the next turn)
    assert pid + "x" in win.project.points and win.current == pid + "x"
    # the rows scroll together
    t.verticalScrollBar().setValue(t.verticalScrollBar().maximum())
    assert t.frozen.verticalScrollBar().value() == t.verticalScrollBar().value()
    assert t.frozen.horizontalHeader().height() == t.horizontalHeader().height()
