"""The residual report of a fitted project as a dict, JSON and CSV (FORMATS.md ``fit --json``)."""
from __future__ import annotations

import csv
import io
from pathlib import Path


from prismstation import __version__
from prismstation.core.solve import Solution
from prismstation.io.jsonfile import plain, write_atomic, write_json

REPORT_FORMAT = "prismstation-report/1"


def _bias_dict(fit) -> dict:
    d = {"model": fit.model, "M": fit.M, "b": fit.b,
         "parameters": {n: {"value": float(v), "std": float(s)} for n, v, s in zip(fit.names, fit.params, fit.std)}}
    if fit.lsq is not None:
        d.update(sigma0=fit.lsq.sigma0, dof=fit.lsq.dof, n_observations=len(fit.lsq.residuals))
    return d


def report_dict(sol: Solution, *, project_path=None, geoid: str | None = None) -> dict:
    """Everything the operator reads: parameters with σ, statistics (MODEL.md §2), points."""
    par = sol.parallax
    model = {"bias": {v: _bias_dict(f) for v, f in sol.bias.items()}}
    if par is not None:
        model["parallax"] = {"requested": par.requested, "used": par.used, "c0": par.c0, "c1": par.c1,
                             "std_c0": par.std_c0, "std_c1": par.std_c1, "c1_theoretical": par.c1_theory,
                             "sigma0_m": par.sigma0, "dof": None if par.lsq is None else par.lsq.dof,
                             "note": par.note}
    stats = {k: v for k, v in sol.stats.items() if k != "reference_view"}
    points = []
    for p in sol.points:
        d = {"id": p.id, "kind": p.kind, "measured": p.measured, "predicted": p.predicted,
             "residual_px": p.residual_px, "parallax_px": p.parallax_px, "across_px": p.across_px}
        if p.ground_est is not None:
            d.update(E_est=p.ground_est[0], N_est=p.ground_est[1], h_est=p.ground_est[2],
                     height_source=p.height_source)
        if p.ground_residual is not None:
            d.update(dE=p.ground_residual[0], dN=p.ground_residual[1], dh=p.ground_residual[2])
        d.update(std_residual=p.std_residual, redundancy=p.redundancy, blunder=p.blunder)
        if p.note:
            d["note"] = p.note
        points.append(d)
    out = {"format": REPORT_FORMAT, "program": f"prismstation {__version__}",
           "project": None if project_path is None else str(project_path),
           "crs": sol.scene.crs, "geoid": geoid, "settings": sol.settings.__dict__,
           "mean_height_m": sol.mean_height, "model": model, "statistics": stats,
           "points": points, "messages": list(sol.messages)}
    return plain(out)


CSV_COLUMNS = ["id", "kind", "view", "x", "y", "x_pred", "y_pred", "vx_px", "vy_px",
               "parallax_px", "E_est", "N_est", "h_est", "height_source", "dE", "dN", "dh",
               "std_residual", "blunder"]


def report_csv(report: dict) -> str:
    """One row per point and view (residuals), with the point's ground estimate repeated."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, CSV_COLUMNS, lineterminator="\n", extrasaction="ignore")
    w.writeheader()
    for p in report["points"]:
        views = list(p["measured"]) or [""]
        for v in views:
            row = {k: p.get(k) for k in CSV_COLUMNS}
            row["view"] = v
            if v:
                row["x"], row["y"] = p["measured"][v]
                if v in p["predicted"]:
                    row["x_pred"], row["y_pred"] = p["predicted"][v]
                if v in p["residual_px"]:
                    row["vx_px"], row["vy_px"] = p["residual_px"][v]
            w.writerow({k: ("" if x is None else x) for k, x in row.items()})
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
        from prismstation.errors import InputError
        raise InputError(f"unknown report format {ext!r}: use .json, .csv, .html or .pdf", path)
