"""Column-mapped CSV reading (the import dialog's, no Qt): column guesses from names and
contents, and :func:`read_mapped`, which reads the file through the table reader
(:mod:`~prismstation.io.csvtable`) and the point readers (:mod:`~prismstation.io.points`) with
the operator's column mapping, returning every bad line (file, line, problem).
"""
from __future__ import annotations

import re
from pathlib import Path

from prismstation.errors import InputError
from prismstation.io import pointfiles
from prismstation.io.csvtable import split_text
from prismstation.io.points import ground_points_from_table, measurements_from_table
from prismstation.model.points import HEIGHT_KINDS, KINDS

GROUND_FIELDS = (("id", True), ("E", True), ("N", True), ("H", True), ("kind", False),
                 ("height", False), ("sigma_xy_m", False), ("sigma_h_m", False))
MEASUREMENT_FIELDS = (("id", True), ("view", True), ("x", True), ("y", True), ("sigma_px", False))
ALIASES = {
    "id": ("id", "name", "point", "pt", "point_id", "pid", "gcp", "gcp_name", "station", "label",
           "nr", "no", "ponto"),
    "E": ("e", "east", "easting", "x", "mapx", "lon", "long", "longitude"),
    "N": ("n", "north", "northing", "y", "mapy", "lat", "latitude"),
    "H": ("h", "z", "elevation", "elev", "alt", "altitude", "height_m", "ortho_h", "cota",
          "height", "hgt"),
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
def split_lines(text: str, delimiter: str, header: bool = True):
    """``(header_line, header_cells, [(line_number, cells)])`` of the data lines of ``text``
    (:func:`prismstation.io.csvtable.split_text`)."""
    t = split_text(text, delimiter, header)
    return t.header_line, t.columns, t.rows


def _fits(field: str, values) -> bool:
    """Whether a column's ``values`` (strings) can be ``field``: mostly numbers for E, N, H, x,
    y and the σ fields, point kinds for kind, height kinds for height (a typo in a few cells
    does not change the guess: the reader names those lines)."""
    vals = [v.strip() for v in values if v.strip()]
    if field == "kind":
        good = [v.upper() in KINDS for v in vals]
    elif field == "height":
        good = [v.lower() in HEIGHT_KINDS for v in vals]
    elif field in NUMERIC_FIELDS:
        good = [bool(_NUMBER.match(v)) for v in vals]
    else:
        return True
    return 2 * sum(good) >= len(good)


def guess_mapping(columns, fields, rows=None) -> dict:
    """``{field: column}`` matching names case-insensitively, then by :data:`ALIASES`.

    ``rows`` (``[(line, cells)]``, optional): the first data rows; a column whose content
    cannot be the field is not guessed for it (a numeric "Height" column is H, not the height
    kind). Each column feeds at most one field."""
    low = {c.lower(): c for c in columns}
    sample = {c: [r[i] for _, r in (rows or [])[:50] if i < len(r)] for i, c in enumerate(columns)}

    def ok(f, c):
        return rows is None or _fits(f, sample.get(c, []))

    out, used = {}, set()
    for f, _ in fields:  # exact names first: 'height' is a kind, not the H column
        c = low.get(f.lower())
        if c is not None and c not in used and ok(f, c):
            out[f] = c
            used.add(c)
    for f, _ in fields:
        if f in out:
            continue
        for a in ALIASES.get(f, ()):
            c = low.get(a)
            if c is not None and c not in used and ok(f, c):
                out[f], _ = c, used.add(c)
                break
    return out


def shared_columns(mapping: dict) -> list[str]:
    """Problems for every file column that feeds more than one field of ``mapping``."""
    by_col: dict = {}
    for f, c in mapping.items():
        by_col.setdefault(c, []).append(f)
    return [f"column {c!r} feeds both {' and '.join(fs)}: give each field its own column"
            for c, fs in by_col.items() if len(fs) > 1]


_DECIMAL_COMMA = re.compile(r"^[+-]?\d+,\d+$")
_NUMBER = re.compile(r"^[+-]?(\d+([.,]\d*)?|[.,]\d+)([eE][+-]?\d+)?$")
NUMERIC_FIELDS = ("E", "N", "H", "x", "y", "sigma_xy_m", "sigma_h_m", "sigma_px")


def has_decimal_comma(rows, delimiter: str) -> bool:
    """True when the delimiter is not a comma and numbers are written ``123,45``."""
    if delimiter == ",":
        return False
    cells = [c for _, r in rows[:50] for c in r]
    return sum(bool(_DECIMAL_COMMA.match(c)) for c in cells) >= max(1, len(cells) // 10)


def read_mapped(path, what, text, mapping, *, delimiter=",", header=True, constants=None,
                crs=None, to_crs=None, height="ellipsoidal", views=None, decimal_comma=False):
    """Read CSV ``text`` (the content of ``path``) through a column mapping with the io readers.

    Returns ``(records, errors)``: ``records`` a list of GroundPoint (``what == "points"``) or
    Measurement, empty when there is any error; ``errors`` a list of :class:`InputError`, one
    per bad line of ``path`` (at most :data:`MAX_ERRORS`), or one for the whole file.
    """
    table = split_text(text, delimiter, header, path)
    if not table.columns:
        return [], [InputError("no data in the file", path)]
    kw = dict(mapping=mapping, constants=constants, decimal_comma=decimal_comma)
    try:
        if what == "points":
            recs, errors = ground_points_from_table(table, crs=crs, to_crs=to_crs, height=height, **kw)
        else:
            recs, errors = measurements_from_table(table, views, **kw)
    except InputError as exc:
        return [], [exc if exc.file else InputError(exc.problem, path, exc.line)]
    return (recs if not errors else []), errors[:MAX_ERRORS]


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
