"""The point table's views: :class:`PointTableView` (sortable, single-row selection, its ID
column frozen in view) over a :class:`~prismstation.gui.point_table.PointTableModel`.

A refit repaints the table on every click, so the paint path is short:
:meth:`_FastTable.paintEvent` draws the visible cells in one pass from the model's preformatted
strings (the standard path — an item delegate called per cell, seven ``data()`` roles each —
took 3–7 ms for a 15-row view, this ~1 ms), and a change repaints only the changed cells.
"""
from __future__ import annotations

from PySide6.QtCore import QRect, Qt
from PySide6.QtGui import QPainter, QPalette
from PySide6.QtWidgets import QAbstractItemView, QHeaderView, QMenu, QTableView

from prismstation.gui.point_table import (BLUNDER, BLUNDER_BRUSH, COLUMNS,
                                          HEIGHT, KIND_BRUSHES, ODD_HEIGHT, ODD_HEIGHT_BRUSH,
                                          ODD_ROW_BRUSH, TEXT, PointTableModel)
from prismstation.gui.static_text import StaticTexts


class _FastTable(QTableView):
    """A table view of a :class:`PointTableModel` that paints its visible cells in one pass."""

    PAD = 4  # text inset in a cell, px

    def __init__(self, model: PointTableModel, parent=None):
        super().__init__(parent)
        self._texts = StaticTexts()  # laid out once (residuals repeat: "0.03" is in many cells)
        self.source_model = model
        self.setModel(model)
        self.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.setSelectionMode(QAbstractItemView.SelectionMode.SingleSelection)
        self.verticalHeader().setVisible(False)
        self.verticalHeader().setDefaultSectionSize(20)
        # sized once per project (ResizeToContents would measure every cell at every change)
        self.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.Interactive)

    def dataChanged(self, top_left, bottom_right, roles=()) -> None:
        """Repaint the changed cells only (Qt repaints the whole table for a range): a refit
        changes the residual columns, and neither the ids nor the known coordinates."""
        if not top_left.isValid() or not bottom_right.isValid() or self.state() == self.State.EditingState:
            return super().dataChanged(top_left, bottom_right, roles)
        vh, hh = self.verticalHeader(), self.horizontalHeader()
        cols = [c for c in range(top_left.column(), bottom_right.column() + 1) if not hh.isSectionHidden(c)]
        if not cols:
            return
        x0 = min(hh.sectionViewportPosition(c) for c in cols)
        x1 = max(hh.sectionViewportPosition(c) + hh.sectionSize(c) for c in cols)
        y0 = vh.sectionViewportPosition(top_left.row())
        y1 = vh.sectionViewportPosition(bottom_right.row()) + vh.sectionSize(bottom_right.row())
        rect = QRect(x0, y0, x1 - x0, y1 - y0).intersected(self.viewport().rect())
        if not rect.isEmpty():
            self.viewport().update(rect)

    def paintEvent(self, event) -> None:
        """The visible cells in one pass, from the model's preformatted strings: background
        (selection, blunder, alternate rows, a height of an unusual kind), text in the kind
        colour or aligned right for numbers, grid. A refit repaints the table at every click;
        the item-view machinery (an item delegate called per cell) cost 3–5 ms of that, this
        ~1 ms."""
        m = self.source_model
        if not m._rows:
            return super().paintEvent(event)
        vh, hh = self.verticalHeader(), self.horizontalHeader()
        area = event.rect()
        first = vh.visualIndexAt(area.top())
        last = vh.visualIndexAt(area.bottom())
        first = 0 if first < 0 else first
        last = len(m._rows) - 1 if last < 0 else last
        cols = []
        for vis in range(hh.count()):
            c = hh.logicalIndex(vis)
            x, w = hh.sectionViewportPosition(c), hh.sectionSize(c)
            if not hh.isSectionHidden(c) and x + w > area.left() and x < area.right() + 1:
                cols.append((c, x, w))
        selected = {r for rng in self.selectionModel().selection() for r in range(rng.top(), rng.bottom() + 1)}
        pal = self.palette()
        text_pen, sel_pen = pal.color(QPalette.ColorRole.Text), pal.color(QPalette.ColorRole.HighlightedText)
        p = QPainter(self.viewport())
        p.fillRect(area, pal.base())
        self._texts.set_font(p, self.font())
        right = cols[-1][1] + cols[-1][2] if cols else 0
        rows = []
        for vis in range(first, last + 1):
            r = vh.logicalIndex(vis)
            y, h = vh.sectionViewportPosition(r), vh.sectionSize(r)
            row, texts, chosen = m.row(r), m.texts(r), r in selected
            if chosen:
                p.fillRect(0, y, right, h, pal.highlight())
            elif row[BLUNDER] or r % 2:
                p.fillRect(0, y, right, h, BLUNDER_BRUSH if row[BLUNDER] else ODD_ROW_BRUSH)
            for c, x, w in cols:
                odd = c == HEIGHT and row[ODD_HEIGHT]  # tinted, selected or not
                if odd:
                    p.fillRect(x, y, w, h, ODD_HEIGHT_BRUSH)
                kind = KIND_BRUSHES.get(row[1]) if c == 1 and not chosen else None
                p.setPen(sel_pen if chosen and not odd else kind.color() if kind is not None else text_pen)
                self._texts.draw(p, x + self.PAD, y, w - 2 * self.PAD, h, c not in TEXT, texts[c])
            rows.append(y + h - 1)
        if self.showGrid():
            p.setPen(pal.color(QPalette.ColorRole.Mid))
            bottom = rows[-1] if rows else area.bottom()
            for y in rows:
                p.drawLine(area.left(), y, right - 1, y)
            for _, x, w in cols:
                p.drawLine(x + w - 1, area.top(), x + w - 1, bottom)
        p.end()


class _FrozenIds(_FastTable):
    """The ID column kept in view over the left edge of the table while it scrolls sideways
    (Qt's frozen-column pattern: a second view of the same model and selection, showing
    column 0 only, scrolled with the table's rows)."""

    def __init__(self, table: "PointTableView"):
        super().__init__(table.source_model, table)
        self.table = table
        own = self.selectionModel()
        self.setSelectionModel(table.selectionModel())
        own.deleteLater()
        self.setFocusPolicy(Qt.FocusPolicy.NoFocus)  # keys go to the table
        self.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        self.setVerticalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        self.setVerticalScrollMode(table.verticalScrollMode())
        self.setFrameShape(self.Shape.NoFrame)
        self.horizontalHeader().setSortIndicator(-1, Qt.SortOrder.AscendingOrder)  # unsorted until the table is
        self.horizontalHeader().setSortIndicatorShown(True)
        self.horizontalHeader().setSectionsClickable(True)
        self.horizontalHeader().sectionClicked.connect(self._sort_clicked)
        self.setStyleSheet("QTableView { border-right: 1px solid palette(mid); }")
        self._hide_other_columns()
        table.source_model.modelReset.connect(self._hide_other_columns)
        table.verticalScrollBar().valueChanged.connect(self.verticalScrollBar().setValue)
        self.verticalScrollBar().valueChanged.connect(table.verticalScrollBar().setValue)

    def _hide_other_columns(self) -> None:
        for c in range(1, len(COLUMNS)):
            self.setColumnHidden(c, True)

    def _sort_clicked(self, column: int) -> None:
        """The header's ID sorts the table as the table's own ID header does."""
        hh = self.table.horizontalHeader()
        order = (Qt.SortOrder.DescendingOrder if hh.sortIndicatorSection() == 0
                 and hh.sortIndicatorOrder() == Qt.SortOrder.AscendingOrder else Qt.SortOrder.AscendingOrder)
        hh.setSortIndicator(0, order)

    def contextMenuEvent(self, event) -> None:
        """The table's own context menu (go to, kind, delete) for the row clicked."""
        if self.table.contextMenuPolicy() == Qt.ContextMenuPolicy.ActionsContextMenu and self.table.actions():
            QMenu.exec(self.table.actions(), event.globalPos(), None, self)


class PointTableView(_FastTable):
    """Sortable table view of a :class:`PointTableModel` with single-row selection; its ID
    column stays in view when the table scrolls sideways (:attr:`frozen`)."""

    def __init__(self, model: PointTableModel, parent=None):
        super().__init__(model, parent)
        self.horizontalHeader().setSortIndicator(-1, Qt.SortOrder.AscendingOrder)
        self.setSortingEnabled(True)
        self.horizontalHeader().setStretchLastSection(True)
        self.setHorizontalScrollMode(QAbstractItemView.ScrollMode.ScrollPerPixel)
        model.modelReset.connect(self._size_columns)
        model.shown_rows = self.rows_on_screen
        self.frozen = _FrozenIds(self)
        self.horizontalHeader().sectionResized.connect(self._frozen_width)
        self.horizontalHeader().sortIndicatorChanged.connect(
            lambda c, o: self.frozen.horizontalHeader().setSortIndicator(c if c == 0 else -1, o))
        self._frozen_width(0, 0, self.columnWidth(0))

    def _frozen_width(self, column: int, _old: int, width: int) -> None:
        if column == 0:
            self.frozen.setColumnWidth(0, width)
            self._place_frozen()

    def _place_frozen(self) -> None:
        f = self.frameWidth()
        self.frozen.setGeometry(f, f, self.columnWidth(0),
                                self.viewport().height() + self.horizontalHeader().height())
        self.frozen.horizontalHeader().setFixedHeight(self.horizontalHeader().height())

    def resizeEvent(self, event) -> None:
        super().resizeEvent(event)
        if hasattr(self, "frozen"):
            self._place_frozen()

    def updateGeometries(self) -> None:
        super().updateGeometries()
        if hasattr(self, "frozen"):
            self._place_frozen()

    def scrollTo(self, index, hint=QAbstractItemView.ScrollHint.EnsureVisible) -> None:
        """As QTableView, but a cell scrolled into view is never left under the frozen IDs."""
        super().scrollTo(index, hint)
        if index.isValid() and index.column() > 0:
            left = self.visualRect(index).left()
            under = self.columnWidth(0) - left
            if under > 0:
                sb = self.horizontalScrollBar()
                sb.setValue(sb.value() - under)

    def _size_columns(self) -> None:
        fm = self.fontMetrics()
        for c, name in enumerate(COLUMNS):
            sample = {"ID": "W0000", "Kind": "GCP", "Views": "N F B", "E (m)": "000000.000",
                      "N (m)": "0000000.000", "H (m)": "0000.000", "Height": "orthometric"}.get(name, "-000000.00")
            self.setColumnWidth(c, max(fm.horizontalAdvance(name), fm.horizontalAdvance(sample)) + 14)

    def rows_on_screen(self) -> tuple[int, int]:
        """``(first, last)`` rows in the viewport (all rows when it shows none)."""
        vh, n = self.verticalHeader(), self.source_model.rowCount()
        first, last = vh.logicalIndexAt(0), vh.logicalIndexAt(self.viewport().height() - 1)
        return (0 if first < 0 else first), (n - 1 if last < 0 else last)

    def current_id(self) -> str | None:
        rows = self.selectionModel().selectedRows()
        if not rows:
            return None
        r = rows[0].row()
        return self.source_model.ids[r] if 0 <= r < len(self.source_model.ids) else None

    def select_id(self, pid: str | None) -> None:
        """Select the row of ``pid`` (clears the selection for None) without emitting twice."""
        sm = self.selectionModel()
        r = -1 if pid is None else self.source_model.row_of(pid)
        if r < 0:
            sm.clearSelection()
            return
        idx = self.source_model.index(r, 0)
        if self.current_id() != pid or not sm.isSelected(idx):
            sm.select(idx, sm.SelectionFlag.ClearAndSelect | sm.SelectionFlag.Rows)
            sm.setCurrentIndex(idx, sm.SelectionFlag.NoUpdate)
        # to the row only: a sideways scroll would move the cell being double-clicked (to
        # edit it) away from under the mouse
        x = self.horizontalScrollBar().value()
        self.scrollTo(idx)
        self.horizontalScrollBar().setValue(x)

    def ordered_ids(self) -> list[str]:
        """Ids in the order shown (after sorting)."""
        return list(self.source_model.ids)
