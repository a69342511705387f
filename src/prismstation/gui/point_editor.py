"""Editing points' ground data in the point table, by paste, and by coordinates.

The table's ID, Kind, E, N, H, Height (its kind), σ plan and σ h cells are typed into
(double-click or F2, type, Enter); each edit is one undoable
:class:`~prismstation.gui.commands.EditPoint`. Ctrl+V on the
table pastes text copied from a spreadsheet or a text file (tabs, commas, semicolons or
spaces between fields), as one undoable step:

* lines ``ID E N H [σplan σh]`` add those points (as GCPs) or set the coordinates of the
  points with those ids;
* lines of numbers fill the editable number cells from the selected cell rightwards, one line
  per row downwards.

*New point from coordinates…* adds a GCP or ICP by its known E, N, H first; it is then the
current point, to be measured in each view; the views are driven to where the model puts it.

Units: metres of the project CRS; H of the kind the point's height kind names. One rule for
every height entered without a kind — typed into a point that had none, pasted, by
coordinates, imported — :meth:`Project.height_kind` (the kind most points of the project have),
unless the operator says otherwise (the Height cell, the dialogs' height-kind choice).
"""
from __future__ import annotations

import math
import re
from dataclasses import replace

from PySide6.QtCore import QEvent, Qt, QTimer
from PySide6.QtGui import QAction, QGuiApplication, QKeySequence
from PySide6.QtWidgets import (QComboBox, QDialog, QDialogButtonBox, QFormLayout, QLineEdit,
                               QMessageBox, QStyledItemDelegate, QToolTip)

from prismstation.errors import InputError, PrismError
from prismstation.gui import commands as cmd
from prismstation.gui.point_table import COLUMNS, EDITABLE
from prismstation.gui.titles import fit_title
from prismstation.model.points import HEIGHT_KINDS, KINDS, GroundPoint
from prismstation.gui.plain import plain

_FIELD = {"E (m)": "E", "N (m)": "N", "H (m)": "H", "σ plan (m)": "sigma_xy_m", "σ h (m)": "sigma_h_m"}
_NUMERIC = tuple(c for c in EDITABLE if c in _FIELD)
_SPLIT = re.compile(r"[\t;,]|\s+")


def parse_number(text: str, what: str, *, sigma: bool = False) -> float | None:
    """A typed number (a decimal comma is accepted); empty → NaN for coordinates, None for a σ.
    Raises InputError naming ``what`` for anything else, or a σ that is not positive."""
    t = text.strip().replace(" ", "")
    if not t:
        return None if sigma else math.nan
    if "," in t and "." not in t:
        t = t.replace(",", ".")
    try:
        v = float(t)
    except ValueError:
        raise InputError(f"{what}: {text.strip()!r} is not a number") from None
    if not math.isfinite(v) or (sigma and v <= 0):
        raise InputError(f"{what}: {text.strip()!r} is not {'a positive' if sigma else 'a finite'} number")
    return v


def height_kind_of(text: str) -> str:
    """A typed height kind: ``ellipsoidal`` or ``orthometric`` (any prefix, any case)."""
    t = text.strip().lower()
    hits = [k for k in HEIGHT_KINDS if t and k.startswith(t)]
    if len(hits) != 1:
        raise InputError(f"height kind {text.strip()!r} is not one of {', '.join(HEIGHT_KINDS)}")
    return hits[0]


def edited_point(point: GroundPoint, column: str, text: str, height_kind: str = "ellipsoidal") -> GroundPoint:
    """``point`` with ``column`` (a name of :data:`EDITABLE`) set from typed ``text``.
    ``height_kind``: the kind an H typed into a point that had none takes (the project's)."""
    if column == "ID":
        return replace(point, id=text.strip())
    if column == "Kind":
        kind = text.strip().upper()
        if kind not in KINDS:
            raise InputError(f"kind {text.strip()!r} is not one of {', '.join(KINDS)}")
        return replace(point, kind=kind)
    if column == "Height":
        if math.isnan(point.H):
            raise InputError(f"{point.id} has no height yet: type H first (it takes the project's "
                             f"kind, {height_kind}; change it here afterwards)")
        return replace(point, height_kind=height_kind_of(text))
    field = _FIELD[column]
    if field == "H" and math.isnan(point.H):  # a first height: of the project's kind
        point = replace(point, height_kind=height_kind)
    return replace(point, **{field: parse_number(text, f"{point.id} {column}", sigma=field.startswith("sigma"))})


def _same(a: GroundPoint, b: GroundPoint) -> bool:
    """Equal, counting two missing (NaN) coordinates as equal."""
    key = lambda p: (p.id, p.kind, p.height_kind, p.sigma_xy_m, p.sigma_h_m,  # noqa: E731
                     *(None if math.isnan(v) else v for v in (p.E, p.N, p.H)))
    return key(a) == key(b)


def _fields(line: str) -> list[str]:
    line = line.strip()
    if "\t" in line:
        return [f.strip() for f in line.split("\t")]
    return [f for f in _SPLIT.split(line) if f]


def _is_number(text: str) -> bool:
    try:
        parse_number(text, "")
        return bool(text.strip())
    except InputError:
        return False


class PointEditor:
    """The table's edit handler, its Ctrl+V, and *New point from coordinates…* for ``window``
    (a :class:`~prismstation.gui.main_window.MainWindow`)."""

    def __init__(self, window):
        self.w = window
        window.table_model.edit_handler = self.edit
        table = window.table
        self.delegates = []  # the table's and its frozen ID column's (a delegate serves one view)
        for view in (table, table.frozen):
            view.setEditTriggers(table.EditTrigger.DoubleClicked | table.EditTrigger.EditKeyPressed)
            cell, kind, height = CellDelegate(view), ChoiceDelegate(KINDS, view), ChoiceDelegate(HEIGHT_KINDS, view)
            view.setItemDelegate(cell)
            view.setItemDelegateForColumn(COLUMNS.index("Kind"), kind)
            view.setItemDelegateForColumn(COLUMNS.index("Height"), height)
            self.delegates += [cell, kind, height]
        self.cell_delegate = self.delegates[0]
        self.a_paste = QAction("&Paste points", table)
        self.a_paste.setShortcuts(QKeySequence.StandardKey.Paste)
        self.a_paste.setShortcutContext(Qt.ShortcutContext.WidgetWithChildrenShortcut)
        self.a_paste.triggered.connect(lambda: self.paste())  # (not the "checked" flag as text)
        table.addAction(self.a_paste)
        self.a_new_gcp = QAction("New point from &coordinates…", window)
        self.a_new_gcp.setShortcut(QKeySequence("Ctrl+Shift+N"))
        self.a_new_gcp.setStatusTip("Add a GCP or ICP by its known E, N, H; then measure it in each view")
        self.a_new_gcp.triggered.connect(lambda: self.new_point_dialog())
        window.addAction(self.a_new_gcp)
        window.edit_menu.insertAction(window.a_del_point, self.a_new_gcp)

    def _message(self, text: str) -> None:
        """Say why an edit was refused: in the status bar, and beside the table's current cell
        (a narrow window leaves the status bar little room for messages)."""
        self.w.statusBar().showMessage(text, 10000)
        t = self.w.table
        if t.isVisible():  # once the cell's editor has closed (closing it hides tooltips)
            QTimer.singleShot(0, t, lambda: QToolTip.showText(
                t.viewport().mapToGlobal(t.visualRect(t.currentIndex()).bottomLeft()), plain(text), t.viewport()))

    # ------------------------------------------------------------------ one cell
    def edit(self, pid: str, column: str, text: str) -> bool:
        """Set ``column`` of point ``pid`` from typed ``text``: one undo step; a bad value is
        refused with a message. True if the project changed."""
        p = self.w.project
        if p is None or pid not in p.points:
            return False
        try:
            new = edited_point(p.points[pid], column, text, p.height_kind())
            if _same(new, p.points[pid]):
                return False
            what = f"Rename {pid} → {new.id}" if new.id != pid else f"{pid}: {column.split(' (')[0]}"
            was_current = self.w.current == pid
            self.w.undo_stack.push(cmd.EditPoint(p, pid, new, what))
        except PrismError as exc:
            self._message(str(exc))
            return False
        if new.id != pid and was_current:
            self.w.set_current(new.id, drive=False)
        return True

    # ------------------------------------------------------------------ paste
    def paste(self, text: str | None = None) -> int:
        """Paste ``text`` (default: the clipboard) into the table, one undo step; returns the
        number of points added or changed."""
        p = self.w.project
        if p is None:
            return 0
        text = QGuiApplication.clipboard().text() if text is None else text
        lines = [_fields(ln) for ln in text.splitlines() if ln.strip()]
        if not lines:
            return 0
        try:
            if all(len(f) >= 4 and not _is_number(f[0]) for f in lines):
                edits = self._paste_points(lines)
            else:
                edits = self._paste_cells(lines)
        except PrismError as exc:
            self._message(f"Nothing pasted: {exc}")
            return 0
        if edits:
            stack = self.w.undo_stack
            stack.beginMacro(f"Paste {len(edits)} point{'s' if len(edits) > 1 else ''}")
            try:
                for c in edits:
                    stack.push(c)
            finally:
                stack.endMacro()
        return len(edits)

    def _paste_points(self, lines) -> list:
        p, out, seen = self.w.project, [], set()
        for i, f in enumerate(lines, 1):
            pid = f[0]
            if pid in seen:
                raise InputError(f"line {i}: point {pid} pasted twice")
            seen.add(pid)
            vals = [parse_number(t, f"line {i} ({pid}) {c}") for t, c in zip(f[1:4], "ENH")]
            sig = [parse_number(t, f"line {i} ({pid}) σ", sigma=True) for t in f[4:6]]
            sig += [None] * (2 - len(sig))
            if pid in p.points:
                old = p.points[pid]
                new = replace(old, E=vals[0], N=vals[1], H=vals[2],
                              sigma_xy_m=sig[0] if len(f) > 4 else old.sigma_xy_m,
                              sigma_h_m=sig[1] if len(f) > 5 else old.sigma_h_m)
                out.append(cmd.EditPoint(p, pid, new, f"Paste {pid}"))
            else:
                out.append(cmd.AddPoint(p, GroundPoint(pid, *vals, height_kind=p.height_kind(),
                                                       kind="GCP", sigma_xy_m=sig[0], sigma_h_m=sig[1])))
        return out

    def _paste_cells(self, lines) -> list:
        t, p = self.w.table, self.w.project
        idx = t.currentIndex()
        if not idx.isValid():
            raise InputError("select the cell to paste into")
        ids = t.ordered_ids()
        first = COLUMNS[idx.column()]
        if first not in _NUMERIC:
            raise InputError(f"numbers go into {', '.join(_NUMERIC)}, not {first}")
        cols = _NUMERIC[_NUMERIC.index(first):]
        out = []
        for i, f in enumerate(lines):
            r = idx.row() + i
            if r >= len(ids):
                raise InputError(f"{len(lines)} lines do not fit below row {idx.row() + 1}")
            if len(f) > len(cols):
                raise InputError(f"line {i + 1}: {len(f)} values for {len(cols)} columns")
            pid = ids[r]
            new = p.points[pid]
            for text, col in zip(f, cols):
                new = edited_point(new, col, text, p.height_kind())
            out.append(cmd.EditPoint(p, pid, new, f"Paste {pid}"))
        return out

    # ------------------------------------------------------------------ new point by coordinates
    def new_point_dialog(self) -> GroundPoint | None:
        """Ask for a point's id, kind, E, N, H, height kind and σ; add it (one undo step), make it
        current and switch to measuring it. Returns the point added (None: cancelled)."""
        p = self.w.project
        if p is None:
            return None
        dlg = NewPointDialog(self.w, {k: p.new_point_id(k[0]) for k in ("GCP", "ICP")}, p.height_kind(),
                             taken=p.points)
        if dlg.exec() != QDialog.DialogCode.Accepted or dlg.accepted_point is None:
            return None
        point = dlg.accepted_point
        self.w.undo_stack.push(cmd.AddPoint(p, point))
        self.w.set_current(point.id, drive=False)
        self._drive_when_predicted(point.id)
        mode = getattr(self.w, "measure_mode", None)
        if mode is not None:
            mode.set_mode("measure")
        self._message(f"{point.id}: click it in each view (the hollow marker is where the model puts it)")
        return point


    def _drive_when_predicted(self, pid: str) -> None:
        """Centre the views on ``pid``'s predictions once the fit that includes it is out (a
        point added now has none until then)."""
        solver, views = self.w.solver, self.w.views

        def drive(*_):
            sol = solver.solution
            if sol is None or sol.revision < self.w.project.revision:
                return  # an older fit: wait for the next one
            solver.solution_changed.disconnect(drive)
            if self.w.current == pid:
                views.drive_to(pid)
        solver.solution_changed.connect(drive)
        drive()


class CellDelegate(QStyledItemDelegate):
    """The table's cell editors keep Enter, Esc and Tab for themselves: the window has
    shortcuts on those keys (accepting a point transfer, rejecting it) that would otherwise
    take them while a cell is being edited."""

    KEYS = (Qt.Key.Key_Return, Qt.Key.Key_Enter, Qt.Key.Key_Escape, Qt.Key.Key_Tab)

    def eventFilter(self, editor, event):
        if event.type() == QEvent.Type.ShortcutOverride and event.key() in self.KEYS:
            event.accept()  # delivered to the editor as a key press, not to a shortcut
            return True
        return super().eventFilter(editor, event)


class ChoiceDelegate(CellDelegate):
    """A cell chosen from a list (Kind: GCP, ICP, TIE; Height: ellipsoidal, orthometric); the
    letter keys choose, Enter sets."""

    def __init__(self, items, parent=None):
        super().__init__(parent)
        self.items = list(items)

    def createEditor(self, parent, option, index):
        box = QComboBox(parent)
        box.addItems(self.items)
        return box

    def setEditorData(self, editor, index):
        editor.setCurrentText(index.data())

    def setModelData(self, editor, model, index):
        model.setData(index, editor.currentText())


class NewPointDialog(QDialog):
    """Id, kind (GCP, ICP), E, N, H (metres), height kind, σ plan and σ h (metres, optional).

    ``ids``: the id proposed for each kind (the next free one, :meth:`Project.new_point_id`);
    switching the kind switches the proposal until the operator types an id of their own.
    ``height_kind``: the one preselected (the project's)."""

    def __init__(self, parent, ids: dict, height_kind: str, taken=()):
        super().__init__(parent)
        self.setWindowTitle("New point from coordinates")
        fit_title(self)
        form = QFormLayout(self)
        self.ids = dict(ids)
        self.id_edit = QLineEdit(self.ids["GCP"])
        self.kind = QComboBox()
        self.kind.addItems(["GCP", "ICP"])
        self.kind.currentTextChanged.connect(self._propose_id)
        self.e, self.n, self.h = QLineEdit(), QLineEdit(), QLineEdit()
        self.height_kind = QComboBox()
        self.height_kind.addItems(list(HEIGHT_KINDS))
        self.height_kind.setCurrentText(height_kind)
        self.s_xy, self.s_h = QLineEdit(), QLineEdit()
        for w, tip in ((self.e, "Easting, metres of the project CRS"), (self.n, "Northing, metres"),
                       (self.h, "Height, metres, of the height kind below"),
                       (self.s_xy, "Known accuracy in plan, metres (empty: the model's default)"),
                       (self.s_h, "Known accuracy in height, metres (empty: the model's default)")):
            w.setToolTip(tip)
        for label, w in (("ID", self.id_edit), ("Kind", self.kind), ("E (m)", self.e), ("N (m)", self.n),
                         ("H (m)", self.h), ("Height", self.height_kind), ("σ plan (m)", self.s_xy),
                         ("σ h (m)", self.s_h)):
            form.addRow(label, w)
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel)
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        form.addRow(buttons)
        self.e.setFocus()
        self.taken = taken  # ids already in the project
        self.accepted_point: GroundPoint | None = None

    def _propose_id(self, kind: str) -> None:
        if self.id_edit.text().strip() in self.ids.values():  # not typed by the operator
            self.id_edit.setText(self.ids.get(kind, self.id_edit.text()))

    def accept(self) -> None:
        """Close only on a valid, new point; otherwise say what is wrong and stay open."""
        try:
            point = self.point()
            if point.id in self.taken:
                raise InputError(f"point {point.id!r} already exists")
        except PrismError as exc:
            QMessageBox.warning(self, "New point", plain(str(exc)))
            return
        self.accepted_point = point
        super().accept()

    def point(self) -> GroundPoint:
        """The point typed (raises InputError naming the field that is wrong)."""
        pid = self.id_edit.text().strip()
        if not pid:
            raise InputError("the point needs an id")
        vals = [parse_number(w.text(), c) for w, c in ((self.e, "E"), (self.n, "N"), (self.h, "H"))]
        if not all(math.isfinite(v) for v in vals):
            raise InputError("E, N and H are all needed")
        return GroundPoint(pid, *vals, height_kind=self.height_kind.currentText(), kind=self.kind.currentText(),
                           sigma_xy_m=parse_number(self.s_xy.text(), "σ plan", sigma=True),
                           sigma_h_m=parse_number(self.s_h.text(), "σ h", sigma=True))
