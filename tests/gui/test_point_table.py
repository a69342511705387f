"""The point table sorts itself (no proxy): by a header click, numerically, keeping the
selected point, re-sorting when a refit changes the values, and Next point follows it."""
from __future__ import annotations

import math

from PySide6.QtCore import Qt

from prismstation.gui.point_table import COLUMNS


def _values(win, column):
    m = win.table_model
    return [m.cell(pid, column) for pid in m.ids]


def _num(t):
    return -math.inf if t == "" else float(t)


def test_sorting_by_a_header_click(qtbot, window):
    win = window
    header = win.table.horizontalHeader()
    col = COLUMNS.index("|v| max (px)")
    win.set_current("I3", drive=False)
    created = [_num(win.table_model.cell(p, "|v| max (px)")) for p in win.project.points]
    assert created != sorted(created)          # else the test would prove nothing
    qtbot.mouseClick(header.viewport(), Qt.MouseButton.LeftButton, pos=_section_center(header, col))
    vals = [_num(t) for t in _values(win, "|v| max (px)")]
    assert vals == sorted(vals) or vals == sorted(vals, reverse=True)
    # the selection stayed on its point, and PgDown follows the shown order
    assert win.table.current_id() == "I3"
    ids = win.table.ordered_ids()
    assert ids == win.table_model.ids and sorted(ids) == sorted(win.project.points)
    win.step_point(1)
    assert win.current == ids[(ids.index("I3") + 1) % len(ids)]

    # a measurement that makes a point the worst re-sorts it to the end, selection kept
    win.table.sortByColumn(col, Qt.SortOrder.AscendingOrder)
    win.set_current("I3", drive=False)
    m = win.project.measurement("I3", "N")
    win.move("I3", "N", m.x + 25.0, m.y, True)
    qtbot.waitUntil(lambda: win.solver.solution.revision == win.project.revision and not win.solver.busy(),
                    timeout=10000)
    assert win.table_model.ids[-1] == "I3" and win.table.current_id() == "I3"
    vals = [_num(t) for t in _values(win, "|v| max (px)")]
    assert vals == sorted(vals)

    # back to creation order
    win.table.sortByColumn(-1, Qt.SortOrder.AscendingOrder)
    assert win.table_model.ids == list(win.project.points)


def _section_center(header, col):
    from PySide6.QtCore import QPoint
    x = header.sectionViewportPosition(col) + header.sectionSize(col) // 2
    return QPoint(x, header.height() // 2)
