"""The one reader of delimited text tables (CSV, semicolon, tab, bar or blank separated).

Rules, the same for every table prismstation reads (ground points, measurements, point pairs,
the import dialog, other tools' point files): UTF-8 text (a byte-order mark is dropped); blank
lines and lines starting with ``#`` are skipped; the delimiter is the one of ``, ; tab |`` that
splits the first line and most of the next twenty into the same number of fields, else blanks;
cells are stripped; header names match field names case-insensitively; a cell written by
:func:`text_cell` (``'=…``: a leading ``'`` before ``= + - @``, tab or CR) is read back as it was.

A bad data line never stops the reading: :func:`records` returns the good rows and one
:class:`~prismstation.errors.InputError` (file, 1-based line, problem) per bad line; readers
add their own per-line errors the same way. Only a problem with the whole file (unreadable,
empty, a required column missing) is raised at once.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from prismstation.errors import InputError
from prismstation.io.inputs import local_file


def guess_delimiter(lines) -> str:
    """The delimiter of text ``lines``: the one of ``, ; tab |`` that splits the first line and
    most of the next 20 into the same number of fields, else ``" "`` (blanks), else ``,``."""
    rows = [ln for ln in lines if ln.strip() and not ln.lstrip().startswith("#")][:21]
    if not rows:
        return ","
    best, score = None, (0, 0.0)
    for d in (",", ";", "\t", "|"):
        n = rows[0].count(d)
        if n == 0:
            continue
        same = sum(ln.count(d) == n for ln in rows) / len(rows)
        if (same, n) > (score[1], score[0]):
            best, score = d, (n, same)
    if best is not None:
        return best
    return " " if len(rows[0].split()) > 1 else ","


@dataclass
class Table:
    """The cells of a text table.

    ``columns``: header names (``column 1``, ``column 2``, … without a header);
    ``header_line``: 1-based line of the header (None without one);
    ``rows``: ``[(line, cells)]`` of the data lines, 1-based line numbers of the file.
    """

    path: str | None
    columns: list
    header_line: int | None
    rows: list
    delimiter: str
    comments: list = field(default_factory=list)  # [(line, text)] of the '#' lines


#: first characters that make a spreadsheet take a cell for a formula (and run it)
FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def text_cell(value) -> str:
    """``value`` (an id, a view, a label) as a CSV cell a spreadsheet shows and never runs: a
    cell starting with ``= + - @``, tab or CR that is not a plain number gets a leading ``'``,
    which spreadsheets take as "this is text" (``=cmd|' /C calc'!A0`` → ``'=cmd|' /C calc'!A0``;
    ``-12.5`` stays a number). Every writer of a CSV prismstation makes passes its text cells
    through here; :func:`_split` — every reader — takes the ``'`` off again."""
    text = "" if value is None else str(value)
    if text.startswith(FORMULA_START):
        try:
            float(text)
        except ValueError:
            return "'" + text
    return text


def _plain(cell: str) -> str:
    """A cell as written before :func:`text_cell` guarded it."""
    return cell[1:] if cell[:1] == "'" and cell[1:2] in FORMULA_START and cell[1:2] else cell


def _split(line: str, delimiter: str) -> list:
    if delimiter == " ":
        return [_plain(c) for c in line.split()]
    return [_plain(c.strip()) for c in next(csv.reader([line], delimiter=delimiter, skipinitialspace=True), [])]


def split_text(text: str, delimiter: str | None = None, header: bool = True, path=None) -> Table:
    """A :class:`Table` of ``text``; ``delimiter`` None = guessed (:func:`guess_delimiter`)."""
    lines = text.splitlines()
    d = guess_delimiter(lines) if delimiter is None else delimiter
    rows, comments = [], []
    for no, ln in enumerate(lines, 1):
        if not ln.strip():
            continue
        if ln.lstrip().startswith("#"):
            comments.append((no, ln.strip()))
            continue
        try:
            rows.append((no, _split(ln, d)))
        except csv.Error as exc:  # a field past the csv module's limit (131,072 characters)
            raise InputError(f"unreadable line ({exc})", path, no) from None
    path = None if path is None else str(path)
    if not rows:
        return Table(path, [], None, [], d, comments)
    if header:
        hno, names = rows[0]
        return Table(path, [n or f"column {i + 1}" for i, n in enumerate(names)], hno, rows[1:], d,
                     comments)
    width = max(len(c) for _, c in rows)
    return Table(path, [f"column {i + 1}" for i in range(width)], None, rows, d, comments)


def read_text(path) -> str:
    """The UTF-8 text of ``path``; :class:`InputError` naming the file when it cannot be read."""
    try:
        return local_file(path).read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise InputError("file not found", path) from None
    except UnicodeDecodeError:
        raise InputError("not a text file (not UTF-8)", path) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", path) from None


def read_table(path, delimiter: str | None = None, header: bool = True) -> Table:
    """:func:`split_text` of the file ``path``; raises when it has no line of data."""
    table = split_text(read_text(path), delimiter, header, path)
    if not table.columns:
        raise InputError("empty file: expected a header row" if header else "empty file", path, 1)
    return table


@dataclass
class Row:
    """One data line: ``values`` by field name (mapped fields) or file column name (the rest)."""

    path: str | None
    line: int
    values: dict
    decimal_comma: bool = False

    def text(self, name: str) -> str:
        return self.values.get(name, "")

    def error(self, problem: str) -> InputError:
        return InputError(problem, self.path, self.line)

    def number(self, name: str, optional: bool = False) -> float | None:
        """The finite float in field ``name``; None when empty and ``optional``; else raises."""
        raw = self.text(name)
        if raw == "":
            if optional:
                return None
            raise self.error(f"column {name} is empty")
        try:
            v = float(raw.replace(",", ".") if self.decimal_comma else raw)
        except ValueError:
            raise self.error(f"column {name}: {raw!r} is not a number") from None
        if not math.isfinite(v):
            raise self.error(f"column {name}: {raw!r} is not a finite number")
        return v


def records(table: Table, fields, required=(), *, mapping=None, constants=None,
            decimal_comma=False):
    """``(rows, errors)``: a :class:`Row` per good line, an InputError per line whose field
    count differs from the header's.

    ``fields``: the field names the reader knows; without ``mapping`` each is matched to a column
    of the same name (case-insensitive). ``mapping`` ``{field: column}`` names the columns
    instead; ``constants`` ``{field: value}`` gives a field one value on every row. Other columns
    keep their names (``name (file)`` when the name is a field's). A ``required`` field with no
    column raises an InputError on the header line.
    """
    constants = dict(constants or {})
    low = {c.lower(): c for c in reversed(table.columns)}
    if mapping is None:
        mapping = {f: low[f.lower()] for f in fields if f.lower() in low and f not in constants}
    missing = [f for f in required if f not in mapping and f not in constants]
    if missing:
        raise InputError(f"header lacks column{'s' * (len(missing) > 1)} {', '.join(missing)} "
                         f"(found: {', '.join(table.columns)!r})", table.path,
                         table.header_line or 1)
    index = {c: i for i, c in reversed(list(enumerate(table.columns)))}
    canon = {f.lower() for f in fields} | {f.lower() for f in mapping} | {f.lower() for f in constants}
    src = [(f, index[c]) for f, c in mapping.items()]
    used = set(mapping.values())
    src += [(f"{c} (file)" if c.lower() in canon else c, i) for i, c in enumerate(table.columns)
            if c not in used]
    width = len(table.columns)
    rows, errors = [], []
    for no, cells in table.rows:
        if len(cells) != width:
            where = "the header has" if table.header_line is not None else "the widest row has"
            errors.append(InputError(f"{len(cells)} fields where {where} {width}", table.path, no))
            continue
        values = {name: cells[i] for name, i in src}
        values.update(constants)
        rows.append(Row(table.path, no, values, decimal_comma))
    return rows, errors


def raise_errors(errors) -> None:
    """Raise the first of ``errors`` (naming how many more lines are bad), if there are any."""
    if not errors:
        return
    first = errors[0]
    if len(errors) == 1:
        raise first
    more = sorted({e.line for e in errors[1:] if e.line is not None})
    shown = ", ".join(map(str, more[:10])) + (", …" if len(more) > 10 else "")
    raise InputError(f"{first.problem} (and {len(errors) - 1} more problem"
                     f"{'s' * (len(errors) > 2)}{f': lines {shown}' if more else ''})",
                     first.file, first.line)
