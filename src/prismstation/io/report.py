"""The residual report of a fitted project: one dict (docs/formats.md ``fit --json``), written as JSON
or CSV here and as HTML or PDF by :mod:`prismstation.gui.report_writer`, so that every format —
from the window or from ``prismstation report`` — holds the same content.

The dict: ``header`` (who, when, with what, on which scene: :func:`report_header`), the model
parameters with their σ, the statistics of docs/model.md §2 and one entry per point with its known
coordinates (``E_known``, ``N_known`` m in the project CRS, ``h_known`` ellipsoidal m — what the
residuals are taken against — and ``H_given`` with its ``height_kind`` as the point file gave
it), measured and predicted image positions (pixels, x column, y row), residuals (measured −
predicted, px), estimated ground coordinates (m, ellipsoidal h; ``lat_est``/``lon_est`` WGS 84
degrees) and ground residuals (estimated − known, m).
"""
from __future__ import annotations

import csv
import getpass
import io
import math
import re
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
from pyproj import CRS, Transformer
from pyproj.exceptions import CRSError

from prismstation import __version__
from prismstation.core.models.solution import Solution
from prismstation.errors import InputError
from prismstation.io.atomic import write_atomic
from prismstation.io.csvtable import text_cell
from prismstation.io.jsonfile import plain, read_json, write_json

REPORT_FORMAT = "prismstation-report/1"
TITLE = "ALOS-PRISM orientation report"


def default_operator() -> str:
    """The login name of the user running the program ("unknown" when it cannot be told)."""
    try:
        return getpass.getuser() or "unknown"
    except (KeyError, OSError):  # no USER variable and no password-database entry
        return "unknown"


def scene_identity(scene, scene_path=None) -> dict:
    """Who the scene is: ``scene_id`` (of the scene, else of its reference view), per view
    ``scene_ids`` and ``product_ids`` (JAXA ``Scs_SceneID`` / ``Pds_ProductID``),
    ``product_level`` (e.g. ``1B2R``), ``acquired`` (view → ISO time) and ``source`` (the
    product kind, or the program that made the scene). Read from the ``scene.json`` when
    readable (it keeps the ids of the views), otherwise from what the Scene kept; missing items
    are ``None`` or empty."""
    data = dict(scene.extra)
    views = {}
    if scene_path is not None:
        try:
            full, _ = read_json(scene_path)
            data = {**full, **data}
            views = full.get("views") if isinstance(full.get("views"), dict) else {}
        except InputError:
            pass

    def per_view(key):
        return {v: str(views[v][key]) for v in scene.views
                if isinstance(views.get(v), dict) and views[v].get(key)}
    scene_ids, product_ids = per_view("scene_id"), per_view("product_id")
    scene_id = data.get("scene_id") or scene_ids.get(scene.reference_view)
    level = data.get("product_level")
    if level is None:
        m = next((re.search(r"1B[12][RG]?", p) for p in product_ids.values()), None)
        level = m.group(0) if m else None
    product = data.get("product") if isinstance(data.get("product"), dict) else {}
    source = product.get("kind") or data.get("generator")
    times = data.get("times") if isinstance(data.get("times"), dict) else {}
    return {"scene_id": None if scene_id is None else str(scene_id), "scene_ids": scene_ids,
            "product_ids": product_ids, "product_level": None if level is None else str(level),
            "acquired": {v: str(t) for v, t in times.items() if v in scene.views},
            "source": None if source is None else str(source)}


def report_title(scene) -> str:
    """The PRISM triplet's title, a single PRISM view's, or ``n`` images of another sensor
    model (``scene.sensor.description``)."""
    if scene.is_triplet:
        return TITLE
    if scene.track is not None:
        return "ALOS-PRISM single-view orientation report"
    return f"Orientation report: {len(scene.views)} {scene.sensor.description}"


def report_header(scene, *, scene_path=None, project_path=None, operator: str | None = None,
                  created: datetime | None = None, orientation: str = "gcp") -> dict:
    """Who made the report, when (``created``: UTC, ISO 8601), with which program, of which
    project and scene (:func:`scene_identity`); ``operator`` defaults to the login name."""
    created = (created or datetime.now(timezone.utc)).astimezone(timezone.utc)
    return {"title": report_title(scene),
            "created": created.replace(microsecond=0).isoformat().replace("+00:00", "Z"),
            "operator": (operator or "").strip() or default_operator(),
            "software": f"prismstation {__version__}", "version": __version__,
            "project": None if project_path is None else str(project_path),
            **scene_identity(scene, scene_path),
            "orientation": "reference DEM" if orientation == "dem" else "GCP"}


def _settings(settings) -> dict:
    """The fit's settings (``fixed_view`` only when a view was held fixed)."""
    d = dict(settings.__dict__)
    if d.get("fixed_view") is None:
        d.pop("fixed_view", None)
    return d


def _bias_dict(fit) -> dict:
    d = {"model": fit.model, "M": fit.M, "b": fit.b,
         "parameters": {n: {"value": float(v), "std": float(s)} for n, v, s in zip(fit.names, fit.params, fit.std)}}
    if fit.lsq is not None:
        d.update(sigma0=fit.lsq.sigma0, dof=fit.lsq.dof, n_observations=len(fit.lsq.residuals))
    if getattr(fit, "fixed", False):
        d["fixed"] = True             # the datum of a fit without GCPs (zero bias)
    if getattr(fit, "reference_px", None) is not None:
        d["reference_px"] = list(fit.reference_px)  # where the parameters' constant terms apply
    return d


def _lonlat(crs: str, en: np.ndarray) -> np.ndarray:
    """``(n, 2)`` map metres → ``(n, 2)`` WGS 84 (lon, lat) degrees; NaN where not possible."""
    out = np.full_like(en, np.nan)
    if len(en):
        try:
            t = Transformer.from_crs(CRS.from_user_input(crs), CRS.from_epsg(4326), always_xy=True)
            out[:, 0], out[:, 1] = t.transform(en[:, 0], en[:, 1], errcheck=False)
        except CRSError:
            pass
    return out


def report_dict(sol: Solution, *, project_path=None, geoid: str | None = None,
                header: dict | None = None, known: dict | None = None) -> dict:
    """The report of ``sol``: header, parameters with σ, statistics (docs/model.md §2), points.

    ``header``: from :func:`report_header` (default: one made from ``sol.scene`` now, by the
    login name). ``known``: point id → ``{"E", "N", "h", "H", "height_kind"}`` (metres; ``h``
    ellipsoidal, ``H`` as given); without it the known coordinates are recovered as estimate −
    ground residual (ellipsoidal only).
    """
    sensor = sol.scene.sensor
    model = {"sensor": sensor.name, "height_source": sensor.height_source,
             "bias": {v: _bias_dict(f) for v, f in sol.bias.items()}, **sol.model.describe()}
    stats = {k: v for k, v in sol.stats.items() if k != "reference_view"}
    est = np.array([p.ground_est[:2] if p.ground_est is not None else (np.nan, np.nan)
                    for p in sol.points], float).reshape(-1, 2)
    lonlat = _lonlat(sol.scene.crs, est)
    points = []
    for p, ll in zip(sol.points, lonlat):
        d = {"id": p.id, "kind": p.kind}
        k = (known or {}).get(p.id)
        if k is None and known is None and p.ground_est is not None and p.ground_residual is not None:
            e, r = p.ground_est, p.ground_residual
            k = {"E": e[0] - r[0], "N": e[1] - r[1], "h": e[2] - r[2], "H": e[2] - r[2],
                 "height_kind": "ellipsoidal"}
        if k is not None:
            d.update(E_known=k["E"], N_known=k["N"], h_known=k["h"], H_given=k["H"],
                     height_kind=k["height_kind"])
        d.update(measured=p.measured, predicted=p.predicted, residual_px=p.residual_px,
                 parallax_px=p.parallax_px, across_px=p.across_px)
        if p.ground_est is not None:
            d.update(E_est=p.ground_est[0], N_est=p.ground_est[1], h_est=p.ground_est[2],
                     height_source=p.height_source, lat_est=ll[1], lon_est=ll[0])
        if getattr(p, "ground_sigma", None) is not None:
            d.update(sigma_E=p.ground_sigma[0], sigma_N=p.ground_sigma[1], sigma_h=p.ground_sigma[2])
        if p.ground_residual is not None:
            d.update(dE=p.ground_residual[0], dN=p.ground_residual[1], dh=p.ground_residual[2])
        d.update(std_residual=p.std_residual, redundancy=p.redundancy, blunder=p.blunder)
        if p.note:
            d["note"] = p.note
        points.append(d)
    if header is None:
        header = report_header(sol.scene, project_path=project_path, orientation=sol.settings.orientation)
    out = {"format": REPORT_FORMAT, "program": header["software"], "header": header,
           "project": None if project_path is None else str(project_path),
           "crs": sol.scene.crs, "geoid": geoid, "settings": _settings(sol.settings),
           "mean_height_m": sol.mean_height, "model": model, "statistics": stats,
           "points": points, "messages": list(sol.messages)}
    return plain(out)


# ---------------------------------------------------------------------------- CSV
# decimals by unit: metres to the millimetre, pixels to 0.001 px, degrees to 1e-8 (≈ 1 mm)
_M, _PX, _DEG = 3, 3, 8
CSV_COLUMNS = {"id": None, "kind": None, "view": None, "x": _PX, "y": _PX, "x_pred": _PX,
               "y_pred": _PX, "vx_px": _PX, "vy_px": _PX, "parallax_px": _PX,
               "E_known": _M, "N_known": _M, "h_known": _M, "H_given": _M, "height_kind": None,
               "E_est": _M, "N_est": _M, "h_est": _M, "lat_est": _DEG, "lon_est": _DEG,
               "height_source": None, "dE": _M, "dN": _M, "dh": _M, "std_residual": 2,
               "blunder": None}


def _cell(v, decimals) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return ""
    if isinstance(v, bool):
        return "yes" if v else "no"
    if decimals is not None and isinstance(v, (int, float)):
        return f"{v:.{decimals}f}"
    return str(v)


def report_csv(report: dict) -> str:
    """One row per point and view (a point measured nowhere: one row, empty view), with the
    point's known and estimated ground coordinates repeated on each of its rows; decimals by
    unit (mm, 0.001 px, 1e-8°). Columns: :data:`CSV_COLUMNS`."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(list(CSV_COLUMNS))
    for p in report["points"]:
        for v in list(p["measured"]) or [""]:
            row = {k: p.get(k) for k in CSV_COLUMNS}
            row["view"] = v
            if v:
                row["x"], row["y"] = p["measured"][v]
                if v in p["predicted"]:
                    row["x_pred"], row["y_pred"] = p["predicted"][v]
                if v in p["residual_px"]:
                    row["vx_px"], row["vy_px"] = p["residual_px"][v]
            w.writerow([_cell(row[k], nd) if nd is not None else text_cell(_cell(row[k], nd))
                        for k, nd in CSV_COLUMNS.items()])
    return buf.getvalue()


def write_report(report: dict, path) -> None:
    """Write by extension: ``.json`` or ``.csv`` (HTML and PDF come from the window's writer)."""
    path = Path(path)
    ext = path.suffix.lower()
    if ext == ".json":
        write_json(path, report, indent=1)
    elif ext == ".csv":
        write_atomic(path, report_csv(report), keep_backup=False)
    else:
        raise InputError(f"unknown report format {ext!r}: use .json, .csv, .html or .pdf", path)
