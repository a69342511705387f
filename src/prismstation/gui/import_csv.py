"""Column-mapped CSV reading for the import dialog (no Qt): delimiter and column guesses, and
:func:`read_mapped`, which hands a normalised copy of the file to the io readers so that their
own messages name the original file and lines (every bad line, not only the first).
"""
from __future__ import annotations

import csv
import io
import os
import re
import tempfile
from pathlib import Path

from prismstation.errors import InputError
from prismstation.io import pointfiles
from prismstation.io.points import read_ground_points, read_measurements

GROUND_FIELDS = (("id", True), ("E", True), ("N", True), ("H", True), ("kind", False),
                 ("height", False), ("sigma_xy_m", False), ("sigma_h_m", False))
MEASUREMENT_FIELDS = (("id", True), ("view", True), ("x", True), ("y", True), ("sigma_px", False))
ALIASES = {
    "id": ("id", "name", "point", "pt", "point_id", "pid", "gcp", "gcp_name", "station", "label",
           "nr", "no", "ponto"),
    "E": ("e", "east", "easting", "x", "mapx", "lon", "long", "longitude"),
    "N": ("n", "north", "northing", "y", "mapy", "lat", "latitude"),
    "H": ("h", "z", "elevation", "elev", "alt", "altitude", "height_m", "ortho_h", "cota"),
    "kind": ("kind", "type", "role"),
    "height": ("height", "height_kind", "datum"),
    "view": ("view", "image", "img", "band"),
    "x": ("x", "col", "column", "sample", "px", "image_x"),
    "y": ("y", "row", "line", "py", "image_y"),
}
DELIMITERS = {"auto": None, "comma ,": ",", "semicolon ;": ";", "tab": "\t", "space": " ",
              "bar |": "|"}
NONE = "(none)"
MAX_ERRORS = 200
PREVIEW_ROWS = 200


# ------------------------------------------------------------------------- pure helpers
def guess_delimiter(lines) -> str:
    """The delimiter of CSV ``lines``: the one of ``, ; tab |`` that splits the header and most
    of the first 20 data lines into the same number of fields, else blanks, else ``,``."""
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


def split_lines(text: str, delimiter: str, header: bool = True):
    """``(header_line, header_cells, [(line_number, cells)])`` of the data lines of ``text``.

    Blank lines and ``#`` comments are skipped; line numbers are 1-based in ``text``. Without a
    header the columns are named ``column 1``, ``column 2``, …
    """
    rows = []
    for no, ln in enumerate(text.splitlines(), 1):
        if not ln.strip() or ln.lstrip().startswith("#"):
            continue
        if delimiter == " ":
            cells = ln.split()
        else:
            cells = next(csv.reader([ln], delimiter=delimiter, skipinitialspace=True), [])
        rows.append((no, [c.strip() for c in cells]))
    if not rows:
        return None, [], []
    if header:
        hno, names = rows[0]
        return hno, [n or f"column {i + 1}" for i, n in enumerate(names)], rows[1:]
    width = max(len(c) for _, c in rows)
    return None, [f"column {i + 1}" for i in range(width)], rows


def guess_mapping(columns, fields) -> dict:
    """``{field: column}`` matching names case-insensitively, then by :data:`ALIASES`."""
    low = {c.lower(): c for c in columns}
    out, used = {}, set()
    for f, _ in fields:  # exact names first: 'height' is a kind, not the H column
        if f.lower() in low:
            out[f] = low[f.lower()]
            used.add(out[f])
    for f, _ in fields:
        if f in out:
            continue
        for a in ALIASES.get(f, ()):
            c = low.get(a)
            if c is not None and c not in used:
                out[f], _ = c, used.add(c)
                break
    return out


NUMERIC_FIELDS = ("E", "N", "H", "sigma_xy_m", "sigma_h_m", "x", "y", "sigma_px")
_DECIMAL_COMMA = re.compile(r"^[+-]?\d+,\d+$")


def has_decimal_comma(rows, delimiter: str) -> bool:
    """True when the delimiter is not a comma and numbers are written ``123,45``."""
    if delimiter == ",":
        return False
    cells = [c for _, r in rows[:50] for c in r]
    return sum(bool(_DECIMAL_COMMA.match(c)) for c in cells) >= max(1, len(cells) // 10)


def normalised_csv(n_lines, header_line, columns, rows, mapping, constants=None,
                   decimal_comma=False) -> str:
    """Text of a comma-delimited CSV with canonical column names, every row on its own line.

    ``mapping`` ``{field: column}``; ``constants`` ``{field: value}`` for fields given one value
    for all rows (e.g. the view of a single-image file). Unmapped columns are kept (renamed when
    their name is a canonical one). Lines that are not data become ``#``. With
    ``decimal_comma`` the numeric fields' ``123,45`` become ``123.45``.
    """
    constants = constants or {}
    canon = {f.lower() for f in mapping} | {f.lower() for f in constants}
    index = {c: i for i, c in enumerate(columns)}
    out_cols = list(mapping) + list(constants)
    extra = [c for c in columns if c not in mapping.values()]
    names = out_cols + [f"{c} (file)" if c.lower() in canon else c for c in extra]
    src = [index[mapping[f]] for f in mapping] + [None] * len(constants) + [index[c] for c in extra]
    numeric = {i for i, f in enumerate(mapping) if decimal_comma and f in NUMERIC_FIELDS}
    const_vals = list(constants.values())
    lines = ["#"] * max(n_lines, 1)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="")

    def fmt(cells):
        buf.seek(0)
        buf.truncate()
        w.writerow(cells)
        return buf.getvalue()

    lines[(header_line or 1) - 1] = fmt(names)
    width = len(columns)
    for no, cells in rows:
        if len(cells) != width:  # let the reader name the field-count problem
            lines[no - 1] = fmt(cells + [""] * len(constants))
            continue
        k = 0
        out = []
        for j, s in enumerate(src):
            if s is None:
                out.append(const_vals[k])
                k += 1
            else:
                out.append(cells[s].replace(",", ".") if j in numeric else cells[s])
        lines[no - 1] = fmt(out)
    return "\n".join(lines) + "\n"


def read_mapped(path, what, text, mapping, *, delimiter=",", header=True, constants=None,
                crs=None, to_crs=None, height="ellipsoidal", views=None, decimal_comma=False):
    """Read a CSV through a column mapping with the io readers.

    Returns ``(records, errors)``: ``records`` a list of GroundPoint (``what == "points"``) or
    Measurement, ``errors`` a list of :class:`InputError` naming ``path`` and its lines.
    """
    header_line, columns, rows = split_lines(text, delimiter, header)
    if not columns:
        return [], [InputError("no data in the file", path)]
    n_lines = len(text.splitlines()) or 1
    if header_line is None:  # no header in the file: the normalised copy needs a line for it
        n_lines += 1
        rows = [(no + 1, c) for no, c in rows]
        header_line = 1
    lines = normalised_csv(n_lines, header_line, columns, rows, mapping, constants,
                           decimal_comma).split("\n")
    errors: list[InputError] = []
    fd, tmp = tempfile.mkstemp(suffix=".csv", prefix="prismstation-import-")
    os.close(fd)
    shift = 0 if header else 1
    try:
        for _ in range(MAX_ERRORS + 1):
            Path(tmp).write_text("\n".join(lines), encoding="utf-8")
            try:
                if what == "points":
                    recs = read_ground_points(tmp, crs=crs, to_crs=to_crs, height=height)
                else:
                    recs = read_measurements(tmp, views=views)
                return (recs if not errors else []), errors
            except InputError as exc:
                line = None if exc.line is None else exc.line - shift
                errors.append(InputError(exc.problem, path, line))
                if exc.line is None or exc.line == header_line or exc.line > len(lines):
                    return [], errors
                lines[exc.line - 1] = "#"
        return [], errors
    finally:
        os.unlink(tmp)


def guess_view(image_name: str, views) -> str | None:
    """The scene view an image name refers to (``N.tif`` → N; ALOS ``ALPSMF…`` → F)."""
    stem = Path(str(image_name)).stem
    for cand in (str(image_name), stem, stem.upper()):
        if cand in views:
            return cand
    up = stem.upper()
    if up.startswith("ALPSM") and len(up) > 5 and up[5] in views:
        return up[5]
    return None


def is_point_file(path) -> bool:
    """True for another tool's point file (QGIS, ODM, ASP), False for a CSV to map."""
    p = Path(path)
    if p.suffix.lower() in (".points", ".gcp"):
        return True
    if p.suffix.lower() == ".csv":
        return False
    try:
        return pointfiles.detect_format(p) in ("qgis", "odm", "asp")
    except InputError:
        return False
