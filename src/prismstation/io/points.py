"""Ground points and image measurements in the CSV forms of docs/formats.md.

Ground points: header row, columns by name in any order, ``id,E,N,H`` required, optional
``kind`` (GCP/ICP/TIE), ``height`` (orthometric/ellipsoidal), ``sigma_xy_m``, ``sigma_h_m``;
other columns are kept in ``extra``. With ``crs`` the coordinates are converted to the
project CRS by pyproj (E = longitude, N = latitude for a geographic CRS).
Measurements: ``id,view,x,y`` and optional ``sigma_px``.
Both are read by :mod:`prismstation.io.csvtable` (its delimiter, comment and header rules); the
``*_from_table`` functions return every bad line, the ``read_*`` ones raise on the first.
"""
from __future__ import annotations

import csv
import io
import math

from pyproj import CRS, Transformer
from pyproj.exceptions import CRSError, ProjError

from prismstation.errors import InputError
from prismstation.io.csvtable import Row, Table, raise_errors, read_table, records, text_cell
from prismstation.io.ranges import SIGMA_M, SIGMA_PX, check_image, check_map, check_sigma
from prismstation.model.points import HEIGHT_KINDS, KINDS, GroundPoint, Measurement

POINT_COLUMNS = ("id", "E", "N", "H", "kind", "height", "sigma_xy_m", "sigma_h_m")
MEASUREMENT_COLUMNS = ("id", "view", "x", "y", "sigma_px")


def ground_points_from_table(table: Table, *, mapping=None, constants=None, crs=None,
                             to_crs=None, height: str | None = None, decimal_comma=False):
    """``(points, errors)`` of a ground-points table: a GroundPoint per good row, an
    InputError per bad line (see :func:`read_ground_points` for the arguments; ``mapping``,
    ``constants``, ``decimal_comma`` as in :func:`prismstation.io.csvtable.records`).
    Problems of the whole table (a missing column, an unknown CRS) are raised."""
    default_kind = height or "ellipsoidal"
    if default_kind not in HEIGHT_KINDS:
        raise InputError(f"height kind must be one of {', '.join(HEIGHT_KINDS)}, not {height!r}")
    tr = _transformer(crs, to_crs)
    rows, errors = records(table, POINT_COLUMNS, ("id", "E", "N", "H"), mapping=mapping,
                           constants=constants, decimal_comma=decimal_comma)
    out: list[GroundPoint] = []
    seen: dict[str, int] = {}
    for row in rows:
        try:
            out.append(_ground_point(row, seen, default_kind, tr, crs, to_crs))
        except InputError as exc:
            errors.append(exc)
    errors.sort(key=lambda e: e.line or 0)
    return out, errors


def _transformer(crs, to_crs):
    if crs is None or to_crs is None:
        return None
    try:
        src, dst = CRS.from_user_input(crs), CRS.from_user_input(to_crs)
    except CRSError as exc:
        raise InputError(f"unknown CRS: {exc}") from None
    if src == dst:
        return None
    try:
        return Transformer.from_crs(src, dst, always_xy=True)
    except ProjError as exc:
        raise InputError(f"cannot convert from {crs} to {to_crs}: {exc}") from None


def _ground_point(row: Row, seen, default_kind, tr, crs, to_crs) -> GroundPoint:
    pid = row.text("id")
    if not pid:
        raise row.error("column id is empty")
    if pid in seen:
        raise row.error(f"point {pid!r} appears twice (first on line {seen[pid]})")
    seen[pid] = row.line
    e, n, h = (row.number(c) for c in ("E", "N", "H"))
    kind = (row.text("kind") or "GCP").upper()
    if kind not in KINDS:
        raise row.error(f"column kind: {kind!r} is not one of {', '.join(KINDS)}")
    hk = (row.text("height") or default_kind).lower()
    if hk not in HEIGHT_KINDS:
        raise row.error(f"column height: {hk!r} is not one of {', '.join(HEIGHT_KINDS)}")
    sxy, sh = row.number("sigma_xy_m", optional=True), row.number("sigma_h_m", optional=True)
    for name, s in (("sigma_xy_m", sxy), ("sigma_h_m", sh)):
        if s is not None and s < 0:
            raise row.error(f"column {name} must not be negative")
    if tr is not None:
        e2, n2 = tr.transform(e, n)
        if not (math.isfinite(e2) and math.isfinite(n2)):
            raise row.error(f"coordinates ({e}, {n}) cannot be converted from {crs} to {to_crs}")
        e, n = e2, n2
    why = check_map(e, n, h) or check_sigma("sigma_xy_m", sxy, SIGMA_M, "m") or check_sigma("sigma_h_m", sh, SIGMA_M, "m")
    if why:
        raise row.error(why)
    extra = {k: v for k, v in row.values.items() if k not in POINT_COLUMNS}
    return GroundPoint(pid, e, n, h, hk, kind, sxy, sh, extra)


def read_ground_points(path, *, crs=None, to_crs=None, height: str | None = None) -> list[GroundPoint]:
    """Read a ground-points CSV; raises an InputError naming the first bad line (and how many
    more there are).

    ``crs``/``to_crs``: convert from ``crs`` to ``to_crs`` (both anything pyproj accepts);
    ``height``: the height kind of rows whose ``height`` column is absent or empty
    (default ``ellipsoidal``).
    """
    points, errors = ground_points_from_table(read_table(path), crs=crs, to_crs=to_crs,
                                              height=height)
    raise_errors(errors)
    return points


def measurements_from_table(table: Table, views=None, *, mapping=None, constants=None,
                            decimal_comma=False):
    """``(measurements, errors)`` of a measurements table (see :func:`ground_points_from_table`)."""
    rows, errors = records(table, MEASUREMENT_COLUMNS, ("id", "view", "x", "y"), mapping=mapping,
                           constants=constants, decimal_comma=decimal_comma)
    out: list[Measurement] = []
    seen: dict = {}
    for row in rows:
        try:
            out.append(_measurement(row, seen, views))
        except InputError as exc:
            errors.append(exc)
    errors.sort(key=lambda e: e.line or 0)
    return out, errors


def _measurement(row: Row, seen, views) -> Measurement:
    pid, view = row.text("id"), row.text("view")
    if not pid:
        raise row.error("column id is empty")
    if views is not None and view not in views:
        raise row.error(f"view {view!r} is not in the scene (views: {', '.join(views)})")
    if (pid, view) in seen:
        raise row.error(f"point {pid!r} is measured twice in view {view} (first on line "
                        f"{seen[pid, view]})")
    seen[pid, view] = row.line
    x, y = row.number("x"), row.number("y")
    s = row.number("sigma_px", optional=True)
    if s is not None and s <= 0:
        raise row.error("column sigma_px must be positive")
    why = check_image(x, y) or check_sigma("sigma_px", s, SIGMA_PX, "px")
    if why:
        raise row.error(why)
    return Measurement(pid, view, x, y, s)


def read_measurements(path, views=None) -> list[Measurement]:
    """Read a measurements CSV; ``views`` (optional) the view names the scene has. Raises an
    InputError naming the first bad line (and how many more there are)."""
    meas, errors = measurements_from_table(read_table(path), views)
    raise_errors(errors)
    return meas


def _fmt(v) -> str:
    return "" if v is None or (isinstance(v, float) and not math.isfinite(v)) else repr(float(v)) if isinstance(v, float) else str(v)


def ground_points_csv(points) -> str:
    """The CSV text of ground points (docs/formats.md columns, then extra columns)."""
    extras = sorted({k for p in points for k in p.extra})
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(list(POINT_COLUMNS) + [text_cell(k) for k in extras])
    for p in points:
        w.writerow([text_cell(p.id), _fmt(p.E), _fmt(p.N), _fmt(p.H), p.kind, p.height_kind,
                    _fmt(p.sigma_xy_m), _fmt(p.sigma_h_m)] + [text_cell(p.extra.get(k, "")) for k in extras])
    return buf.getvalue()


def measurements_csv(measurements) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(MEASUREMENT_COLUMNS)
    for m in measurements:
        w.writerow([text_cell(m.id), text_cell(m.view), _fmt(m.x), _fmt(m.y), _fmt(m.sigma_px)])
    return buf.getvalue()
