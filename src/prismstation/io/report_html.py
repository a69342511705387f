"""The report as one HTML document (no Qt): what :mod:`prismstation.gui.report_writer` saves as
``.html`` and paints into a PDF.

:func:`report_html` takes the dict of :func:`prismstation.io.report.report_dict` (the one
report model: the window and ``prismstation report`` give the same). Sections: header (date,
operator, program, project, scene and product ids), accuracy, model, residual statistics,
figures (given as image sources), points (known coordinates beside the residuals), notes.
"""
from __future__ import annotations

import html
import itertools
import re
from pathlib import Path

from prismstation.core.models.scene import reference_view
from prismstation.io.formatting import fixed

FIGURE_CAPTIONS = {
    "height": "Ellipsoidal height versus F−B parallax of the GCPs and ICPs, with the fitted and "
              "the theoretical height–parallax lines.",
    "height_minus_theory": "Height minus the theoretical prediction c1·py versus parallax, with "
                           "the fitted line in the same form.",
    "vectors": "Residual vectors (measured − predicted) in view {view}, exaggerated as the title "
               "says; y (rows) downwards.",
    "std_residuals": "Largest |standardised residual| of each GCP, on the normal scale, "
                     "against the one blunder threshold of every fit; blunders in magenta.",
}

_SOURCE = {"parallax": "py", "intersection": "rays", "reference": "DEM", "mean": "mean"}
#: the figures of a model whose heights come from the F−B parallax line (the PRISM model)
PARALLAX_FIGURES = ("height", "height_minus_theory")


def _from_parallax(r: dict) -> bool:
    """Whether the report's heights come from the parallax line (the PRISM model) rather than
    from intersecting rays (``model.height_source``)."""
    return (r.get("model") or {}).get("height_source", "parallax") == "parallax"
_TABLE_MARK = "\x00table\x00"  # numbered in document order by report_html
_NEW_PAGE = ' style="page-break-before:always"'
_NUMBER = re.compile(r"[+\-]?\d|—$")  # cells aligned right: numbers and the "no value" dash
# ---------------------------------------------------------------------------- formatting
def _sci(v) -> str:
    if v is None:
        return "—"
    return f"{v:.4g}" if 1e-3 <= abs(v) < 1e5 or v == 0 else f"{v:.4e}"


def _esc(s) -> str:
    return html.escape("" if s is None else str(s))


def _table(tid, caption, head, rows, *, small=False, highlight=()) -> str:
    """An HTML table; ``head`` list of column titles (repeated on each PDF page); ``rows``
    lists of cell texts; ``caption`` numbered "Table k." in document order."""
    # Qt's rich text wants the style per cell, and knows no "nowrap" attribute
    size = f' style="white-space:nowrap{"; font-size:7pt" if small else ""}"'
    # the caption is the table's first heading row: never parted from it by a page break,
    # and repeated with the column titles on every page the table runs over
    cap = (f'<tr><th colspan="{len(head)}" align="left" style="font-weight:normal">'
           f'<b>{_TABLE_MARK}</b> {_esc(caption)}</th></tr>' if caption else "")
    out = [f'<table id="{tid}" border="1" cellspacing="0" cellpadding="{2 if small else 3}">',
           "<thead>" + cap + "<tr>" + "".join(f'<th bgcolor="#e4e8f0"{size}>{_esc(h)}</th>' for h in head)
           + "</tr></thead>"]
    for i, row in enumerate(rows):
        bg = ' bgcolor="#ffd6d6"' if i in highlight else ""
        cells = []
        for j, c in enumerate(row):
            align = "right" if j and _NUMBER.match(str(c)) else "left"
            cells.append(f'<td align="{align}"{size}>{_esc(c)}</td>')
        out.append(f"<tr{bg}>" + "".join(cells) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def _stat_rows(columns, stats=("n", "min", "max", "mean", "rms", "std"), nd=2):
    """Rows ``[stat, col1, col2, ...]`` from ComponentStats dicts ``columns``."""
    names = {"n": "n", "min": "Minimum", "max": "Maximum", "mean": "Mean", "rms": "RMS",
             "std": "Std. dev."}
    rows = []
    for s in stats:
        rows.append([names[s]] + [("—" if c is None else str(c.get(s)) if s == "n"
                                   else fixed(c.get(s), nd, sign=s in ("min", "max", "mean")))
                                  for c in columns])
    return rows


# ---------------------------------------------------------------------------- HTML
def format_when(iso) -> str:
    """``2026-12-01T17:49:38Z`` / ``...+00:00`` → ``2026-12-01 17:49:38 UTC``."""
    if not iso:
        return "—"
    s = str(iso).replace("T", " ")
    for tail in ("Z", "+00:00"):
        if s.endswith(tail):
            return s[: -len(tail)].split(".")[0] + " UTC"
    return s


def _header_rows(r: dict) -> list:
    """Rows of the header table: ``(label, value)`` pairs, two per row (a long one alone); a
    list value is one line per item."""
    h = r.get("header") or {}
    settings = r.get("settings") or {}
    project = h.get("project") or r.get("project")
    sids, pids = h.get("scene_ids") or {}, h.get("product_ids") or {}
    products = [f"{v}: {' '.join(x for x in (sids.get(v), pids.get(v)) if x)}"
                for v in dict.fromkeys([*sids, *pids])] or "—"
    acquired = [f"{v}: {format_when(t)}" for v, t in (h.get("acquired") or {}).items()] or "—"
    geoid = r.get("geoid")
    return [
        [("Date", format_when(h.get("created"))), ("Operator", h.get("operator") or "—")],
        [("Software", h.get("software") or r.get("program") or "—"),
         ("Project", Path(project).name if project else "—")],
        [("Scene ID", h.get("scene_id") or "—"), ("Product level", h.get("product_level") or "—")],
        [("Products", products)],
        [("Acquired", acquired)],
        [("Source", h.get("source") or "—"), ("Orientation", f"from {h.get('orientation', 'GCP')}")],
        [("CRS", r.get("crs") or "—"),
         ("Heights", "ellipsoidal h" + (f"; geoid {geoid}" if geoid else ""))],
        [("Bias model", settings.get("bias_model", "—")),
         ("Height–parallax model", settings.get("parallax_model", "—")) if _from_parallax(r) else
         ("View held fixed", settings.get("fixed_view") or next(
             (v for v, b in (r.get("model") or {}).get("bias", {}).items() if b.get("fixed")), "—"))],
        [("A-priori σ of a measurement", f"{fixed(settings.get('sigma_px'))} px"),
         ("Blunder threshold |w|", fixed(settings.get("blunder_threshold")))],
        [("Mean scene height", f"{fixed(r.get('mean_height_m'))} m")],
    ]


def _header_table(r: dict) -> str:
    out = ['<table id="info" width="100%" border="1" cellspacing="0" cellpadding="3">']
    for row in _header_rows(r):
        cells = []
        for label, value in row:
            cells.append(f'<td bgcolor="#e4e8f0" nowrap><b>{_esc(label)}</b></td>')
            span = ' colspan="3"' if len(row) == 1 else ""
            text = "<br>".join(map(_esc, value)) if isinstance(value, list) else _esc(value)
            cells.append(f"<td{span}>{text}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    return "\n".join(out + ["</table>"])


def _summary(r: dict, ref: str) -> str:
    """The accuracy in one table: ground RMSE of GCPs and ICPs, and the fit's σ0."""
    st = r.get("statistics", {})
    g, hgt, img = st.get("ground", {}), st.get("height", {}), st.get("image", {}).get(ref, {})
    rows = []
    for kind in ("GCP", "ICP"):
        if kind not in g:
            continue
        rows.append([kind, str(g[kind]["x"]["n"]), fixed(g[kind]["x"]["rms"]), fixed(g[kind]["y"]["rms"]),
                     fixed(g[kind]["planimetric_rms"]), fixed((hgt.get(kind) or {}).get("rms")),
                     fixed(img.get(kind, {}).get("px", {}).get("planimetric_rms"))])
    bias = (r.get("model") or {}).get("bias", {}).get(ref, {})
    sigma = (r.get("settings") or {}).get("sigma_px")
    if (r.get("header") or {}).get("orientation") == "reference DEM":
        note = ("<p>Oriented from the reference DEM, not from the GCPs: GCP and ICP figures are "
                "both independent checks.</p>")
    else:
        note = (f'<p>σ0 of the bias fit in view {_esc(ref)}: {fixed(bias.get("sigma0"), 3)} '
                f'(unit weight; a-priori σ {fixed(sigma)} px). GCP figures are the fit\'s own '
                f'residuals; ICP figures are the independent check.</p>')
    return _table("summary", "Accuracy: root-mean-square ground residuals, estimated − known (m), "
                             f"and image residuals in view {ref} (px)",
                  ["", "n", "RMSE E", "RMSE N", "RMSE plan.", "RMSE h", f"RMS image {ref}"], rows) + note


def _model(r: dict) -> list:
    model = r.get("model", {})
    bias = model.get("bias", {})
    views = list(bias)
    names = []
    for v in views:
        names += [n for n in bias[v].get("parameters", {}) if n not in names]
    rows = []
    for n in names:
        row = [n]
        for v in views:
            p = bias[v].get("parameters", {}).get(n)
            row.append("" if p is None else f"{_sci(p['value'])} ± {_sci(p['std'])}")
        rows.append(row)
    rows.append(["model"] + [bias[v].get("model", "") for v in views])
    rows.append(["σ0 (px)"] + [fixed(bias[v].get("sigma0"), 3) for v in views])
    rows.append(["redundancy (dof)"] + [fixed(bias[v].get("dof")) for v in views])
    rows.append(["observations"] + [fixed(bias[v].get("n_observations")) for v in views])
    caption = ("Bias compensation per view, x = x′ + M·x′ + b (x′: image position from the "
               "product's ancillary data; M 2×2, b in pixels): parameter ± σ" if _from_parallax(r) else
               "Bias compensation per view, x = RPC(ground) + Δ(x) (Δ at the image point: a0, b0 in pixels "
               "at the view's reference point, the other terms in pixels per 1,000 pixels): parameter ± σ")
    parts = [_table("bias", caption,
                    ["Parameter"] + [f"view {v}" for v in views], rows)]
    par = model.get("parallax")
    if par:
        rows = [["c0 (m)", fixed(par.get("c0"), 2), fixed(par.get("std_c0"), 2)],
                ["c1 (m/px)", fixed(par.get("c1"), 4), fixed(par.get("std_c1"), 4)],
                ["c1 theoretical (m/px)", fixed(par.get("c1_theoretical"), 4), ""],
                ["σ0 (m)", fixed(par.get("sigma0_m"), 3), ""],
                ["redundancy (dof)", fixed(par.get("dof")), ""],
                ["fitted", f"{par.get('used')} (requested {par.get('requested')})", ""]]
        if par.get("note"):
            rows.append(["note", par["note"], ""])
        parts.append(_table("parallax", "Height–parallax relation h = c0 + c1·py (py: F−B parallax, px)",
                            ["Parameter", "Value", "σ"], rows))
    return parts


def _statistics(r: dict, ref: str) -> list:
    st = r.get("statistics", {})
    img = st.get("image", {})
    parts = []
    if ref in img:
        cols = [img[ref][k]["m"][c] for k in ("GCP", "ICP") for c in ("x", "y")]
        rows = _stat_rows(cols)
        rows.append(["Planimetric RMS", "", fixed(img[ref]["GCP"]["m"]["planimetric_rms"]), "",
                     fixed(img[ref]["ICP"]["m"]["planimetric_rms"])])
        parts.append(_table("table1", f"Image residuals of GCPs and ICPs in view {ref}, scaled to metres "
                                      "by the pixel size (m)",
                            ["", "GCP Rx", "GCP Ry", "ICP Rx", "ICP Ry"], rows))
    kinds = [k for k in ("GCP", "ICP", "TIE") if all(k in d for d in img.values())]
    rows = [[v] + [x for k in kinds for x in
                   (str(d[k]["px"]["x"]["n"]), fixed(d[k]["px"]["x"]["rms"]),
                    fixed(d[k]["px"]["y"]["rms"]), fixed(d[k]["px"]["planimetric_rms"]))]
            for v, d in img.items()]
    if rows:
        parts.append(_table("table1b", "Image residuals per view (px)",
                            ["View"] + [f"{k} {c}" for k in kinds for c in ("n", "RMS x", "RMS y", "RMS xy")],
                            rows))
    if "F-N" in st and "B-N" in st:
        parts.append(_table("table2", "Across-track differences of image coordinates F − N and B − N (px)",
                            ["", "Δx F−N", "Δx B−N"],
                            _stat_rows([st["F-N"], st["B-N"]], ("n", "min", "max", "mean", "std"))))
    if "height" in st:
        parts.append(_table("table3", "Height residuals, height from "
                            f"{'parallax' if _from_parallax(r) else 'intersection'} − known (m)",
                            ["", "Rh GCP", "Rh ICP"],
                            _stat_rows([st["height"].get("GCP"), st["height"].get("ICP")])))
    if "ground" in st:
        g = st["ground"]
        cols = [g[k][c] for k in ("GCP", "ICP") for c in ("x", "y")]
        rows = _stat_rows(cols, ("n", "min", "max", "mean", "rms"))
        rows.append(["Planimetric RMS", "", fixed(g["GCP"]["planimetric_rms"]), "",
                     fixed(g["ICP"]["planimetric_rms"])])
        parts.append(_table("ground", "Ground residuals, estimated − known (m)",
                            ["", "GCP dE", "GCP dN", "ICP dE", "ICP dN"], rows))
    return parts


#: the points a paged document (the PDF) lists at most: a page holds about 50 rows and each
#: point is in three tables, so 50,000 points would be 3,000 pages and minutes of layout
MAX_DOCUMENT_POINTS = 1000


def listed_points(points: list, limit: int | None) -> tuple[list, str | None]:
    """The points a document lists, at most ``limit`` (None: all): every GCP and ICP and every
    flagged blunder first, then tie points, in the report's order; and the note saying what was
    left out (None when nothing was)."""
    if limit is None or len(points) <= limit:
        return points, None
    first = {i for i, p in enumerate(points) if p.get("kind") in ("GCP", "ICP") or p.get("blunder")}
    rest = [i for i in range(len(points)) if i not in first]
    keep = sorted(first)[:limit]
    keep = sorted(keep + rest[:max(0, limit - len(keep))])
    return [points[i] for i in keep], (
        f"The point tables list {len(keep):,} of the {len(points):,} points (every GCP, ICP and flagged "
        "blunder first, then tie points); the statistics and figures use them all. Every point is in "
        "the CSV or JSON report (prismstation report PROJECT -o report.csv).")


def _points(r: dict, ref: str, views: list, limit: int | None = None) -> list:
    """Three tables: known coordinates beside ground residuals; image residuals; estimates
    (at most ``limit`` points: :func:`listed_points`)."""
    pts, cut = listed_points(r.get("points", []), limit)
    known = [p for p in pts if p.get("E_known") is not None]
    ortho = any(p.get("height_kind") == "orthometric" for p in known)
    head = ["id", "kind", "E", "N", "h"] + (["H given"] if ortho else []) + ["dE", "dN", "dh", "|w|", "blunder"]
    rows, flagged = [], []
    for i, p in enumerate(known):
        given = [fixed(p.get("H_given"), 3) if p.get("height_kind") == "orthometric" else ""] if ortho else []
        rows.append([p["id"], p["kind"], fixed(p["E_known"], 3), fixed(p["N_known"], 3),
                     fixed(p.get("h_known"), 3)] + given +
                    [fixed(p.get("dE"), sign=True), fixed(p.get("dN"), sign=True),
                     fixed(p.get("dh"), sign=True), fixed(p.get("std_residual")),
                     "yes" if p.get("blunder") else ""])
        if p.get("blunder"):
            flagged.append(i)
    h_note = "; H orthometric as given" if ortho else ""
    parts = [_table("known", f"Known coordinates (E, N in {r.get('crs') or 'the project CRS'}; "
                             f"h ellipsoidal{h_note}) and ground residuals, estimated − known (m); "
                             "|w|: largest standardised residual of a GCP; a flagged blunder shaded",
                    head, rows, small=True, highlight=flagged)]
    rows, flagged = [], []
    py = _from_parallax(r)
    for i, p in enumerate(pts):
        res = p.get("residual_px") or {}
        rows.append([p["id"], p["kind"]] + [fixed(x, sign=True) for v in views
                                             for x in (res.get(v) or (None, None))]
                    + ([fixed(p.get("parallax_px"))] if py else []))
        if p.get("blunder"):
            flagged.append(i)
    parts.append(_table("residuals", "Image residuals, measured − predicted (px)"
                        + (", and F−B parallax py (px)" if py else ""),
                        ["id", "kind"] + [f"{c} {v}" for v in views for c in ("vx", "vy")] + (["py"] if py else []),
                        rows, small=True, highlight=flagged))
    rows = [[p["id"], p["kind"], fixed(p.get("E_est"), 2), fixed(p.get("N_est"), 2), fixed(p.get("h_est"), 2),
             _SOURCE.get(p.get("height_source"), p.get("height_source") or ""),
             fixed(p.get("lat_est"), 7), fixed(p.get("lon_est"), 7)] for p in pts]
    parts.append(_table("estimates", "Estimated ground coordinates (E, N m; h ellipsoidal m, from "
                                     + ("py: parallax" if py else "rays: intersection of the rays")
                                     + ", DEM: reference DEM, mean: mean height; latitude and "
                                     "longitude WGS 84, degrees)",
                        ["id", "kind", "E est", "N est", "h est", "h from", "lat", "lon"],
                        rows, small=True))
    if cut:
        parts.insert(0, f"<p><i>{_esc(cut)}</i></p>")
    return parts


def report_html(report: dict, images: dict | None = None, max_points: int | None = None) -> str:
    """The report as HTML; ``images`` maps plot names (``plots.PLOT_NAMES``) to ``src`` URLs;
    ``max_points``: the most points the point tables list (:func:`listed_points`)."""
    r = report
    bias = r.get("model", {}).get("bias", {})
    ref = reference_view(bias)
    title = (r.get("header") or {}).get("title") or "ALOS-PRISM orientation report"
    parts = [f"<html><head><meta charset=\"utf-8\"><title>{_esc(title)}</title>",
             "<style>body{font-family:sans-serif;font-size:9pt} table{border-collapse:collapse;"
             "margin-bottom:6px} th,td{padding:2px 5px} .caption{margin-top:10px}</style>",
             "</head><body>", f"<h1>{_esc(title)}</h1>", _header_table(r),
             "<h2>1. Accuracy</h2>", _summary(r, ref),
             "<h2>2. Model</h2>", *_model(r),
             "<h2>3. Residual statistics</h2>", *_statistics(r, ref)]
    if images and not _from_parallax(r):
        images = {k: v for k, v in images.items() if k not in PARALLAX_FIGURES}
    if images:
        parts.append(f"<h2{_NEW_PAGE}>4. Figures</h2>")
        for k, (name, src) in enumerate(images.items(), 1):
            caption = FIGURE_CAPTIONS.get(name, name).format(view=ref)
            parts.append(f'<p align="center"><img src="{_esc(src)}" width="620"></p>'
                         f'<p class="caption">Figure {k}. {_esc(caption)}</p>')
    parts.append(f"<h2{_NEW_PAGE}>{5 if images else 4}. Points</h2>")
    parts += _points(r, ref, list(bias), max_points)
    notes = list(r.get("messages") or [])
    notes += [f"{p['id']}: {p['note']}" for p in r.get("points", []) if p.get("note")]
    if notes:
        parts.append("<h2>Notes</h2><ul>" + "".join(f"<li>{_esc(n)}</li>" for n in notes) + "</ul>")
    parts.append("</body></html>")
    number = itertools.count(1)
    return re.sub(_TABLE_MARK, lambda _: f"Table {next(number)}.", "\n".join(p for p in parts if p))


# ---------------------------------------------------------------------------- figures
