"""Ground points and image measurements in the CSV forms of FORMATS.md.

Ground points: header row, columns by name in any order, ``id,E,N,H`` required, optional
``kind`` (GCP/ICP/TIE), ``height`` (orthometric/ellipsoidal), ``sigma_xy_m``, ``sigma_h_m``;
other columns are kept in ``extra``. With ``crs`` the coordinates are converted to the
project CRS by pyproj (E = longitude, N = latitude for a geographic CRS).
Measurements: ``id,view,x,y`` and optional ``sigma_px``.
"""
from __future__ import annotations

import csv
import io
import math
from pathlib import Path

from pyproj import CRS, Transformer
from pyproj.exceptions import CRSError, ProjError

from prismstation.errors import InputError
from prismstation.model.points import HEIGHT_KINDS, KINDS, GroundPoint, Measurement

POINT_COLUMNS = ("id", "E", "N", "H", "kind", "height", "sigma_xy_m", "sigma_h_m")
MEASUREMENT_COLUMNS = ("id", "view", "x", "y", "sigma_px")


def _rows(path, required):
    """Yield ``(line_number, row_dict)`` with keys matched case-insensitively to ``required``."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise InputError("file not found", path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read as UTF-8 text: {exc}", path) from None
    lines = [(i, ln) for i, ln in enumerate(text.splitlines(), 1) if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise InputError("empty file: expected a header row", path, 1)
    try:
        dialect = csv.Sniffer().sniff(lines[0][1], delimiters=",;\t")
    except csv.Error:
        dialect = csv.excel
    reader = csv.reader(io.StringIO("\n".join(ln for _, ln in lines)), dialect)
    try:
        header = [h.strip() for h in next(reader)]
    except csv.Error as exc:
        raise InputError(f"bad header: {exc}", path, lines[0][0]) from None
    lower = {h.lower(): i for i, h in enumerate(header)}
    missing = [c for c in required if c.lower() not in lower]
    if missing:
        raise InputError(f"header lacks column{'s' * (len(missing) > 1)} {', '.join(missing)} "
                         f"(found: {', '.join(header)!r})", path, lines[0][0])
    for (lineno, _), row in zip(lines[1:], reader):
        if len(row) != len(header):
            raise InputError(f"{len(row)} fields where the header has {len(header)}", path, lineno)
        yield lineno, {h: v.strip() for h, v in zip(header, row)}, lower


def _float(row, lower, name, path, lineno, optional=False):
    key = next((h for h in row if h.lower() == name.lower()), None)
    raw = row.get(key, "") if key else ""
    if raw == "":
        if optional:
            return None
        raise InputError(f"column {name} is empty", path, lineno)
    try:
        v = float(raw)
    except ValueError:
        raise InputError(f"column {name}: {raw!r} is not a number", path, lineno) from None
    if not math.isfinite(v):
        raise InputError(f"column {name}: {raw!r} is not a finite number", path, lineno)
    return v


def _get(row, name):
    return next((v for h, v in row.items() if h.lower() == name.lower()), "")


def read_ground_points(path, *, crs=None, to_crs=None, height: str | None = None) -> list[GroundPoint]:
    """Read a ground-points CSV.

    ``crs``/``to_crs``: convert from ``crs`` to ``to_crs`` (both anything pyproj accepts);
    ``height``: the height kind of rows whose ``height`` column is absent or empty
    (default ``ellipsoidal``).
    """
    path = Path(path)
    default_kind = height or "ellipsoidal"
    if default_kind not in HEIGHT_KINDS:
        raise InputError(f"height kind must be one of {', '.join(HEIGHT_KINDS)}, not {height!r}")
    tr = None
    if crs is not None and to_crs is not None:
        try:
            src, dst = CRS.from_user_input(crs), CRS.from_user_input(to_crs)
        except CRSError as exc:
            raise InputError(f"unknown CRS: {exc}") from None
        if src != dst:
            try:
                tr = Transformer.from_crs(src, dst, always_xy=True)
            except ProjError as exc:
                raise InputError(f"cannot convert from {crs} to {to_crs}: {exc}") from None
    out: list[GroundPoint] = []
    seen: dict[str, int] = {}
    for lineno, row, _ in _rows(path, ("id", "E", "N", "H")):
        pid = _get(row, "id")
        if not pid:
            raise InputError("column id is empty", path, lineno)
        if pid in seen:
            raise InputError(f"point {pid!r} appears twice (first on line {seen[pid]})", path, lineno)
        seen[pid] = lineno
        e, n, h = (_float(row, None, c, path, lineno) for c in ("E", "N", "H"))
        kind = (_get(row, "kind") or "GCP").upper()
        if kind not in KINDS:
            raise InputError(f"column kind: {kind!r} is not one of {', '.join(KINDS)}", path, lineno)
        hk = (_get(row, "height") or default_kind).lower()
        if hk not in HEIGHT_KINDS:
            raise InputError(f"column height: {hk!r} is not one of {', '.join(HEIGHT_KINDS)}", path, lineno)
        sxy = _float(row, None, "sigma_xy_m", path, lineno, optional=True)
        sh = _float(row, None, "sigma_h_m", path, lineno, optional=True)
        for name, s in (("sigma_xy_m", sxy), ("sigma_h_m", sh)):
            if s is not None and s < 0:
                raise InputError(f"column {name} must not be negative", path, lineno)
        if tr is not None:
            e2, n2 = tr.transform(e, n)
            if not (math.isfinite(e2) and math.isfinite(n2)):
                raise InputError(f"coordinates ({e}, {n}) cannot be converted from {crs} to {to_crs}", path, lineno)
            e, n = e2, n2
        extra = {k: v for k, v in row.items() if k.lower() not in {c.lower() for c in POINT_COLUMNS}}
        out.append(GroundPoint(pid, e, n, h, hk, kind, sxy, sh, extra))
    return out


def read_measurements(path, views=None) -> list[Measurement]:
    """Read a measurements CSV; ``views`` (optional) the view names the scene has."""
    path = Path(path)
    out: list[Measurement] = []
    seen: dict = {}
    for lineno, row, _ in _rows(path, ("id", "view", "x", "y")):
        pid, view = _get(row, "id"), _get(row, "view")
        if not pid:
            raise InputError("column id is empty", path, lineno)
        if views is not None and view not in views:
            raise InputError(f"view {view!r} is not in the scene (views: {', '.join(views)})", path, lineno)
        if (pid, view) in seen:
            raise InputError(f"point {pid!r} is measured twice in view {view} (first on line "
                             f"{seen[pid, view]})", path, lineno)
        seen[pid, view] = lineno
        x, y = (_float(row, None, c, path, lineno) for c in ("x", "y"))
        s = _float(row, None, "sigma_px", path, lineno, optional=True)
        if s is not None and s <= 0:
            raise InputError("column sigma_px must be positive", path, lineno)
        out.append(Measurement(pid, view, x, y, s))
    return out


def _fmt(v) -> str:
    return "" if v is None or (isinstance(v, float) and not math.isfinite(v)) else repr(float(v)) if isinstance(v, float) else str(v)


def ground_points_csv(points) -> str:
    """The CSV text of ground points (FORMATS.md columns, then extra columns)."""
    extras = sorted({k for p in points for k in p.extra})
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(list(POINT_COLUMNS) + extras)
    for p in points:
        w.writerow([p.id, _fmt(p.E), _fmt(p.N), _fmt(p.H), p.kind, p.height_kind,
                    _fmt(p.sigma_xy_m), _fmt(p.sigma_h_m)] + [p.extra.get(k, "") for k in extras])
    return buf.getvalue()


def measurements_csv(measurements) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(MEASUREMENT_COLUMNS)
    for m in measurements:
        w.writerow([m.id, m.view, _fmt(m.x), _fmt(m.y), _fmt(m.sigma_px)])
    return buf.getvalue()
