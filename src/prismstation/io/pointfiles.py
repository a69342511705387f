"""Other tools' ground-control files: read, write, convert (docs/formats.md ``prismstation points``).

Formats (detected from extension and content, see :func:`detect_format`):

``qgis``  QGIS Georeferencer ``.points``: optional first line ``#CRS: <WKT>``, a header
          ``mapX,mapY,sourceX,sourceY,enable,dX,dY,residual`` (older QGIS: ``pixelX,pixelY``),
          one row per point. ``sourceY`` is negative downwards (QGIS shows the image with y up),
          origin at the top-left corner of the image: ``x = sourceX``, ``y = -sourceY``.
          ``enable = 0`` points become ``ICP`` (kept, not used in a fit) and are written back as 0.
          QGIS has no point ids nor heights: this writer appends ``id,H`` columns after the eight
          QGIS ones (QGIS reads the first columns by position and ignores the rest).
``odm``   OpenDroneMap ``gcp_list.txt``: first line a CRS (``EPSG:xxxx``, a proj4 string,
          ``WGS84 UTM 17N`` or ``WGS84 longlat``; :func:`~prismstation.io.georef.parse_crs`), ``#`` comments and blank lines skipped, rows
          ``geo_x geo_y geo_z im_x im_y image_name [gcp_name] [extra...]`` separated by blanks or
          tabs. ``geo_z`` is in the CRS's unit (US-feet grids give feet); OpenSfM puts pixel centres
          at integers, so ``x = im_x + 0.5``. Rows with the same name (or, when unnamed, the same
          coordinates) are one point measured in several images.
``asp``   Ames Stereo Pipeline ``.gcp``: ``id lat lon height sigma_lat sigma_lon sigma_h`` then per
          image ``name col row sigma_col sigma_row`` (commas and/or blanks); ``#`` comments; datum
          WGS84 (``# WKT:`` comment lines name another). Heights are above the datum (ellipsoidal).
          Vision Workbench puts pixel centres at integers, so ``x = col + 0.5``.
``csv``   the ground-point CSV of docs/formats.md (``id,E,N,H[,kind,height,sigma_xy_m,sigma_h_m]``);
          it has no CRS and no image measurements.

Conventions of the returned objects: ``E``, ``N`` in the units of ``PointFile.crs`` (x = easting
or longitude, y = northing or latitude; pyproj ``always_xy``); ``H`` always in metres (a feet grid's
heights are converted on reading and back on writing); measurements ``(x, y)`` in pixels with origin
at the top-left corner of the top-left pixel (docs/model.md §1), ``view`` = the image name of the file.

Geographic files whose column read as latitude holds values |v| > 90 while the other column has
none are read with the two columns swapped, and ``PointFile.warnings`` says so
(:func:`~prismstation.io.georef.lonlat_order`); a file whose order is ambiguous is read as it says.
The formats themselves are in :mod:`prismstation.io.gcpformats`; every line is split by
:mod:`prismstation.io.csvtable`.
"""
from __future__ import annotations

import csv
import io
import re
from pathlib import Path

from prismstation.errors import InputError
from prismstation.io.atomic import write_atomic
from prismstation.io.csvtable import raise_errors, read_table, read_text, text_cell
from prismstation.io.gcpformats import (QGIS_COLUMNS, fmt, format_asp_gcp, format_odm_gcp,
                                        format_qgis_points, read_asp_gcp, read_odm_gcp,
                                        read_qgis_points)
from prismstation.io.georef import PointFile, convert_point_file, metres_per_unit, parse_crs
from prismstation.io.points import POINT_COLUMNS, ground_points_from_table
from prismstation.model.points import HEIGHT_KINDS

__all__ = ["FORMATS", "PointFile", "convert_point_file", "detect_format", "format_asp_gcp",
           "format_ground_csv", "format_odm_gcp", "format_qgis_points", "metres_per_unit",
           "parse_crs", "read_asp_gcp", "read_ground_csv", "read_odm_gcp", "read_point_file",
           "read_qgis_points", "write_point_file", "QGIS_COLUMNS"]

FORMATS = ("csv", "qgis", "odm", "asp")


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
    lines = [ln for ln in read_text(path).splitlines() if ln.strip()]
    if not lines:
        raise InputError("empty file", path)
    first = lines[0].strip()
    if first.upper().startswith("#CRS") or "mapX" in first:
        return "qgis"
    content = [ln for ln in lines if not ln.lstrip().startswith("#")]
    if content and re.match(r"^\s*id\s*[,;\t]", content[0], re.IGNORECASE):
        return "csv"
    if content and content[0].strip().strip("'\"").upper().startswith(
            ("EPSG:", "+PROJ", "+INIT", "WGS84", "WGS 84")):
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
    write_atomic(path, writers[fmt](), keep_backup=False)  # a failure: WriteError, no file


def read_ground_csv(path, *, height: str = "ellipsoidal") -> PointFile:
    """Read the ground-point CSV (:func:`prismstation.io.points.read_ground_points` rules)."""
    points, errors = ground_points_from_table(read_table(path), height=height)
    raise_errors(errors)
    return PointFile(tuple(points), (), None, "csv", None)


def format_ground_csv(pf: PointFile) -> str:
    """Text of the ground-point CSV (extra columns of the points appended)."""
    extras = []
    for p in pf.points:
        extras += [k for k in p.extra if k not in extras and k not in POINT_COLUMNS
                   and k not in ("sigma_lat", "sigma_lon", "odm_extra")]
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(list(POINT_COLUMNS) + [text_cell(k) for k in extras])
    for p in pf.points:
        w.writerow([text_cell(p.id), fmt(p.E), fmt(p.N), fmt(p.H), p.kind, p.height_kind,
                    "" if p.sigma_xy_m is None else fmt(p.sigma_xy_m),
                    "" if p.sigma_h_m is None else fmt(p.sigma_h_m)]
                   + [text_cell(p.extra.get(k, "")) for k in extras])
    return out.getvalue()
