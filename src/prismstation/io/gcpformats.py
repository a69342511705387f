"""QGIS ``.points``, OpenDroneMap ``gcp_list.txt`` and Ames Stereo Pipeline ``.gcp`` files:
read and write (formats and conventions in :mod:`prismstation.io.pointfiles`).

Lines are split by :mod:`prismstation.io.csvtable` (blank lines and ``#`` comments skipped);
every bad line is collected and the first raised with the count of the others.
"""
from __future__ import annotations

import csv
import io
import re

from prismstation.errors import InputError
from prismstation.io.csvtable import raise_errors, read_text, split_text, text_cell
from prismstation.io.georef import (PointFile, convert_point_file, latitude_first, lonlat_order,
                                    metres_per_unit, parse_crs)
from prismstation.model.points import GroundPoint, Measurement

QGIS_COLUMNS = ["mapX", "mapY", "sourceX", "sourceY", "enable", "dX", "dY", "residual"]


def fmt(value: float) -> str:
    """Shortest text that reads back to the same float."""
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def _fmt_px(value: float) -> str:
    return fmt(round(float(value), 9))


def _float(text: str, what: str, path, line: int) -> float:
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"{what} {text!r} is not a number", path, line) from None
    if not value - value == 0:  # inf or nan
        raise InputError(f"{what} {text!r} is not a finite number", path, line)
    return value


def read_qgis_points(path, *, height: str = "ellipsoidal", view: str = "N") -> PointFile:
    """Read a QGIS Georeferencer ``.points`` file (see :mod:`prismstation.io.pointfiles`)."""
    text = read_text(path)
    lines = text.splitlines()
    crs = header = None
    first = next((i for i, ln in enumerate(lines) if ln.strip()), None)
    if first is not None and lines[first].lstrip().upper().startswith("#CRS"):
        header = lines[first].strip()
        crs_text = header.split(":", 1)[1].strip() if ":" in header else ""
        if crs_text:
            parse_crs(crs_text, path, first + 1)
            crs = crs_text
    table = split_text(text, ",", True, path)
    if not table.columns:
        raise InputError("no header row (mapX,mapY,sourceX,sourceY,...)", path)
    lower = [n.lower() for n in table.columns]

    def col(*options):
        return next((lower.index(o.lower()) for o in options if o.lower() in lower), None)

    ix = {"mapx": col("mapX"), "mapy": col("mapY"), "sx": col("sourceX", "pixelX"),
          "sy": col("sourceY", "pixelY"), "enable": col("enable"), "id": col("id"), "h": col("H")}
    if any(ix[k] is None for k in ("mapx", "mapy", "sx", "sy")):
        raise InputError("header lacks mapX, mapY, sourceX/pixelX or sourceY/pixelY", path,
                         table.header_line)
    points, meas, lines_of, errors = [], [], [], []
    for no, cells in table.rows:
        try:
            if max(ix[k] for k in ("mapx", "mapy", "sx", "sy")) >= len(cells):
                raise InputError(f"expected at least {len(table.columns)} comma-separated values, "
                                 f"found {len(cells)}", path, no)
            E, N, sx, sy = (_float(cells[ix[k]], w, path, no) for k, w in (
                ("mapx", "mapX"), ("mapy", "mapY"), ("sx", "sourceX"), ("sy", "sourceY")))

            def cell(k):
                return cells[ix[k]] if ix[k] is not None and ix[k] < len(cells) else ""

            flag = cell("enable")
            if flag not in ("", "0", "1"):
                raise InputError(f"enable must be 0 or 1, not {flag!r}", path, no)
            pid = cell("id") or f"P{len(points) + 1}"
            H = _float(cell("h"), "H", path, no) if cell("h") else 0.0
        except InputError as exc:
            errors.append(exc)
            continue
        points.append(GroundPoint(pid, E, N, H, height_kind=height,
                                  kind="ICP" if flag == "0" else "GCP"))
        lines_of.append(no)
        meas.append(Measurement(pid, view, sx, -sy))
    raise_errors(errors)
    points, warnings = lonlat_order(points, lines_of, path, crs, ("mapX", "mapY"))
    return PointFile(tuple(points), tuple(meas), crs, "qgis", header, tuple(warnings))


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
    out.write(",".join(QGIS_COLUMNS + ["id", "H"]) + "\n")
    rows = csv.writer(out, lineterminator="\n")
    for p in pf.points:
        m = by_id.get(p.id)
        if m is None:
            continue
        enable = "0" if p.kind == "ICP" else "1"
        sy = -m.y if m.y != 0 else 0.0
        rows.writerow([fmt(p.E), fmt(p.N), _fmt_px(m.x), _fmt_px(sy), enable, "0", "0", "0",
                       text_cell(p.id), fmt(p.H)])
    return out.getvalue()



def read_odm_gcp(path, *, height: str = "ellipsoidal") -> PointFile:
    """Read an OpenDroneMap ``gcp_list.txt`` (see :mod:`prismstation.io.pointfiles`)."""
    text = read_text(path)
    lines = text.splitlines()
    first = next((i for i, ln in enumerate(lines)
                  if ln.strip() and not ln.lstrip().startswith("#")), None)
    if first is None:
        raise InputError("empty file", path)
    header = lines[first].strip()
    parse_crs(header, path, first + 1)
    z_to_m = metres_per_unit(header)
    swap = latitude_first(header)
    points: dict[str, GroundPoint] = {}
    lines_of: dict[str, int] = {}
    by_coords: dict[tuple, str] = {}
    meas, errors = [], []
    for no, cells in split_text(text, " ", False, path).rows:
        if no == first + 1:
            continue
        try:
            if len(cells) < 6:
                raise InputError("expected geo_x geo_y geo_z im_x im_y image_name [gcp_name], "
                                 f"found {len(cells)} values", path, no)
            gx, gy, gz, ix, iy = (_float(c, w, path, no) for c, w in
                                  zip(cells[:5], ("geo_x", "geo_y", "geo_z", "im_x", "im_y")))
            key = (gx, gy, gz)
            name = cells[6] if len(cells) > 6 else by_coords.get(key, f"gcp{len(points) + 1}")
            extra = {"odm_extra": " ".join(cells[7:])} if len(cells) > 7 else {}
            e, n = (gy, gx) if swap else (gx, gy)
            point = GroundPoint(name, e, n, gz * z_to_m, height_kind=height, extra=extra)
            old = points.get(name)
            if old is not None and (old.E, old.N, old.H) != (point.E, point.N, point.H):
                raise InputError(f"point {name!r} has other coordinates than on an earlier row",
                                 path, no)
        except InputError as exc:
            errors.append(exc)
            continue
        if old is None:
            points[name], lines_of[name] = point, no
            by_coords.setdefault(key, name)
        meas.append(Measurement(name, cells[5], ix + 0.5, iy + 0.5))
    raise_errors(errors)
    names = ("geo_y", "geo_x") if swap else ("geo_x", "geo_y")
    pts, warnings = lonlat_order(list(points.values()), list(lines_of.values()), path, header, names)
    return PointFile(tuple(pts), tuple(meas), header, "odm", header, tuple(warnings))


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
        geo = [p.N, p.E] if latitude_first(crs_line) else [p.E, p.N]
        row = [fmt(geo[0]), fmt(geo[1]), fmt(p.H / z_to_m), _fmt_px(m.x - 0.5), _fmt_px(m.y - 0.5),
               m.view, p.id]
        if p.extra.get("odm_extra"):
            row.append(p.extra["odm_extra"])
        out.write(" ".join(row) + "\n")
    return out.getvalue()



def read_asp_gcp(path) -> PointFile:
    """Read an Ames Stereo Pipeline ``.gcp`` file (see :mod:`prismstation.io.pointfiles`)."""
    table = split_text(read_text(path), None, False, path)
    crs, header = "EPSG:4326", None
    for no, text in table.comments:
        m = re.match(r"#\s*WKT:\s*(.+)$", text)
        if m:
            header, crs = text, m.group(1).strip()
            parse_crs(crs, path, no)
    points, meas, lines_of, errors = [], [], [], []
    seen = set()
    for no, cells in table.rows:
        cells = [c for c in cells if c]
        try:
            if len(cells) < 12 or (len(cells) - 7) % 5:
                raise InputError("expected id lat lon height 3 sigmas, then name col row "
                                 f"2 sigmas per image; found {len(cells)} values", path, no)
            pid = cells[0]
            if pid in seen:
                raise InputError(f"point id {pid!r} appears twice", path, no)
            lat, lon, h, s_lat, s_lon, s_h = (_float(c, w, path, no) for c, w in zip(
                cells[1:7], ("latitude", "longitude", "height", "sigma", "sigma", "sigma")))
            m_here = []
            for k in range(7, len(cells), 5):
                col, row, s_c, s_r = (_float(c, w, path, no) for c, w in zip(
                    cells[k + 1:k + 5], ("column", "row", "sigma", "sigma")))
                m_here.append(Measurement(pid, cells[k], col + 0.5, row + 0.5,
                                          sigma_px=max(s_c, s_r)))
        except InputError as exc:
            errors.append(exc)
            continue
        seen.add(pid)
        points.append(GroundPoint(pid, lon, lat, h, height_kind="ellipsoidal",
                                  sigma_xy_m=max(s_lat, s_lon), sigma_h_m=s_h,
                                  extra={"sigma_lat": s_lat, "sigma_lon": s_lon}))
        lines_of.append(no)
        meas += m_here
    raise_errors(errors)
    if not points:
        raise InputError("no points", path)
    points, warnings = lonlat_order(points, lines_of, path, crs, ("column 3 (lon)", "column 2 (lat)"))
    return PointFile(tuple(points), tuple(meas), crs, "asp", header, tuple(warnings))


def format_asp_gcp(pf: PointFile) -> str:
    """Text of an ASP ``.gcp`` file (points must be geographic: lon, lat in degrees)."""
    if pf.crs and not parse_crs(pf.crs).is_geographic:
        pf = convert_point_file(pf, "EPSG:4326")
    out = io.StringIO()
    if pf.header and pf.crs and pf.header.startswith("#") and pf.header.endswith(pf.crs):
        out.write(pf.header + "\n")
    by_point: dict[str, list] = {}
    for m in pf.measurements:
        by_point.setdefault(m.id, []).append(m)
    for p in pf.points:
        s_lat = p.extra.get("sigma_lat", p.sigma_xy_m if p.sigma_xy_m is not None else 1.0)
        s_lon = p.extra.get("sigma_lon", p.sigma_xy_m if p.sigma_xy_m is not None else 1.0)
        s_h = p.sigma_h_m if p.sigma_h_m is not None else 1.0
        row = [p.id, fmt(p.N), fmt(p.E), fmt(p.H), fmt(s_lat), fmt(s_lon), fmt(s_h)]
        for m in by_point.get(p.id, []):
            s = m.sigma_px if m.sigma_px is not None else 1.0
            row += [m.view, _fmt_px(m.x - 0.5), _fmt_px(m.y - 0.5), fmt(s), fmt(s)]
        if len(row) > 7:  # ASP needs at least one image per point
            out.write(", ".join(row) + "\n")
    return out.getvalue()
