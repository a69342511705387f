"""Reading control points for a single image (docs/model.md §4); the rectification itself is
:func:`prismstation.ops.rectify.rectify_raster`.

Image coordinates ``(x, y)``: column, row in pixels, origin at the top-left corner of the
top-left pixel. Map coordinates ``(E, N)`` in metres of the points' CRS.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from prismstation.errors import InputError
from prismstation.io.csvtable import raise_errors, read_table, records


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


def read_point_pairs(points_csv, measurements_csv=None, view: str | None = None) -> PointPairs:
    """Join ground points (``id,E,N[,H][,kind]``) with one view's measurements (``id,view,x,y``).

    Without ``measurements_csv`` the points file itself must carry ``x`` and ``y`` columns.
    ``view`` picks the view in the measurements (required when there is more than one).
    Points measured but without ground coordinates (tie points) and ground points not measured
    are left out. Both files are read by :mod:`prismstation.io.csvtable`; raises
    :class:`InputError` naming file, first bad line and problem (and how many more lines are bad).
    """
    need = ("id", "E", "N") if measurements_csv else ("id", "E", "N", "x", "y")
    rows, errors = records(read_table(points_csv), ("id", "E", "N", "H", "kind", "x", "y"), need)
    ground: dict[str, tuple] = {}
    for row in rows:
        try:
            pid = row.text("id")
            if not pid:
                raise row.error("empty id")
            if pid in ground:
                raise row.error(f"duplicate point id {pid!r}")
            kind = row.text("kind").upper() or "GCP"
            if kind not in ("GCP", "ICP"):
                raise row.error(f"kind {kind!r} is neither GCP nor ICP")
            e, n = row.number("E"), row.number("N")
            h = row.number("H", optional=True)
            xy = None if measurements_csv else (row.number("x"), row.number("y"))
            ground[pid] = (e, n, math.nan if h is None else h, kind == "ICP", xy)
        except InputError as exc:
            errors.append(exc)
    raise_errors(sorted(errors, key=lambda e: e.line or 0))
    meas: dict[str, tuple] = {}
    if measurements_csv:
        by_view: dict[str, dict] = {}
        rows, errors = records(read_table(measurements_csv), ("id", "view", "x", "y"),
                               ("id", "view", "x", "y"))
        for row in rows:
            try:
                pid, v = row.text("id"), row.text("view")
                xy = (row.number("x"), row.number("y"))
                if pid in by_view.setdefault(v, {}):
                    raise row.error(f"point {pid!r} measured twice in view {v!r}")
                by_view[v][pid] = xy
            except InputError as exc:
                errors.append(exc)
        raise_errors(sorted(errors, key=lambda e: e.line or 0))
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
