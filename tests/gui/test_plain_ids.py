"""Point ids are drawn as they were typed wherever the window shows them: an id that looks
like markup (``<b>x</b>``, ``<script>…``) is never rendered as rich text."""
from __future__ import annotations

from PySide6.QtGui import Qt  # (with QtGui's functions: mightBeRichText)
from PySide6.QtGui import QFont, QFontMetricsF, QTextDocument

from tests.gui.test_editing import type_into_cell
from tests.gui.test_operator import settle

BOLD, SCRIPT = "<b>x</b>", "<script>alert(1)</script>"


def shown(text: str) -> str:
    """What a Qt widget that guesses the format (tool tip, QLabel, message box) shows."""
    doc = QTextDocument()
    doc.setHtml(text) if Qt.mightBeRichText(text) else doc.setPlainText(text)
    return doc.toPlainText()


def test_markup_ids_are_plain_in_views_tips_and_plots(qtbot, window):
    win = window
    type_into_cell(qtbot, win, "G1", "ID", BOLD)
    type_into_cell(qtbot, win, "I1", "ID", SCRIPT)
    assert {BOLD, SCRIPT} <= set(win.project.points)
    other = "ellipsoidal" if win.project.height_kind() != "ellipsoidal" else "orthometric"
    choose_in_cell(qtbot, win, BOLD, "Height", other)  # unlike the others': a tool tip names the id
    settle(qtbot, win)

    # the labels beside the markers: laid out as the literal text, not as a bold "x" or nothing
    ov = win.views.overlays["N"]
    assert {BOLD, SCRIPT} <= set(ov.label_texts())
    win.views.fit_all()
    win.views.views["N"].grab()  # painted: each label laid out
    metrics = QFontMetricsF(QFont(ov.labels.font))
    for text in (BOLD, SCRIPT):
        st = ov.labels._static[text]
        assert st.size().width() >= 0.9 * metrics.horizontalAdvance(text), text

    # the table's tool tips (Qt guesses their format) show the id literally
    m = win.table_model
    from prismstation.gui.point_table import COLUMNS
    tip = m.data(m.index(m.row_of(BOLD), COLUMNS.index("Height")), Qt.ItemDataRole.ToolTipRole)
    assert tip and shown(tip).startswith(BOLD + ": H is")
    assert m.cell(BOLD, "ID") == BOLD

    # a plot's tool tip over a point (pyqtgraph joins the tips of the points under the cursor)
    for item in _scatters(win):
        tip = item.opts["tip"]
        if tip is not None:
            assert shown("\n\n".join([tip(x=1.0, y=2.0, data=SCRIPT), tip(x=1.0, y=2.0, data=BOLD)])) \
                .split() == [SCRIPT + ":", "1.00,", "2.00", BOLD + ":", "1.00,", "2.00"]
            break
    else:
        raise AssertionError("no scatter with a tool tip in the plots")


def choose_in_cell(qtbot, win, pid, column, text):
    """Double-click the cell, choose ``text`` in its list by its first letter, Enter."""
    from PySide6.QtWidgets import QApplication, QComboBox
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


def _scatters(win):
    import pyqtgraph as pg
    for pw in win.plots.plots.values():
        for item in pw.getPlotItem().items:
            if isinstance(item, pg.ScatterPlotItem):
                yield item
