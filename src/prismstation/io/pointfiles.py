"""Other tools' ground-control files: read, write, convert (FORMATS.md ``prismstation points``).

Formats (detected from extension and content, see :func:`detect_format`):

``qgis``  QGIS Georeferencer ``.points``: optional first line ``#CRS: <WKT>``, a header
          ``mapX,mapY,sourceX,sourceY,enable,dX,dY,residual`` (older QGIS: ``pixelX,pixelY``),
          one row per point. ``sourceY`` is negative downwards (QGIS shows the image with y up),
          origin at the top-left corner of the image: ``x = sourceX``, ``y = -sourceY``.
          ``enable = 0`` points become ``ICP`` (kept, not used in a fit) and are written back as 0.
          QGIS has no point ids nor heights: this writer appends ``id,H`` columns after the eight
          QGIS ones (QGIS reads the first columns by position and ignores the rest).
``odm``   OpenDroneMap ``gcp_list.txt``: first line a CRS (``EPSG:xxxx``, a proj4 string, or
          ``WGS84 UTM 17N``), ``#`` comments and blank lines skipped, rows
          ``geo_x geo_y geo_z im_x im_y image_name [gcp_name] [extra...]`` separated by blanks or
          tabs. ``geo_z`` is in the CRS's unit (US-feet grids give feet); OpenSfM puts pixel centres
          at integers, so ``x = im_x + 0.5``. Rows with the same name (or, when unnamed, the same
          coordinates) are one point measured in several images.
``asp``   Ames Stereo Pipeline ``.gcp``: ``id lat lon height sigma_lat sigma_lon sigma_h`` then per
          image ``name col row sigma_col sigma_row`` (commas and/or blanks); ``#`` comments; datum
          WGS84 (``# WKT:`` comment lines name another). Heights are above the datum (ellipsoidal).
          Vision Workbench puts pixel centres at integers, so ``x = col + 0.5``.
``csv``   the ground-point CSV of FORMATS.md (``id,E,N,H[,kind,height,sigma_xy_m,sigma_h_m]``);
          it has no CRS and no image measurements.

Conventions of the returned objects: ``E``, ``N`` in the units of ``PointFile.crs`` (x = easting
or longitude, y = northing or latitude; pyproj ``always_xy``); ``H`` always in metres (a feet grid's
heights are converted on reading and back on writing); measurements ``(x, y)`` in pixels with origin
at the top-left corner of the top-left pixel (MODEL.md §1), ``view`` = the image name of the file.
"""
from __future__ import annotations

import csv
import io
import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

from pyproj import CRS, Transformer
from pyproj.exceptions import CRSError, ProjError

from prismstation.errors import InputError
from prismstation.model.points import HEIGHT_KINDS, GroundPoint, Measurement

FORMATS = ("csv", "qgis", "odm", "asp")
_QGIS_COLUMNS = ["mapX", "mapY", "sourceX", "sourceY", "enable", "dX", "dY", "residual"]
_CSV_COLUMNS = ["id", "E", "N", "H", "kind", "height", "sigma_xy_m", "sigma_h_m"]
_UTM_WORDS = re.compile(r"^\s*WGS\s*84\s+UTM\s+(\d{1,2})\s*([NS])\s*$", re.IGNORECASE)


@dataclass(frozen=True)
class PointFile:
    """Ground points and image measurements read from (or to write to) one file.

    Attributes
    ----------
    points : tuple of GroundPoint
        ``E``, ``N`` in units of ``crs``; ``H`` in metres.
    measurements : tuple of Measurement
        Pixel coordinates, MODEL.md §1 convention; ``view`` is the image name.
    crs : str or None
        The CRS as the file states it (``"EPSG:32617"``, a proj4 string, WKT), or ``None``.
    format : str
        One of ``FORMATS``.
    header : str or None
        The file's own CRS line, written back unchanged when the CRS was not changed.
    """

    points: tuple = ()
    measurements: tuple = ()
    crs: str | None = None
    format: str = "csv"
    header: str | None = field(default=None, compare=False)



def _fmt(value: float) -> str:
    """Shortest text that reads back to the same float."""
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def _fmt_px(value: float) -> str:
    return _fmt(round(float(value), 9))


def _float(text: str, what: str, path, line: int) -> float:
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"{what} {text!r} is not a number", path, line) from None
    if not math.isfinite(value):
        raise InputError(f"{what} {text!r} is not a finite number", path, line)
    return value


def parse_crs(text: str, path=None, line: int | None = None) -> CRS:
    """A pyproj CRS from an ODM / QGIS / user CRS text (``WGS84 UTM 17N`` included)."""
    text = text.strip()
    m = _UTM_WORDS.match(text)
    if m:
        zone, hemi = int(m.group(1)), m.group(2).upper()
        if not 1 <= zone <= 60:
            raise InputError(f"UTM zone {zone} is not between 1 and 60", path, line)
        return CRS.from_epsg((32600 if hemi == "N" else 32700) + zone)
    try:
        return CRS.from_user_input(text)
    except CRSError as exc:
        raise InputError(f"unknown coordinate system {text!r} ({exc})", path, line) from None


def metres_per_unit(crs_text: str | None) -> float:
    """Metres per unit of the first axis of ``crs_text`` (1 for geographic or unknown CRSs)."""
    if not crs_text:
        return 1.0
    crs = parse_crs(crs_text)
    if crs.is_geographic:
        return 1.0
    factor = crs.axis_info[0].unit_conversion_factor if crs.axis_info else 1.0
    return float(factor or 1.0)


def _lines(path: Path):
    try:
        text = Path(path).read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise InputError("not a text file (not UTF-8)", path) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", path) from None
    return text.splitlines()



def detect_format(path) -> str:
    """The format of ``path`` (one of ``FORMATS``) from its extension, then its content."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".points":
        return "qgis"
    if suffix == ".gcp":
        return "asp"
    if suffix == ".csv":
        return "csv"
    lines = [ln for ln in _lines(path) if ln.strip()]
    if not lines:
        raise InputError("empty file", path)
    first = lines[0].strip()
    if first.upper().startswith("#CRS") or "mapX" in first:
        return "qgis"
    content = [ln for ln in lines if not ln.lstrip().startswith("#")]
    if content and re.match(r"^\s*id\s*,", content[0], re.IGNORECASE):
        return "csv"
    if content and content[0].strip().upper().startswith(("EPSG:", "+PROJ", "WGS84", "WGS 84")):
        return "odm"
    if content and len(re.split(r"[,\s]+", content[0].strip())) >= 12:
        return "asp"
    raise InputError("unknown point-file format (expected QGIS .points, ODM gcp_list.txt, "
                     "ASP .gcp or ground-point CSV)", path, 1)


def read_point_file(path, fmt: str | None = None, *, height: str = "ellipsoidal",
                    view: str = "N") -> PointFile:
    """Read any supported point file.

    Parameters
    ----------
    path : path-like
    fmt : str, optional
        Force a format (``FORMATS``); detected when omitted.
    height : {"ellipsoidal", "orthometric"}
        Height kind given to points of files that do not say (QGIS, ODM, CSV rows without a
        ``height`` column). ASP heights are always ellipsoidal (above the datum).
    view : str
        View name for the measurements of a QGIS file (it names no image).
    """
    if height not in HEIGHT_KINDS:
        raise InputError(f"height kind {height!r} is not one of {HEIGHT_KINDS}")
    fmt = fmt or detect_format(path)
    readers = {"qgis": lambda: read_qgis_points(path, height=height, view=view),
               "odm": lambda: read_odm_gcp(path, height=height),
               "asp": lambda: read_asp_gcp(path),
               "csv": lambda: read_ground_csv(path, height=height)}
    if fmt not in readers:
        raise InputError(f"unknown point-file format {fmt!r} (one of {', '.join(FORMATS)})", path)
    return readers[fmt]()


def write_point_file(pf: PointFile, path, fmt: str | None = None, *, view: str | None = None) -> None:
    """Write ``pf`` in ``fmt`` (from the extension of ``path`` when omitted; ``.txt`` is ODM)."""
    path = Path(path)
    if fmt is None:
        fmt = {".points": "qgis", ".gcp": "asp", ".csv": "csv", ".txt": "odm"}.get(
            path.suffix.lower())
        if fmt is None:
            raise InputError("cannot tell the output format from the extension "
                             "(.points, .gcp, .csv or .txt)", path)
    writers = {"qgis": lambda: format_qgis_points(pf, view=view),
               "odm": lambda: format_odm_gcp(pf),
               "asp": lambda: format_asp_gcp(pf),
               "csv": lambda: format_ground_csv(pf)}
    if fmt not in writers:
        raise InputError(f"unknown point-file format {fmt!r}", path)
    text = writers[fmt]()
    try:
        path.write_text(text, encoding="utf-8", newline="")
    except OSError as exc:
        raise InputError(f"cannot write: {exc.strerror or exc}", path) from None



def read_qgis_points(path, *, height: str = "ellipsoidal", view: str = "N") -> PointFile:
    """Read a QGIS Georeferencer ``.points`` file (see the module docstring)."""
    lines = _lines(path)
    crs = header = None
    start = 0
    while start < len(lines) and not lines[start].strip():
        start += 1
    if start < len(lines) and lines[start].lstrip().upper().startswith("#CRS"):
        header = lines[start].strip()
        crs_text = header.split(":", 1)[1].strip() if ":" in header else ""
        if crs_text:
            parse_crs(crs_text, path, start + 1)
            crs = crs_text
        start += 1
    if start >= len(lines):
        raise InputError("no header row (mapX,mapY,sourceX,sourceY,...)", path)
    names = [c.strip() for c in lines[start].split(",")]
    lower = [n.lower() for n in names]

    def col(*options):
        for o in options:
            if o.lower() in lower:
                return lower.index(o.lower())
        return None

    ix = {"mapx": col("mapX"), "mapy": col("mapY"), "sx": col("sourceX", "pixelX"),
          "sy": col("sourceY", "pixelY"), "enable": col("enable"), "id": col("id"), "h": col("H")}
    missing = [k for k in ("mapx", "mapy", "sx", "sy") if ix[k] is None]
    if missing:
        raise InputError("header lacks mapX, mapY, sourceX/pixelX or sourceY/pixelY", path,
                         start + 1)
    points, meas = [], []
    for no, raw in enumerate(lines[start + 1:], start=start + 2):
        if not raw.strip() or raw.lstrip().startswith("#"):
            continue
        cells = [c.strip() for c in raw.split(",")]
        if len(cells) < 4 or any(ix[k] is not None and ix[k] >= len(cells)
                                 for k in ("mapx", "mapy", "sx", "sy")):
            raise InputError(f"expected at least {len(names)} comma-separated values, "
                             f"found {len(cells)}", path, no)
        E = _float(cells[ix["mapx"]], "mapX", path, no)
        N = _float(cells[ix["mapy"]], "mapY", path, no)
        sx = _float(cells[ix["sx"]], "sourceX", path, no)
        sy = _float(cells[ix["sy"]], "sourceY", path, no)
        enabled = True
        if ix["enable"] is not None and ix["enable"] < len(cells) and cells[ix["enable"]]:
            flag = cells[ix["enable"]]
            if flag not in ("0", "1"):
                raise InputError(f"enable must be 0 or 1, not {flag!r}", path, no)
            enabled = flag == "1"
        pid = (cells[ix["id"]] if ix["id"] is not None and ix["id"] < len(cells)
               and cells[ix["id"]] else f"P{len(points) + 1}")
        H = (_float(cells[ix["h"]], "H", path, no) if ix["h"] is not None
             and ix["h"] < len(cells) and cells[ix["h"]] else 0.0)
        points.append(GroundPoint(pid, E, N, H, height_kind=height,
                                  kind="GCP" if enabled else "ICP"))
        meas.append(Measurement(pid, view, sx, -sy))
    return PointFile(tuple(points), tuple(meas), crs, "qgis", header)


def format_qgis_points(pf: PointFile, *, view: str | None = None) -> str:
    """Text of a QGIS ``.points`` file holding the measurements of one view."""
    views = sorted({m.view for m in pf.measurements})
    if view is None:
        if len(views) > 1:
            raise InputError(f"a QGIS .points file holds one image; choose one of {views}")
        view = views[0] if views else None
    by_id = {m.id: m for m in pf.measurements if m.view == view}
    out = io.StringIO()
    if pf.crs:
        if pf.header and pf.header.split(":", 1)[-1].strip() == pf.crs:
            out.write(pf.header + "\n")
        else:
            out.write("#CRS: " + parse_crs(pf.crs).to_wkt() + "\n")
    out.write(",".join(_QGIS_COLUMNS + ["id", "H"]) + "\n")
    for p in pf.points:
        m = by_id.get(p.id)
        if m is None:
            continue
        enable = "0" if p.kind == "ICP" else "1"
        sy = -m.y if m.y != 0 else 0.0
        out.write(",".join([_fmt(p.E), _fmt(p.N), _fmt_px(m.x), _fmt_px(sy), enable,
                            "0", "0", "0", p.id, _fmt(p.H)]) + "\n")
    return out.getvalue()



def read_odm_gcp(path, *, height: str = "ellipsoidal") -> PointFile:
    """Read an OpenDroneMap ``gcp_list.txt`` (see the module docstring)."""
    lines = _lines(path)
    first = next((i for i, ln in enumerate(lines)
                  if ln.strip() and not ln.lstrip().startswith("#")), None)
    if first is None:
        raise InputError("empty file", path)
    header = lines[first].strip()
    parse_crs(header, path, first + 1)
    z_to_m = metres_per_unit(header)
    points: dict[str, GroundPoint] = {}
    by_coords: dict[tuple, str] = {}
    meas = []
    for no, raw in enumerate(lines[first + 1:], start=first + 2):
        text = raw.strip()
        if not text or text.startswith("#"):
            continue
        cells = text.split()
        if len(cells) < 6:
            raise InputError("expected geo_x geo_y geo_z im_x im_y image_name [gcp_name], "
                             f"found {len(cells)} values", path, no)
        gx, gy, gz, ix, iy = (_float(c, w, path, no) for c, w in
                              zip(cells[:5], ("geo_x", "geo_y", "geo_z", "im_x", "im_y")))
        image = cells[5]
        key = (gx, gy, gz)
        name = cells[6] if len(cells) > 6 else by_coords.get(key, f"gcp{len(points) + 1}")
        extra = {"odm_extra": " ".join(cells[7:])} if len(cells) > 7 else {}
        point = GroundPoint(name, gx, gy, gz * z_to_m, height_kind=height, extra=extra)
        if name in points:
            old = points[name]
            if (old.E, old.N, old.H) != (point.E, point.N, point.H):
                raise InputError(f"point {name!r} has other coordinates than on an earlier "
                                 "row", path, no)
        else:
            points[name] = point
            by_coords.setdefault(key, name)
        meas.append(Measurement(name, image, ix + 0.5, iy + 0.5))
    return PointFile(tuple(points.values()), tuple(meas), header, "odm", header)


def format_odm_gcp(pf: PointFile) -> str:
    """Text of an ODM ``gcp_list.txt``: one row per measurement, the point's name last."""
    if not pf.crs:
        raise InputError("an ODM gcp_list.txt needs a coordinate system (give --to-crs)")
    if not pf.measurements:
        raise InputError("an ODM gcp_list.txt lists image measurements; there are none")
    crs_line = pf.header if pf.header and pf.header.strip() == pf.crs.strip() else pf.crs
    if "\n" in crs_line or crs_line.lstrip().startswith(("PROJCRS", "GEOGCRS", "PROJCS")):
        crs_obj = parse_crs(crs_line)
        epsg = crs_obj.to_epsg()
        crs_line = f"EPSG:{epsg}" if epsg else crs_obj.to_proj4()
    z_to_m = metres_per_unit(crs_line)
    by_id = {p.id: p for p in pf.points}
    out = io.StringIO()
    out.write(crs_line.strip() + "\n")
    for m in pf.measurements:
        p = by_id.get(m.id)
        if p is None:
            continue
        row = [_fmt(p.E), _fmt(p.N), _fmt(p.H / z_to_m), _fmt_px(m.x - 0.5), _fmt_px(m.y - 0.5),
               m.view, p.id]
        if p.extra.get("odm_extra"):
            row.append(p.extra["odm_extra"])
        out.write(" ".join(row) + "\n")
    return out.getvalue()



def read_asp_gcp(path) -> PointFile:
    """Read an Ames Stereo Pipeline ``.gcp`` file (see the module docstring)."""
    lines = _lines(path)
    crs = "EPSG:4326"
    header = None
    points, meas = [], []
    seen = set()
    for no, raw in enumerate(lines, start=1):
        text = raw.strip()
        if not text:
            continue
        if text.startswith("#"):
            m = re.match(r"#\s*WKT:\s*(.+)$", text)
            if m:
                header = text
                crs = m.group(1).strip()
                parse_crs(crs, path, no)
            continue
        cells = [c for c in re.split(r"[,\s]+", text) if c]
        if len(cells) < 12 or (len(cells) - 7) % 5:
            raise InputError("expected id lat lon height 3 sigmas, then name col row "
                             f"2 sigmas per image; found {len(cells)} values", path, no)
        pid = cells[0]
        if pid in seen:
            raise InputError(f"point id {pid!r} appears twice", path, no)
        seen.add(pid)
        lat, lon, h, s_lat, s_lon, s_h = (_float(c, w, path, no) for c, w in zip(
            cells[1:7], ("latitude", "longitude", "height", "sigma", "sigma", "sigma")))
        for what, v, lim in (("latitude", lat, (-90, 90)), ("longitude", lon, (-180, 360))):
            if not lim[0] <= v <= lim[1]:
                raise InputError(f"{what} {v} is outside [{lim[0]}, {lim[1]}]", path, no)
        points.append(GroundPoint(pid, lon, lat, h, height_kind="ellipsoidal",
                                  sigma_xy_m=max(s_lat, s_lon), sigma_h_m=s_h,
                                  extra={"sigma_lat": s_lat, "sigma_lon": s_lon}))
        for k in range(7, len(cells), 5):
            name = cells[k]
            col, row, s_c, s_r = (_float(c, w, path, no) for c, w in zip(
                cells[k + 1:k + 5], ("column", "row", "sigma", "sigma")))
            meas.append(Measurement(pid, name, col + 0.5, row + 0.5, sigma_px=max(s_c, s_r)))
    if not points:
        raise InputError("no points", path)
    return PointFile(tuple(points), tuple(meas), crs, "asp", header)


def format_asp_gcp(pf: PointFile) -> str:
    """Text of an ASP ``.gcp`` file (points must be geographic: lon, lat in degrees)."""
    if pf.crs and not parse_crs(pf.crs).is_geographic:
        pf = convert_point_file(pf, "EPSG:4326")
    out = io.StringIO()
    if pf.header and pf.crs and pf.header.endswith(pf.crs):
        out.write(pf.header + "\n")
    by_point: dict[str, list] = {}
    for m in pf.measurements:
        by_point.setdefault(m.id, []).append(m)
    for p in pf.points:
        s_lat = p.extra.get("sigma_lat", p.sigma_xy_m if p.sigma_xy_m is not None else 1.0)
        s_lon = p.extra.get("sigma_lon", p.sigma_xy_m if p.sigma_xy_m is not None else 1.0)
        s_h = p.sigma_h_m if p.sigma_h_m is not None else 1.0
        row = [p.id, _fmt(p.N), _fmt(p.E), _fmt(p.H), _fmt(s_lat), _fmt(s_lon), _fmt(s_h)]
        for m in by_point.get(p.id, []):
            s = m.sigma_px if m.sigma_px is not None else 1.0
            row += [m.view, _fmt_px(m.x - 0.5), _fmt_px(m.y - 0.5), _fmt(s), _fmt(s)]
        if len(row) > 7:  # ASP needs at least one image per point
            out.write(", ".join(row) + "\n")
    return out.getvalue()



def read_ground_csv(path, *, height: str = "ellipsoidal") -> PointFile:
    """Read the ground-point CSV of FORMATS.md (extra columns kept in ``extra``)."""
    lines = _lines(path)
    rows = list(csv.reader(lines))
    start = next((i for i, r in enumerate(rows) if r and not r[0].lstrip().startswith("#")), None)
    if start is None:
        raise InputError("no header row", path)
    names = [c.strip() for c in rows[start]]
    for need in ("id", "E", "N", "H"):
        if need not in names:
            raise InputError(f"header lacks column {need!r}", path, start + 1)
    points, seen = [], set()
    for no, cells in enumerate(rows[start + 1:], start=start + 2):
        if not cells or not "".join(cells).strip() or cells[0].lstrip().startswith("#"):
            continue
        if len(cells) != len(names):
            raise InputError(f"expected {len(names)} values, found {len(cells)}", path, no)
        rec = dict(zip(names, (c.strip() for c in cells)))
        pid = rec["id"]
        if not pid:
            raise InputError("empty id", path, no)
        if pid in seen:
            raise InputError(f"point id {pid!r} appears twice", path, no)
        seen.add(pid)
        kind = rec.get("kind") or "GCP"
        if kind not in ("GCP", "ICP"):
            raise InputError(f"kind must be GCP or ICP, not {kind!r}", path, no)
        hk = rec.get("height") or height
        if hk not in HEIGHT_KINDS:
            raise InputError(f"height must be one of {HEIGHT_KINDS}, not {hk!r}", path, no)
        sig = {k: (_float(rec[k], k, path, no) if rec.get(k) else None)
               for k in ("sigma_xy_m", "sigma_h_m")}
        extra = {k: v for k, v in rec.items() if k not in _CSV_COLUMNS}
        points.append(GroundPoint(pid, _float(rec["E"], "E", path, no),
                                  _float(rec["N"], "N", path, no), _float(rec["H"], "H", path, no),
                                  height_kind=hk, kind=kind, extra=extra, **sig))
    return PointFile(tuple(points), (), None, "csv", None)


def format_ground_csv(pf: PointFile) -> str:
    """Text of the FORMATS.md ground-point CSV (extra columns of the points appended)."""
    extras = []
    for p in pf.points:
        extras += [k for k in p.extra if k not in extras and k not in _CSV_COLUMNS
                   and k not in ("sigma_lat", "sigma_lon", "odm_extra")]
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(_CSV_COLUMNS + extras)
    for p in pf.points:
        w.writerow([p.id, _fmt(p.E), _fmt(p.N), _fmt(p.H), p.kind, p.height_kind,
                    "" if p.sigma_xy_m is None else _fmt(p.sigma_xy_m),
                    "" if p.sigma_h_m is None else _fmt(p.sigma_h_m)]
                   + [str(p.extra.get(k, "")) for k in extras])
    return out.getvalue()


def convert_point_file(pf: PointFile, to_crs: str) -> PointFile:
    """Ground points transformed horizontally to ``to_crs`` with pyproj (``always_xy``).

    Heights are kept (metres, same kind); a vertical datum change is not made here.
    """
    if not pf.crs:
        raise InputError("the input names no coordinate system; give it with --crs")
    src, dst = parse_crs(pf.crs), parse_crs(to_crs)
    try:
        tr = Transformer.from_crs(src, dst, always_xy=True)
    except ProjError as exc:
        raise InputError(f"cannot convert from {pf.crs[:60]!r} to {to_crs!r}: {exc}") from None
    pts = []
    for p in pf.points:
        e, n = tr.transform(p.E, p.N)
        if not (math.isfinite(e) and math.isfinite(n)):
            raise InputError(f"point {p.id!r} cannot be transformed to {to_crs}")
        pts.append(replace(p, E=float(e), N=float(n)))
    return replace(pf, points=tuple(pts), crs=to_crs, header=None)
