"""Reading control points for a single image (MODEL.md §4); the rectification itself is
:func:`prismstation.ops.rectify.rectify_raster`.

Image coordinates ``(x, y)``: column, row in pixels, origin at the top-left corner of the
top-left pixel. Map coordinates ``(E, N)`` in metres of the points' CRS.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from prismstation.errors import InputError


@dataclass(frozen=True, eq=False)
class PointPairs:
    """Points with both image and ground coordinates, in file order.

    ``xy`` (n, 2) pixels; ``en`` (n, 2) metres; ``h`` (n,) heights as given (NaN if absent);
    ``is_check`` (n,) True for ICPs; ``view`` the view the measurements came from.
    """

    ids: tuple
    xy: np.ndarray
    en: np.ndarray
    h: np.ndarray
    is_check: np.ndarray
    view: str | None = None


def _float(row: dict, key: str, path, line: int, required: bool = True) -> float:
    text = (row.get(key) or "").strip()
    if not text:
        if required:
            raise InputError(f"column {key!r} is empty", file=path, line=line)
        return float("nan")
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"column {key!r}: {text!r} is not a number", file=path, line=line) from None
    if not math.isfinite(value):
        raise InputError(f"column {key!r}: {text!r} is not a finite number", file=path, line=line)
    return value


def _rows(path, required: tuple[str, ...]):
    """Yield (line number, row dict) of a CSV with a header; check the required columns."""
    path = Path(path)
    try:
        fh = open(path, newline="", encoding="utf-8-sig")
    except OSError as exc:
        raise InputError(f"cannot open: {exc.strerror}", file=path) from None
    with fh:
        reader = csv.DictReader(fh)
        try:
            header = [h.strip() for h in (reader.fieldnames or [])]
        except (csv.Error, UnicodeDecodeError) as exc:
            raise InputError(f"not a readable CSV file ({exc})", file=path, line=1) from None
        reader.fieldnames = header
        missing = [c for c in required if c not in header]
        if missing:
            raise InputError(f"header lacks column(s) {', '.join(missing)} "
                             f"(has {', '.join(header) or 'none'})", file=path, line=1)
        try:
            for row in reader:
                if not any((v or "").strip() for v in row.values() if isinstance(v, str)):
                    continue
                if None in row:
                    raise InputError("more fields than the header", file=path, line=reader.line_num)
                yield reader.line_num, row
        except (csv.Error, UnicodeDecodeError) as exc:
            raise InputError(f"unreadable CSV ({exc})", file=path, line=reader.line_num) from None


def read_point_pairs(points_csv, measurements_csv=None, view: str | None = None) -> PointPairs:
    """Join ground points (``id,E,N[,H][,kind]``) with one view's measurements (``id,view,x,y``).

    Without ``measurements_csv`` the points file itself must carry ``x`` and ``y`` columns.
    ``view`` picks the view in the measurements (required when there is more than one).
    Points measured but without ground coordinates (tie points) and ground points not measured
    are left out. Raises :class:`InputError` naming file, line and problem.
    """
    need = ("id", "E", "N") if measurements_csv else ("id", "E", "N", "x", "y")
    ground: dict[str, tuple] = {}
    for line, row in _rows(points_csv, need):
        pid = row["id"].strip()
        if not pid:
            raise InputError("empty id", file=points_csv, line=line)
        if pid in ground:
            raise InputError(f"duplicate point id {pid!r}", file=points_csv, line=line)
        kind = (row.get("kind") or "GCP").strip().upper() or "GCP"
        if kind not in ("GCP", "ICP"):
            raise InputError(f"kind {kind!r} is neither GCP nor ICP", file=points_csv, line=line)
        e, n = _float(row, "E", points_csv, line), _float(row, "N", points_csv, line)
        h = _float(row, "H", points_csv, line, required=False)
        xy = None
        if not measurements_csv:
            xy = (_float(row, "x", points_csv, line), _float(row, "y", points_csv, line))
        ground[pid] = (e, n, h, kind == "ICP", xy)
    meas: dict[str, tuple] = {}
    if measurements_csv:
        by_view: dict[str, dict] = {}
        for line, row in _rows(measurements_csv, ("id", "view", "x", "y")):
            pid, v = row["id"].strip(), row["view"].strip()
            xy = (_float(row, "x", measurements_csv, line), _float(row, "y", measurements_csv, line))
            if pid in by_view.setdefault(v, {}):
                raise InputError(f"point {pid!r} measured twice in view {v!r}",
                                 file=measurements_csv, line=line)
            by_view[v][pid] = xy
        if view is None:
            if len(by_view) > 1:
                raise InputError(f"measurements of several views ({', '.join(sorted(by_view))}); "
                                 f"choose one with --view", file=measurements_csv)
            view = next(iter(by_view), None)
        if view not in by_view:
            raise InputError(f"no measurements in view {view!r}", file=measurements_csv)
        meas = by_view[view]
    ids, xy, en, h, chk = [], [], [], [], []
    for pid, (e, n, hh, is_icp, own_xy) in ground.items():
        m = own_xy if not measurements_csv else meas.get(pid)
        if m is None:
            continue
        ids.append(pid)
        xy.append(m)
        en.append((e, n))
        h.append(hh)
        chk.append(is_icp)
    if not ids:
        raise InputError("no point has both ground and image coordinates",
                         file=measurements_csv or points_csv)
    return PointPairs(tuple(ids), np.array(xy, float), np.array(en, float), np.array(h, float),
                      np.array(chk, bool), view)
