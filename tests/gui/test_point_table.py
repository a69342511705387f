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


def test_the_table_paints_selection_blunder_and_text(qtbot, window):
    """The table paints its cells itself: the selected row in the highlight colour, a blunder
    row in the blunder colour, alternate rows shaded, and text in the cells (dark pixels)."""
    from PySide6.QtGui import QPalette

    from prismstation.gui.point_table import BLUNDER, BLUNDER_BG
    win = window
    m = win.table_model
    win.set_current("G1", drive=False)
    r_sel = m.row_of("G1")
    blunder = "G2"
    r_bl = m.row_of(blunder)
    row = list(m._rows[r_bl])
    row[BLUNDER] = True
    m._rows[r_bl] = tuple(row)  # as if the fit had flagged it
    t = win.table
    t.viewport().update()
    img = t.viewport().grab().toImage()
    vh = t.verticalHeader()
    x = t.horizontalHeader().sectionViewportPosition(3) + 3  # left edge of a number cell

    def colour_at(r):
        return img.pixelColor(x, vh.sectionViewportPosition(r) + 2)
    assert colour_at(r_sel) == t.palette().color(QPalette.ColorRole.Highlight)
    assert colour_at(r_bl) == BLUNDER_BG
    plain = next(r for r in range(len(m.ids)) if r not in (r_sel, r_bl) and r % 2 == 0)
    odd = next(r for r in range(len(m.ids)) if r not in (r_sel, r_bl) and r % 2 == 1)
    assert colour_at(plain) != colour_at(odd)            # alternate rows shaded
    y = vh.sectionViewportPosition(plain)
    x0, w = t.horizontalHeader().sectionViewportPosition(3), t.horizontalHeader().sectionSize(3)
    dark = sum(img.pixelColor(xx, yy).lightness() < 100
               for xx in range(x0, x0 + w) for yy in range(y, y + vh.sectionSize(plain)))
    assert dark > 10, "no text drawn in the cell"
