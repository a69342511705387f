"""The point table: one row per point with its kind, views, residuals and ground estimate.

A ``QAbstractTableModel`` reading the project (ids, kinds, measurements) and the current
:class:`~prismstation.core.models.solution.Solution` (residuals, estimates, standardised residuals).
GCPs flagged as blunders get a red background; residuals are in pixels of the reference view.
A refit repaints the table on every click, so the model sorts itself (no proxy model in
between), builds only the rows on screen and formats their texts once for the view's one-pass
paint (:mod:`prismstation.gui.point_table_view`).
"""
from __future__ import annotations

import math

import numpy as np
from PySide6.QtCore import QAbstractTableModel, QModelIndex, Qt
from PySide6.QtGui import QBrush, QColor

from prismstation.core.models.scene import reference_view
from prismstation.gui.overlays import KIND_COLORS
from prismstation.gui.plain import plain
from prismstation.gui.static_text import ALIGN_RIGHT

COLUMNS = ("ID", "Kind", "Views", "vx (px)", "vy (px)", "|v| max (px)", "E est (m)", "N est (m)",
           "h est (m)", "dh (m)", "std. res.", "E (m)", "N (m)", "H (m)", "Height", "σ plan (m)",
           "σ h (m)")
EDITABLE = ("ID", "Kind", "E (m)", "N (m)", "H (m)", "Height", "σ plan (m)", "σ h (m)")
"""Columns the operator types into (the known ground data of the point)."""
HEIGHT = COLUMNS.index("Height")  # the kind of H: ellipsoidal or orthometric (empty without H)
TEXT = (0, 1, 2, HEIGHT)  # columns of text (left-aligned, sorted as text)
BLUNDER = len(COLUMNS)  # index of the blunder flag in a row, after the columns' values
ODD_HEIGHT = BLUNDER + 1  # the flag of an H of another kind than the project's
BLUNDER_BG = QColor(255, 190, 190)
TOLERANCE_BG = QColor(255, 235, 180)


BLUNDER_BRUSH = QBrush(BLUNDER_BG)
ODD_HEIGHT_BRUSH = QBrush(TOLERANCE_BG)
ODD_ROW_BRUSH = QBrush(QColor(245, 245, 245))  # alternate rows (the view's own costs 3 ms a repaint)
KIND_BRUSHES = {k: QBrush(c.darker(140)) for k, c in KIND_COLORS.items()}
_DISPLAY, _BACKGROUND, _FOREGROUND, _ALIGN, _TOOLTIP, _SORT, _EDIT = (
    int(r) for r in (Qt.ItemDataRole.DisplayRole, Qt.ItemDataRole.BackgroundRole,
                     Qt.ItemDataRole.ForegroundRole, Qt.ItemDataRole.TextAlignmentRole,
                     Qt.ItemDataRole.ToolTipRole, Qt.ItemDataRole.UserRole,
                     Qt.ItemDataRole.EditRole))
_DIGITS = (None, None, None, 3, 3, 3, 2, 2, 2, 2, 2, 3, 3, 3, None, 3, 3)


_SPECS = tuple(None if d is None else f".{d}f" for d in _DIGITS)


def _texts(row) -> list:
    return [row[c] if spec is None else _fmt(row[c], spec) for c, spec in enumerate(_SPECS)]


def odd_height_text(pid: str, kind: str, usual: str) -> str:
    """Why a height-kind cell is tinted: the point's H is of another kind than most."""
    return (f"{pid}: H is {kind} while most points of the project are {usual} — check it "
            "(double-click to change the kind)")


def _fmt(v, spec=".2f"):
    return "" if v is None or v != v or v in (math.inf, -math.inf) else format(v, spec)


_UNFITTED = (None,) * 8 + (False,)


def _fitted_values(sol, ref: str):
    """``fitted(id) -> (vx, vy, vmax, E, N, h, dh, std residual, blunder)`` of ``sol`` (None:
    none), None where a point has no value: the residual in the ``ref`` view, the longest
    residual over the views (px), the estimated ground and height residual (m). Computed for
    every point at once, read per row (a refit builds the rows on screen only)."""
    if sol is None:
        return lambda pid: _UNFITTED
    c = sol.columns
    n = len(c)
    nan2 = np.full((n, 2), np.nan)
    r = c.residual.get(ref, nan2)
    lengths = [np.hypot(a[:, 0], a[:, 1]) for a in c.residual.values()]
    with np.errstate(invalid="ignore"):
        vmax = np.fmax.reduce(lengths) if lengths else np.full(n, np.nan)  # (NaN where none)
    est = np.where(np.isfinite(c.ground_est).all(axis=1)[:, None], c.ground_est, np.nan)
    cols = [a.tolist() for a in (r[:, 0], r[:, 1], vmax, est[:, 0], est[:, 1], est[:, 2],
                                 np.where(np.isfinite(est[:, 2]), c.ground_residual[:, 2], np.nan),
                                 c.std_residual)]
    blunder = c.blunder.tolist()

    def fitted(pid: str) -> tuple:
        i = c.index(pid)
        if i is None:
            return _UNFITTED
        return (*(None if col[i] != col[i] else col[i] for col in cols), blunder[i])
    return fitted


def _sort_key(row, column):
    v = row[column]
    return v if column in TEXT else -math.inf if v is None else v


class PointTableModel(QAbstractTableModel):
    """Rows: the project's points, in creation order or sorted by a column (:meth:`sort`).
    :meth:`refresh` after every change. ``ids`` are in the order shown.

    In creation order a refresh builds only the rows on screen (:attr:`shown_rows`, set by the
    view) and compares them with what they showed; the others are built when first read (a
    refit changes every row's residuals, a view shows a few dozen of a thousand). Sorted, every
    row is built (the order depends on them all)."""

    def __init__(self, parent=None):
        super().__init__(parent)
        self.project = None
        self.solution = None
        self.ids: list[str] = []
        self._row_of: dict[str, int] = {}
        self._rows: list = []  # row tuples; None: not built since the last refresh
        self._text: list[list] = []
        self._make = None  # pid -> row tuple, for the project and solution of the last refresh
        self._sort = (-1, Qt.SortOrder.AscendingOrder)
        self.edit_handler = None  # callable(pid, column, text): set by the point editor
        self.shown_rows = None  # callable() -> (first, last) rows on screen; None: all

    def set_project(self, project) -> None:
        self.project, self.solution = project, None
        self.refresh()

    def set_solution(self, solution) -> None:
        self.solution = solution
        self.refresh()

    def refresh(self) -> None:
        """Rebuild the rows from the project and the solution: ``dataChanged`` for the cells
        that changed when the rows are the same points in the same order, a layout change when
        only the order changed (selection and scroll stay in both), else one reset."""
        if self.project is None:
            self._reset([], None)
            return
        make = self._row_builder()
        if self._sort[0] < 0:  # creation order: the ids say it all, rows are built when read
            ids = list(self.project.points)
            if ids == self.ids and ids:
                self._refresh_shown(make)
            else:
                self._reset(ids, make)
            return
        rows = self._sorted([make(pid) for pid in self.project.points])
        ids = [r[0] for r in rows]
        if ids == self.ids and rows:
            old, self._make = self._rows, make
            self._rows, self._text = rows, [None] * len(rows)
            self._emit_changed(old, rows, range(len(rows)))
            return
        if rows and len(ids) == len(self.ids) and set(ids) == set(self.ids):
            self._relayout(rows)  # re-sorted by new values
            return
        self._reset(ids, make, rows)

    def _refresh_shown(self, make) -> None:
        """The same points in creation order: build the rows on screen, repaint what changed
        in them; the rest are built when read."""
        n = len(self.ids)
        try:
            first, last = self.shown_rows() if self.shown_rows is not None else (0, n - 1)
        except RuntimeError:  # the view is being deleted: every row
            first, last = 0, n - 1
        first, last = max(first, 0), min(last, n - 1)
        old, rows = self._rows, [None] * n
        for i in range(first, last + 1):
            rows[i] = make(self.ids[i])
        self._rows, self._text, self._make = rows, [None] * n, make
        self._emit_changed(old, rows, range(first, last + 1))

    def _emit_changed(self, old, rows, where) -> None:
        """``dataChanged`` for the rows of ``where`` that differ between ``old`` and ``rows``:
        the columns between the leftmost and the rightmost that changed (a refit changes the
        residual columns, never the ids: the frozen id column is not repainted), and the whole
        row where a flag changed (its colour, a blunder). A row not built before counts as
        changed everywhere."""
        n = len(COLUMNS)
        changed = [i for i in where if old[i] != rows[i]]
        if not changed:
            return
        if any(old[i] is None for i in changed):
            cols = list(range(n))
        else:
            was, now = [old[i][:n] for i in changed], [rows[i][:n] for i in changed]
            cols = [c for c, (a, b) in enumerate(zip(zip(*was), zip(*now))) if a != b]
        if cols:
            self.dataChanged.emit(self.index(min(changed), cols[0]), self.index(max(changed), cols[-1]))
        for i in changed:
            if old[i] is not None and old[i][n:] != rows[i][n:]:
                self.dataChanged.emit(self.index(i, 0), self.index(i, n - 1))

    def _reset(self, ids, make, rows=None) -> None:
        self.beginResetModel()
        self._make = make
        self._set_rows(rows if rows is not None else [None] * len(ids), ids)
        self.endResetModel()

    def _set_rows(self, rows, ids=None) -> None:
        self._rows = rows
        self.ids = [r[0] for r in rows] if ids is None else list(ids)
        self._row_of = {pid: i for i, pid in enumerate(self.ids)}
        self._text = [None] * len(rows)

    def row(self, r: int) -> tuple:
        """Row ``r``'s values (built when first read after a refresh)."""
        x = self._rows[r]
        if x is None:
            x = self._rows[r] = self._make(self.ids[r])
        return x

    def texts(self, r: int) -> list:
        """The display texts of row ``r`` (formatted when first shown after a change)."""
        t = self._text[r]
        if t is None:
            t = self._text[r] = _texts(self.row(r))
        return t

    def _sorted(self, rows: list[tuple]) -> list[tuple]:
        column, order = self._sort
        if column < 0:
            return rows
        rev = order == Qt.SortOrder.DescendingOrder
        return sorted(rows, key=lambda r: _sort_key(r, column), reverse=rev)

    def sort(self, column: int, order=Qt.SortOrder.AscendingOrder) -> None:
        """Sort the rows by ``column`` (−1: creation order); numbers sort numerically, empty
        cells first."""
        self._sort = (column, order)
        if self.project is not None:
            self._make = self._row_builder()
            self._relayout(self._sorted([self._make(pid) for pid in self.project.points]))

    def _relayout(self, rows) -> None:
        """The same points in a new order: selection and scroll follow their rows."""
        self.layoutAboutToBeChanged.emit()
        old = dict(self._row_of)
        self._set_rows(rows)
        n = len(COLUMNS)
        self.changePersistentIndexList(
            [self.index(old[pid], c) for pid in self.ids for c in range(n)],
            [self.index(i, c) for i in range(len(self.ids)) for c in range(n)])
        self.layoutChanged.emit()

    def _row_builder(self):
        """``make(pid) -> row``: a row's values (the columns, then the blunder flag and the
        unusual-height flag) from the project and the solution as they are now — a snapshot
        of the project: a row built later shows the same state as the others, not an edit
        made since (whose refit refreshes the table)."""
        p, sol = self.project.snapshot(), self.solution
        views = list(p.scene.views)
        ref = reference_view(views)
        measurements, points = p.measurements, p.points
        shown: dict[tuple, str] = {}  # views measured -> "N · B" (a handful of kinds)
        # long view names (an RPC project's image names) by their place, "1 · 3", to stay legible
        marks = views if all(len(v) <= 2 for v in views) else [str(i + 1) for i in range(len(views))]
        fitted = _fitted_values(sol, ref)
        usual = p.height_kind()

        def make(pid: str) -> tuple:
            pt = points[pid]
            have = tuple(v for v in views if (pid, v) in measurements)
            vs = shown.get(have)
            if vs is None:
                vs = shown[have] = " ".join(m if v in have else "·" for v, m in zip(views, marks))
            vx, vy, vmax, e, n, h, dh, sr, blunder = fitted(pid)
            hk = pt.height_kind if pt.H == pt.H else ""  # (NaN: no height, no kind)
            return (pid, pt.kind, vs, vx, vy, vmax, e, n, h, dh, sr,
                    pt.E, pt.N, pt.H, hk, pt.sigma_xy_m, pt.sigma_h_m, blunder,
                    bool(hk) and hk != usual)
        return make

    # ------------------------------------------------------------------ Qt model
    def rowCount(self, parent=QModelIndex()) -> int:
        return 0 if parent.isValid() else len(self._rows)

    def columnCount(self, parent=QModelIndex()) -> int:
        return 0 if parent.isValid() else len(COLUMNS)

    def headerData(self, section, orientation, role=Qt.ItemDataRole.DisplayRole):
        if orientation == Qt.Orientation.Horizontal and role == Qt.ItemDataRole.DisplayRole:
            return COLUMNS[section]
        if (orientation == Qt.Orientation.Horizontal and role == Qt.ItemDataRole.ToolTipRole
                and COLUMNS[section] == "Views" and self.project is not None):
            views = list(self.project.scene.views)
            return "  ".join(f"{i + 1} = {v}" for i, v in enumerate(views)) if any(len(v) > 2 for v in views) else None
        return None

    def data(self, index, role=Qt.ItemDataRole.DisplayRole):
        if not index.isValid():
            return None
        r, c = index.row(), index.column()
        if role == _DISPLAY:
            return self.texts(r)[c]
        row = self.row(r)
        if role == _SORT:
            return _sort_key(row, c)
        if role == _EDIT:
            return self.texts(r)[c] if COLUMNS[c] in EDITABLE else None
        if role == _BACKGROUND:
            if c == HEIGHT and row[ODD_HEIGHT]:
                return ODD_HEIGHT_BRUSH
            return BLUNDER_BRUSH if row[BLUNDER] else ODD_ROW_BRUSH if r % 2 else None
        if role == _FOREGROUND and c == 1:
            return KIND_BRUSHES.get(row[1])
        if role == _ALIGN and c not in TEXT:
            return ALIGN_RIGHT
        if role == _TOOLTIP and c == HEIGHT and row[ODD_HEIGHT]:
            return plain(odd_height_text(row[0], row[HEIGHT], self.project.height_kind()))
        if role == _TOOLTIP and row[BLUNDER]:
            return plain(f"{row[0]}: standardised residual {_fmt(row[10])} above the blunder threshold")
        return None

    def flags(self, index):
        f = super().flags(index)
        if index.isValid() and COLUMNS[index.column()] in EDITABLE:
            f |= Qt.ItemFlag.ItemIsEditable
        return f

    def setData(self, index, value, role=Qt.ItemDataRole.EditRole) -> bool:
        """A cell typed into: handed to :attr:`edit_handler` ``(pid, column name, text)``,
        which edits the project through an undoable command (the refresh that follows shows
        it). Returns False: the model itself never changes a value."""
        if (role == _EDIT and index.isValid() and self.edit_handler is not None
                and COLUMNS[index.column()] in EDITABLE):
            self.edit_handler(self.ids[index.row()], COLUMNS[index.column()], str(value))
        return False

    def row_of(self, pid: str) -> int:
        return self._row_of.get(pid, -1)

    def cell(self, pid: str, column: str) -> str:
        """Displayed text of ``column`` (a COLUMNS name) in the row of ``pid`` (tests, scripts)."""
        r = self.row_of(pid)
        return self.data(self.index(r, COLUMNS.index(column))) if r >= 0 else None

    def is_blunder(self, pid: str) -> bool:
        r = self.row_of(pid)
        return r >= 0 and bool(self.row(r)[BLUNDER])
