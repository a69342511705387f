"""Import of ground points or image measurements.

:class:`ImportDialog` reads a CSV with any delimiter and any column names (one combo per field
maps a file column onto docs/formats.md's names), or another tool's point file (QGIS ``.points``,
OpenDroneMap ``gcp_list.txt``, Ames Stereo Pipeline ``.gcp``) through
:mod:`prismstation.io.pointfiles`. It shows a preview of the first rows and every bad line as
``file, line N: problem``. On accept, :meth:`ImportDialog.result` gives
``(points: list[GroundPoint], measurements: list[Measurement])`` in the project CRS.

The CSV path never re-implements the readers: :func:`~prismstation.io.mapped_csv.read_mapped`
reads the file through :mod:`prismstation.io.csvtable` and the io point readers with the chosen
column mapping; they return every bad line, each with its own message, file and line.
"""
from __future__ import annotations

from html import escape
from dataclasses import replace
from pathlib import Path

from PySide6.QtCore import QAbstractTableModel, QModelIndex, Qt, QTimer
from PySide6.QtGui import QColor
from PySide6.QtWidgets import (QCheckBox, QComboBox, QDialog, QDialogButtonBox, QFileDialog,
                               QFormLayout, QGroupBox, QHBoxLayout, QLabel, QLineEdit,
                               QListWidget, QPushButton, QSplitter, QTableView, QVBoxLayout,
                               QWidget)

from prismstation.errors import InputError
from prismstation.io import pointfiles
from prismstation.io.csvtable import guess_delimiter, read_text
from prismstation.io.mapped_csv import (DELIMITERS, GROUND_FIELDS, MEASUREMENT_FIELDS, NONE,
                                        PREVIEW_ROWS, guess_mapping, guess_view, shared_columns,
                                        has_decimal_comma, is_point_file, read_mapped,
                                        split_lines)
from prismstation.model.points import HEIGHT_KINDS
from prismstation.gui.plain import plain

__all__ = ["ImportDialog", "PreviewModel", "guess_delimiter", "guess_mapping", "GROUND_FIELDS",
           "MEASUREMENT_FIELDS", "read_mapped"]


# ------------------------------------------------------------------------- preview model
class PreviewModel(QAbstractTableModel):
    """Rows of text; rows with a problem tinted red with the problem as tooltip."""

    def __init__(self, parent=None):
        super().__init__(parent)
        self.columns: list[str] = []
        self.rows: list[list[str]] = []
        self.line_numbers: list = []
        self.problems: dict = {}  # row -> text

    def set_content(self, columns, rows, line_numbers=None, problems=None) -> None:
        self.beginResetModel()
        self.columns = list(columns)
        self.rows = [list(r) for r in rows]
        self.line_numbers = list(line_numbers or [])
        self.problems = dict(problems or {})
        self.endResetModel()

    def rowCount(self, parent=QModelIndex()):
        return 0 if parent.isValid() else len(self.rows)

    def columnCount(self, parent=QModelIndex()):
        return 0 if parent.isValid() else len(self.columns)

    def data(self, index, role=Qt.ItemDataRole.DisplayRole):
        if not index.isValid():
            return None
        r, c = index.row(), index.column()
        if role == Qt.ItemDataRole.DisplayRole:
            row = self.rows[r]
            return row[c] if c < len(row) else ""
        if role == Qt.ItemDataRole.BackgroundRole and r in self.problems:
            return QColor(255, 205, 205)
        if role == Qt.ItemDataRole.ToolTipRole and r in self.problems:
            return self.problems[r]
        return None

    def headerData(self, section, orientation, role=Qt.ItemDataRole.DisplayRole):
        if role != Qt.ItemDataRole.DisplayRole:
            return None
        if orientation == Qt.Orientation.Horizontal:
            return self.columns[section] if section < len(self.columns) else None
        if section < len(self.line_numbers):
            return str(self.line_numbers[section])
        return str(section + 1)


# ------------------------------------------------------------------------- the dialog
class ImportDialog(QDialog):
    """Import ground points or image measurements into a project.

    Parameters
    ----------
    scene_views : iterable of str
        The scene's view names (``N``, ``F``, ``B``); measurements must name one of them.
    crs : str
        The project CRS; ground points are converted into it from the source CRS.
    parent : QWidget, optional
    height_kind : str
        The kind of the heights of rows and files that do not say (the project's,
        :meth:`Project.height_kind`, unless the operator chooses the other).
    """

    def __init__(self, scene_views, crs, parent=None, height_kind: str = "ellipsoidal"):
        super().__init__(parent)
        self.setWindowTitle("Import points or measurements")
        self.views = list(scene_views)
        self.crs = crs
        self.path: Path | None = None
        self._text = ""
        self._result: tuple[list, list] = ([], [])
        self._errors: list[InputError] = []
        self._warnings: list[str] = []
        self._pf = None
        self._kept = None  # ((path, content, columns), {field: combo text}) of the last mapping
        self._kept_key = None
        self._timer = QTimer(self, singleShot=True, interval=0)
        self._timer.timeout.connect(self.refresh)

        self.path_edit = QLineEdit()
        self.path_edit.setPlaceholderText("a CSV, QGIS .points, ODM gcp_list.txt or ASP .gcp file")
        self.path_edit.returnPressed.connect(lambda: self.set_path(self.path_edit.text()))
        self.path_edit.editingFinished.connect(self._path_edited)
        browse = QPushButton("Browse…")
        browse.clicked.connect(self._browse)
        self.what = QComboBox()
        self.what.addItem("Ground points", "points")
        self.what.addItem("Image measurements", "measurements")
        self.format_label = QLabel()
        self.delimiter = QComboBox()
        self.delimiter.addItems(list(DELIMITERS))
        self.has_header = QCheckBox("first row is a header")
        self.has_header.setChecked(True)
        self.decimal_comma = QCheckBox("decimal comma")
        self.decimal_comma.setToolTip("numbers written 123,45 (the delimiter is then not a comma)")
        self.crs_edit = QLineEdit(crs or "")
        self.crs_status = QLabel()
        self.height_kind = QComboBox()
        self.height_kind.addItems(list(HEIGHT_KINDS))
        self.height_kind.setCurrentText(height_kind)
        self.height_kind.setToolTip(f"The project's points are {height_kind} (most of them): rows "
                                    "without a height kind are read as this")
        self.columns_box = QGroupBox("Columns")
        self.columns_form = QFormLayout(self.columns_box)
        self.combos: dict[str, QComboBox] = {}
        self.preview_model = PreviewModel(self)
        self.preview = QTableView()
        self.preview.setModel(self.preview_model)
        self.preview.verticalHeader().setDefaultSectionSize(20)
        self.error_list = QListWidget()
        self.error_list.currentRowChanged.connect(self._show_error_row)
        self.status = QLabel()
        self.buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok
                                        | QDialogButtonBox.StandardButton.Cancel)
        self.buttons.button(QDialogButtonBox.StandardButton.Ok).setText("Import")
        self.buttons.accepted.connect(self.accept)
        self.buttons.rejected.connect(self.reject)

        top = QFormLayout()
        row = QHBoxLayout()
        row.addWidget(self.path_edit, 1)
        row.addWidget(browse)
        top.addRow("File", row)
        row = QHBoxLayout()
        row.addWidget(self.what)
        row.addWidget(self.format_label, 1)
        top.addRow("Content", row)
        row = QHBoxLayout()
        row.addWidget(self.delimiter)
        row.addWidget(self.has_header)
        row.addWidget(self.decimal_comma)
        row.addStretch(1)
        top.addRow("Delimiter", row)
        row = QHBoxLayout()
        row.addWidget(self.crs_edit, 1)
        row.addWidget(self.crs_status, 1)
        top.addRow("Source CRS", row)
        top.addRow("Heights without a kind", self.height_kind)
        left = QWidget()
        lv = QVBoxLayout(left)
        lv.setContentsMargins(0, 0, 0, 0)
        lv.addLayout(top)
        lv.addWidget(self.columns_box)
        lv.addStretch(1)
        right = QSplitter(Qt.Orientation.Vertical)
        right.addWidget(self.preview)
        box = QGroupBox("Problems (file, line: problem)")
        QVBoxLayout(box).addWidget(self.error_list)
        right.addWidget(box)
        right.setSizes([300, 120])
        split = QSplitter()
        split.addWidget(left)
        split.addWidget(right)
        split.setSizes([380, 520])
        lay = QVBoxLayout(self)
        lay.addWidget(split, 1)
        bottom = QHBoxLayout()
        bottom.addWidget(self.status, 1)
        bottom.addWidget(self.buttons)
        lay.addLayout(bottom)
        self.resize(960, 560)

        self.what.currentIndexChanged.connect(self._rebuild_columns)
        self.delimiter.currentIndexChanged.connect(self._rebuild_columns)
        self.has_header.toggled.connect(self._rebuild_columns)
        self.decimal_comma.toggled.connect(self.schedule)
        self.crs_edit.textChanged.connect(self.schedule)
        self.height_kind.currentIndexChanged.connect(self.schedule)
        self._set_ok(False)
        self.status.setText("Choose a file.")

    # ---------------------------------------------------------------- public
    def set_path(self, path) -> None:
        """(Re)load ``path`` as the Browse button does: guess content, delimiter and columns;
        a file read again with the same columns keeps the mapping chosen for it."""
        if not path:
            return
        path = Path(path)
        self.path = path
        self.path_edit.setText(str(path))
        self._pf = None
        try:
            self._text = read_text(path)
        except InputError as exc:  # nothing of the previous file stays on show
            self._text = ""
            self._clear_form()
            self.format_label.setText("")
            self.preview_model.set_content([], [])
            self._show_errors([InputError(f"{exc.problem}: a point or measurement file is text "
                                          "(CSV, QGIS .points, ODM gcp_list.txt or ASP .gcp)", path)])
            return
        point_file = is_point_file(path)
        self.delimiter.setEnabled(not point_file)
        self.has_header.setEnabled(not point_file)
        self.decimal_comma.setEnabled(not point_file)
        self.what.setEnabled(not point_file)
        if point_file:
            fmt = pointfiles.detect_format(path)
            self.format_label.setText({"qgis": "QGIS .points", "odm": "OpenDroneMap gcp_list.txt",
                                       "asp": "Ames Stereo Pipeline .gcp"}[fmt])
        else:
            lines = self._text.splitlines()
            d = guess_delimiter(lines)
            self.format_label.setText(f"CSV, delimiter {d!r} guessed")
            _, cols, rows = split_lines(self._text, d, True)
            self.decimal_comma.blockSignals(True)
            self.decimal_comma.setChecked(has_decimal_comma(rows, d))
            self.decimal_comma.blockSignals(False)
            # the content whose required fields the header names best (ties: ground points)
            n_req = [sum(f in guess_mapping(cols, fields, rows) for f, req in fields if req)
                     for fields in (GROUND_FIELDS, MEASUREMENT_FIELDS)]
            self.what.blockSignals(True)
            self.what.setCurrentIndex(1 if n_req[1] > n_req[0] else 0)
            self.what.blockSignals(False)
        self._rebuild_columns()

    def set_mapping(self, field: str, column: str) -> None:
        """Map ``field`` onto the file column ``column`` (or ``'(none)'``, or ``'= N'``)."""
        combo = self.combos[field]
        i = combo.findText(column)
        if i < 0:
            raise KeyError(f"no column {column!r} for {field}")
        combo.setCurrentIndex(i)
        self.refresh()

    def mapping(self) -> tuple[dict, dict]:
        """``({field: column}, {field: constant})`` as the combos say."""
        cols, consts = {}, {}
        for f, combo in self.combos.items():
            t = combo.currentText()
            if t.startswith("= "):
                consts[f] = t[2:]
            elif t and t != NONE:
                cols[f] = t
        return cols, consts

    def errors(self) -> list[str]:
        """The problems shown, as ``file, line N: problem`` texts."""
        return [str(e) for e in self._errors]

    def warnings(self) -> list[str]:
        """The warnings shown below the problems (``warning: …``); they do not block the import."""
        return list(self._warnings)

    def result(self):  # noqa: D401 — overrides QDialog.result() (the dialog code is exec()'s)
        """``(points: list[GroundPoint], measurements: list[Measurement])`` read from the file."""
        return self._result

    def schedule(self) -> None:
        """Re-read the file at the next event-loop turn (changes coalesce)."""
        self._timer.start()

    # ---------------------------------------------------------------- building
    def _fields(self):
        return GROUND_FIELDS if self.what.currentData() == "points" else MEASUREMENT_FIELDS

    def _delimiter(self) -> str:
        d = DELIMITERS[self.delimiter.currentText()]
        return guess_delimiter(self._text.splitlines()) if d is None else d

    def _clear_form(self) -> None:
        while self.columns_form.rowCount():
            self.columns_form.removeRow(0)
        self.combos = {}

    def _rebuild_columns(self) -> None:
        self._clear_form()
        if self.path is None:
            return
        if not self.what.isEnabled():  # a point file: map its image names onto views
            self.columns_box.setTitle("Images → views")
            self._build_point_file_form()
        else:
            self.columns_box.setTitle("Columns")
            _, columns, rows = split_lines(self._text, self._delimiter(), self.has_header.isChecked())
            guess = guess_mapping(columns, self._fields(), rows)
            key = (str(self.path), self.what.currentData(), tuple(columns))
            if self._kept is not None and self._kept[0] == key:  # same file and columns again
                guess = {f: c for f, c in self._kept[1].items()}
            for f, required in self._fields():
                combo = QComboBox()
                items = [NONE] + columns
                if f == "view":
                    items += [f"= {v}" for v in self.views]
                combo.addItems(items)
                if f in guess:
                    combo.setCurrentText(guess[f])
                elif self._kept is not None and self._kept[0] == key:
                    combo.setCurrentText(NONE)
                elif f == "view" and self.views:
                    combo.setCurrentText(f"= {self.views[0]}")
                combo.currentIndexChanged.connect(self.schedule)
                self.combos[f] = combo
                self.columns_form.addRow(f + (" *" if required else ""), combo)
            self._kept_key = key
        self.refresh()

    def _build_point_file_form(self) -> None:
        fmt = pointfiles.detect_format(self.path)
        try:
            pf = pointfiles.read_point_file(self.path, fmt, height=self.height_kind.currentText(),
                                            view=self.path.stem)
        except InputError as exc:
            self._pf = None
            self._show_errors([exc])
            return
        self._pf = pf
        if pf.crs:
            self.crs_edit.blockSignals(True)
            self.crs_edit.setText(pf.crs)
            self.crs_edit.blockSignals(False)
        for name in dict.fromkeys(m.view for m in pf.measurements):
            combo = QComboBox()
            combo.addItems([NONE] + self.views)
            combo.setCurrentText(guess_view(name, self.views) or NONE)
            combo.currentIndexChanged.connect(self.schedule)
            self.combos[name] = combo
            self.columns_form.addRow(name, combo)

    # ---------------------------------------------------------------- reading
    def _source_crs(self):
        text = self.crs_edit.text().strip()
        if not text:
            self.crs_status.setText("project CRS")
            return None
        try:
            crs = pointfiles.parse_crs(text)
        except InputError as exc:
            self.crs_status.setText(f'<span style="color:#c00">{escape(exc.problem)}</span>')
            raise
        self.crs_status.setText(crs.name)
        return crs

    def refresh(self) -> None:
        """Re-read the file with the current choices; update preview, problems, OK button."""
        if self.path is None:
            return
        try:
            src = self._source_crs()
        except InputError as exc:
            self._show_errors([InputError(f"source CRS: {exc.problem}")])
            return
        if not self.what.isEnabled():
            self._refresh_point_file(src)
        else:
            self._refresh_csv(src)

    def _refresh_csv(self, src) -> None:
        what = self.what.currentData()
        cols, consts = self.mapping()
        self._kept = (self._kept_key, {**cols, **{f: f"= {v}" for f, v in consts.items()}})
        missing = [f for f, req in self._fields() if req and f not in cols and f not in consts]
        delim, header = self._delimiter(), self.has_header.isChecked()
        hline, columns, rows = split_lines(self._text, delim, header)
        errors = [InputError(f"map a column onto {f}", self.path) for f in missing]
        errors += [InputError(p, self.path) for p in shared_columns(cols)]
        recs = []
        if not errors:
            recs, errors = read_mapped(self.path, what, self._text, cols, delimiter=delim,
                                       header=header, constants=consts, crs=src,
                                       to_crs=self.crs if src is not None else None,
                                       height=self.height_kind.currentText(), views=self.views,
                                       decimal_comma=self.decimal_comma.isChecked())
        inverse = {c: f for f, c in cols.items()}
        heads = [f"{inverse[c]} ← {c}" if c in inverse else c for c in columns]
        shown = rows[:PREVIEW_ROWS]
        by_line = {no: i for i, (no, _) in enumerate(shown)}
        problems = {by_line[e.line]: e.problem for e in errors if e.line in by_line}
        self.preview_model.set_content(heads, [c for _, c in shown], [no for no, _ in shown], problems)
        self._result = (recs, []) if what == "points" else ([], recs)
        self._show_errors(errors, f"{len(recs)} {'ground points' if what == 'points' else 'measurements'} "
                                  f"read from {len(rows)} rows" if recs else None)

    def _refresh_point_file(self, src) -> None:
        pf = self._pf
        if pf is None:
            return
        errors = []
        try:
            pf = pointfiles.read_point_file(self.path, height=self.height_kind.currentText(),
                                            view=self.path.stem)
            if src is not None and self.crs:
                pf = pointfiles.convert_point_file(replace(pf, crs=src.to_wkt()), self.crs)
        except InputError as exc:
            errors.append(exc)
        views = {name: combo.currentText() for name, combo in self.combos.items()}
        meas = [replace(m, view=views[m.view]) for m in pf.measurements
                if views.get(m.view, NONE) != NONE]
        points = list(pf.points)
        seen = {}
        for m in pf.measurements:
            if views.get(m.view, NONE) != NONE:
                seen.setdefault(m.id, []).append(views[m.view])
        rows = [[p.id, p.kind, f"{p.E:.3f}", f"{p.N:.3f}", f"{p.H:.3f}", p.height_kind,
                 " ".join(seen.get(p.id, []))] for p in points[:PREVIEW_ROWS]]
        self.preview_model.set_content(["id", "kind", "E", "N", "H", "height", "measured in"], rows)
        self._result = ([], []) if errors else (points, meas)
        self._show_errors(errors, f"{len(points)} ground points and {len(meas)} measurements "
                                  f"({len(pf.measurements) - len(meas)} in images not mapped)",
                          pf.warnings)

    def _show_errors(self, errors, ok_text=None, warnings=()) -> None:
        """List ``errors`` (they block the import) and then ``warnings`` (they do not)."""
        self._errors = list(errors)
        self._warnings = [f"warning: {w}" for w in warnings]
        self.error_list.clear()
        self.error_list.addItems([str(e) for e in errors] + self._warnings)
        if self._warnings and not errors:
            ok_text = f"{ok_text or ''} — {len(self._warnings)} warning{'s' * (len(self._warnings) > 1)}"
        if errors:
            self._result = ([], [])
            self.status.setText(f'<span style="color:#c00">{len(errors)} problem'
                                f'{"s" * (len(errors) > 1)}: fix the file or the choices</span>')
        else:
            self.status.setText(plain(ok_text or "nothing to import"))
        self._set_ok(not errors and bool(self._result[0] or self._result[1]))

    def _set_ok(self, on: bool) -> None:
        self.buttons.button(QDialogButtonBox.StandardButton.Ok).setEnabled(on)

    def _show_error_row(self, i: int) -> None:
        if 0 <= i < len(self._errors) and self._errors[i].line in self.preview_model.line_numbers:
            row = self.preview_model.line_numbers.index(self._errors[i].line)
            self.preview.selectRow(row)
            self.preview.scrollTo(self.preview_model.index(row, 0))

    def _path_edited(self) -> None:
        if self.path_edit.text() and self.path_edit.text() != str(self.path):
            self.set_path(self.path_edit.text())

    def _browse(self) -> None:
        path, _ = QFileDialog.getOpenFileName(
            self, "Import points or measurements", str(self.path.parent if self.path else ""),
            "Point and measurement files (*.csv *.txt *.points *.gcp);;All files (*)")
        if path:
            self.set_path(path)
