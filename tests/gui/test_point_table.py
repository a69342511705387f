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


def test_a_refit_builds_the_rows_on_screen_and_the_others_when_shown(qtbot, window):
    """In creation order a refit builds and repaints only the rows in the viewport; a row
    scrolled into view afterwards shows the same fit as the others (not a stale one, not an
    edit made since), and a refit repaints only cells on screen."""
    from PySide6.QtWidgets import QAbstractItemView

    win, m = window, window.table_model
    t = win.table
    t.scrollToTop()
    qtbot.wait(20)
    first, last = t.rows_on_screen()
    assert last - first + 1 < len(m.ids), "the table shows every row: nothing to prove"
    bottom = m.ids[-1]
    g = win.project.measurement("G2", "N")
    repainted = []
    m.dataChanged.connect(lambda a, b, *_: repainted.append((a.row(), b.row())))
    win.move("G2", "N", g.x + 3.0, g.y, True)   # a refit changes every row's residuals
    qtbot.waitUntil(lambda: win.solver.solution.revision == win.project.revision and not win.solver.busy(),
                    timeout=10000)
    assert repainted and all(first <= a and b <= last for a, b in repainted)
    assert sum(r is not None for r in m._rows) <= last - first + 1   # the rest: built when shown
    sol = win.solver.solution
    # the bottom row, scrolled into view, shows this fit's residual
    t.scrollTo(m.index(m.row_of(bottom), 3), QAbstractItemView.ScrollHint.PositionAtBottom)
    qtbot.wait(20)
    res = sol.point(bottom).residual_px.get("N")
    assert m.cell(bottom, "vx (px)") == ("" if res is None else f"{res[0]:.3f}")
    # a row not built yet shows the state of the last refresh, not an edit made since (the
    # edit's refit refreshes the table): here a point removed before its row is read
    t.scrollToTop()
    qtbot.wait(20)
    gone = next(pid for i, pid in enumerate(m.ids) if m._rows[i] is None)
    kind = win.project.points[gone].kind
    win.project.remove_point(gone)
    assert m.cell(gone, "Kind") == kind
    qtbot.waitUntil(lambda: gone not in m.ids, timeout=10000)


def test_cached_texts_draw_as_qt_draws_them(qtbot, window, monkeypatch):
    """The table and the model panel lay their texts out once and reuse them: the pixels are
    those of Qt's own ``drawText`` in the cell (aligned, centred, a text wider than its cell
    clipped to it)."""
    from prismstation.gui.static_text import ALIGN_LEFT, ALIGN_RIGHT, StaticTexts

    t, panel = window.table, window.panel.sections
    narrow = COLUMNS.index("E est (m)")  # so narrow that its numbers do not fit: clipped
    t.setColumnWidth(narrow, 30)
    widgets = (t.viewport(), panel)
    for w in widgets:
        w.update()
    cached = [w.grab().toImage() for w in widgets]
    assert len(t._texts) > 20 and len(panel._texts) > 20, "no text taken from the cache"

    def qt_text(self, p, x, y, w, h, right, text):
        p.drawText(x, y, w, h, ALIGN_RIGHT if right else ALIGN_LEFT, text)
    monkeypatch.setattr(StaticTexts, "draw", qt_text)
    for w in widgets:
        w.update()
    assert [w.grab().toImage() for w in widgets] == cached
