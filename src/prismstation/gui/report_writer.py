"""The residual report as HTML or PDF through Qt's own writers (issue 3, item 8).

:func:`write_document` takes the dict of :func:`prismstation.io.report.report_dict` (FORMATS.md
``fit --json``) and writes, by extension, a self-contained ``.html`` (figures as PNG data URIs) or
a ``.pdf`` (``QTextDocument`` printed on a ``QPdfWriter``, A4). The statistics are laid out as
the seed paper's Tables 1–3 plus the ground residuals; the figures are the four plots of
:class:`prismstation.gui.plots.PlotsWidget`, drawn from the dict alone unless given.
"""
from __future__ import annotations

import base64
import html
import math
import os
import sys
import tempfile
from pathlib import Path

from prismstation.core.scene import reference_view
from prismstation.errors import InputError

FIGURE_CAPTIONS = {
    "height": "Figure 1. Height (ellipsoidal) versus F−B parallax of the GCPs and ICPs, with the "
              "fitted and the theoretical (eq. 4) lines — the seed paper's Fig. 4.",
    "height_minus_theory": "Figure 2. Height minus the theoretical prediction versus parallax, "
                           "with the fitted line in the same form — the seed paper's Fig. 5.",
    "vectors": "Figure 3. Residual vectors (measured − predicted) in the reference image, "
               "exaggerated as the title says; y (rows) downwards.",
    "std_residuals": "Figure 4. Largest |standardised residual| of each GCP against the rejection "
                     "threshold and its critical values; the flagged blunder in red.",
}

_SOURCE = {"parallax": "py", "reference": "DEM", "mean": "mean"}
_app = None  # a QApplication made here for the command line, kept alive


def _ensure_app():
    """The running QApplication, or a new one (offscreen when there is no display)."""
    global _app
    from PySide6.QtWidgets import QApplication
    app = QApplication.instance()
    if app is None:
        if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                     or os.environ.get("WAYLAND_DISPLAY")):
            os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
        app = _app = QApplication([])
    return app


# ---------------------------------------------------------------------------- formatting
def _num(v, nd=2, signed=False) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "—"
    if isinstance(v, bool) or isinstance(v, int):
        return str(v)
    return f"{v:+.{nd}f}" if signed else f"{v:.{nd}f}"


def _sci(v) -> str:
    if v is None:
        return "—"
    return f"{v:.4g}" if 1e-3 <= abs(v) < 1e5 or v == 0 else f"{v:.4e}"


def _esc(s) -> str:
    return html.escape("" if s is None else str(s))


def _table(tid, caption, head, rows, *, small=False, highlight=()) -> str:
    """An HTML table; ``head`` list of column titles; ``rows`` lists of cell texts."""
    size = ' style="font-size:6.5pt"' if small else ""  # Qt's rich text wants it per cell
    out = [f'<p class="caption"><b>{caption}</b></p>' if caption else "",
           f'<table id="{tid}" border="1" cellspacing="0" cellpadding="{2 if small else 3}">',
           "<tr>" + "".join(f'<th bgcolor="#e4e8f0"{size}>{_esc(h)}</th>' for h in head) + "</tr>"]
    for i, row in enumerate(rows):
        bg = ' bgcolor="#ffd6d6"' if i in highlight else ""
        cells = []
        for j, c in enumerate(row):
            align = "left" if j == 0 else "right"
            cells.append(f'<td align="{align}" nowrap{size}>{_esc(c)}</td>')
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
                                   else _num(c.get(s), nd, signed=s in ("min", "max", "mean")))
                                  for c in columns])
    return rows


# ---------------------------------------------------------------------------- HTML
def report_html(report: dict, images: dict | None = None) -> str:
    """The report as HTML; ``images`` maps plot names (``plots.PLOT_NAMES``) to ``src`` URLs."""
    r = report
    st = r.get("statistics", {})
    model = r.get("model", {})
    bias = model.get("bias", {})
    ref = reference_view(bias)
    settings = r.get("settings") or {}
    parts = ["<html><head><meta charset=\"utf-8\"><title>prismstation residual report</title>",
             "<style>body{font-family:sans-serif;font-size:9pt} table{border-collapse:collapse;"
             "margin-bottom:6px} th,td{padding:2px 5px} .caption{margin-top:10px}</style>",
             "</head><body>",
             "<h1>PRISM triplet orientation — residual report</h1>"]
    info = [["Project", r.get("project") or "—"], ["CRS", r.get("crs") or "—"],
            ["Geoid", r.get("geoid") or "none (heights as given)"],
            ["Program", r.get("program") or "—"],
            ["Bias model", settings.get("bias_model", "—")],
            ["Parallax model", settings.get("parallax_model", "—")],
            ["A-priori σ of a measurement", f"{_num(settings.get('sigma_px'))} px"],
            ["Blunder threshold (|standardised residual|)", _num(settings.get("blunder_threshold"))],
            ["Mean scene height", f"{_num(r.get('mean_height_m'))} m"]]
    parts.append(_table("info", "", ["Item", "Value"], info))

    # ---- model parameters
    parts.append("<h2>Model</h2>")
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
    rows.append(["σ0 (px)"] + [_num(bias[v].get("sigma0"), 3) for v in views])
    rows.append(["redundancy (dof)"] + [_num(bias[v].get("dof")) for v in views])
    rows.append(["observations"] + [_num(bias[v].get("n_observations")) for v in views])
    parts.append(_table("bias", "Bias compensation x = x0′ + M·x0′ + b (eq. 3): parameter ± σ",
                        ["Parameter"] + [f"view {v}" for v in views], rows))
    par = model.get("parallax")
    if par:
        rows = [["c0 (m)", _num(par.get("c0"), 2), _num(par.get("std_c0"), 2)],
                ["c1 (m/px)", _num(par.get("c1"), 4), _num(par.get("std_c1"), 4)],
                ["c1 theoretical (m/px)", _num(par.get("c1_theoretical"), 4), ""],
                ["σ0 (m)", _num(par.get("sigma0_m"), 3), ""],
                ["redundancy (dof)", _num(par.get("dof")), ""],
                ["fitted", f"{par.get('used')} (requested {par.get('requested')})", ""]]
        if par.get("note"):
            rows.append(["note", par["note"], ""])
        parts.append(_table("parallax", "Height–parallax relation h = c0 + c1·py (eq. 4)",
                            ["Parameter", "Value", "σ"], rows))

    # ---- statistics
    parts.append("<h2>Statistics</h2>")
    img = st.get("image", {})
    if ref in img:
        cols = [img[ref][k]["m"][c] for k in ("GCP", "ICP") for c in ("x", "y")]
        rows = _stat_rows(cols)
        rows.append(["Planimetric RMS", "", _num(img[ref]["GCP"]["m"]["planimetric_rms"]), "",
                     _num(img[ref]["ICP"]["m"]["planimetric_rms"])])
        parts.append(_table("table1", f"Table 1. Residuals of GCPs and ICPs in the orientation of "
                                      f"image {ref} (m)",
                            ["", "GCP Rx", "GCP Ry", "ICP Rx", "ICP Ry"], rows))
    rows = []
    for v, d in img.items():
        rows.append([v] + [x for k in ("GCP", "ICP") for x in
                           (str(d[k]["px"]["x"]["n"]), _num(d[k]["px"]["x"]["rms"]),
                            _num(d[k]["px"]["y"]["rms"]), _num(d[k]["px"]["planimetric_rms"]))])
    if rows:
        parts.append(_table("table1b", "Image residuals per view (px)",
                            ["View", "GCP n", "GCP RMS x", "GCP RMS y", "GCP RMS xy",
                             "ICP n", "ICP RMS x", "ICP RMS y", "ICP RMS xy"], rows))
    if "F-N" in st and "B-N" in st:
        parts.append(_table("table2", "Table 2. Across-track differences of image coordinates "
                                      "F − N and B − N (px)",
                            ["", "Δx F−N", "Δx B−N"],
                            _stat_rows([st["F-N"], st["B-N"]], ("n", "min", "max", "mean", "std"))))
    if "height" in st:
        parts.append(_table("table3", "Table 3. Height residuals of GCPs and ICPs, height from "
                                      "parallax − known (m)",
                            ["", "Rh GCP", "Rh ICP"],
                            _stat_rows([st["height"].get("GCP"), st["height"].get("ICP")])))
    if "ground" in st:
        g = st["ground"]
        cols = [g[k][c] for k in ("GCP", "ICP") for c in ("x", "y")]
        rows = _stat_rows(cols, ("n", "min", "max", "mean", "rms"))
        rows.append(["Planimetric RMS", "", _num(g["GCP"]["planimetric_rms"]), "",
                     _num(g["ICP"]["planimetric_rms"])])
        parts.append(_table("ground", "Table 4. Ground residuals, estimated − known (m)",
                            ["", "GCP dE", "GCP dN", "ICP dE", "ICP dN"], rows))

    # ---- figures
    if images:
        parts.append("<h2>Figures</h2>")
        for name, src in images.items():
            parts.append(f'<p align="center"><img src="{_esc(src)}" width="620"></p>'
                         f'<p class="caption">{_esc(FIGURE_CAPTIONS.get(name, name))}</p>')

    # ---- points
    head = ["id", "kind", f"vx {ref}", f"vy {ref}", "py", "E est", "N est", "h est", "h from",
            "dE", "dN", "dh", "|w|", "blunder"]
    rows, flagged = [], []
    for i, p in enumerate(r.get("points", [])):
        v = (p.get("residual_px") or {}).get(ref) or (None, None)
        rows.append([p["id"], p["kind"], _num(v[0], signed=True),
                     _num(v[1], signed=True), _num(p.get("parallax_px")), _num(p.get("E_est")),
                     _num(p.get("N_est")), _num(p.get("h_est")), _SOURCE.get(p.get("height_source"), p.get("height_source") or ""),
                     _num(p.get("dE"), signed=True), _num(p.get("dN"), signed=True),
                     _num(p.get("dh"), signed=True), _num(p.get("std_residual")),
                     "yes" if p.get("blunder") else ""])
        if p.get("blunder"):
            flagged.append(i)
    parts.append("<h2>Points</h2>")
    parts.append(_table("points", f"Residuals v (measured − predicted) in view {ref} (px), "
                                  f"F−B parallax py (px), estimated ground coordinates "
                                  f"(h from py: parallax, DEM: reference, mean: mean height) "
                                  f"(m, h ellipsoidal), ground residuals estimated − known (m), "
                                  f"largest |standardised residual| |w|.",
                        head, rows, small=True, highlight=flagged))
    notes = list(r.get("messages") or [])
    notes += [f"{p['id']}: {p['note']}" for p in r.get("points", []) if p.get("note")]
    if notes:
        parts.append("<h2>Notes</h2><ul>" + "".join(f"<li>{_esc(n)}</li>" for n in notes) + "</ul>")
    parts.append("</body></html>")
    return "\n".join(p for p in parts if p)


# ---------------------------------------------------------------------------- figures
def render_figures(report: dict, size=(840, 540)) -> dict:
    """The four plots of ``report`` as QImages ``{name: QImage}`` (offscreen pyqtgraph)."""
    _ensure_app()
    from prismstation.gui.plots import PlotsWidget
    w = PlotsWidget()
    try:
        w.set_report(report)
        return w.render_images(size)
    finally:
        w.deleteLater()


def _png_bytes(image) -> bytes:
    from PySide6.QtCore import QBuffer, QByteArray, QIODevice
    data = QByteArray()
    buf = QBuffer(data)
    buf.open(QIODevice.OpenModeFlag.WriteOnly)
    image.save(buf, "PNG")
    buf.close()
    return bytes(data.data())


def write_document(report: dict, path, figures: dict | None = None) -> None:
    """Write the residual report to ``path``: ``.html`` or ``.pdf`` (by extension).

    Parameters
    ----------
    report : dict
        As returned by :func:`prismstation.io.report.report_dict`.
    path : path-like
    figures : dict of str -> QImage, optional
        Plots to embed (keys as ``prismstation.gui.plots.PLOT_NAMES``); drawn from
        ``report`` when omitted.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in (".html", ".htm", ".pdf"):
        raise InputError(f"unknown document format {ext!r}: use .html or .pdf", path)
    _ensure_app()
    if figures is None:
        figures = render_figures(report)
    if ext in (".html", ".htm"):
        srcs = {n: "data:image/png;base64," + base64.b64encode(_png_bytes(im)).decode("ascii")
                for n, im in figures.items()}
        text = report_html(report, srcs).encode("utf-8")
        _atomic(path, lambda tmp: Path(tmp).write_bytes(text))
    else:
        _atomic(path, lambda tmp: _write_pdf(report, tmp, figures))


def _atomic(path: Path, write) -> None:
    """``write(tmp)`` a temporary file beside ``path``, then rename it onto ``path``
    (permissions as a plain new file: 0666 less the umask)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        write(tmp)
        if os.path.getsize(tmp) == 0:
            raise InputError("nothing was written (Qt wrote an empty file)", path)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _write_pdf(report: dict, path, figures: dict) -> None:
    """Print the report's QTextDocument on an A4 ``QPdfWriter`` at ``path``."""
    from PySide6.QtCore import QMarginsF, QSizeF, QUrl
    from PySide6.QtGui import QPageLayout, QPageSize, QPdfWriter, QTextDocument
    doc = QTextDocument()
    srcs = {}
    for name, im in figures.items():
        url = f"figure-{name}.png"
        doc.addResource(QTextDocument.ResourceType.ImageResource, QUrl(url), im)
        srcs[name] = url
    doc.setHtml(report_html(report, srcs))
    writer = QPdfWriter(str(path))
    writer.setTitle("prismstation residual report")
    writer.setCreator(str(report.get("program") or "prismstation"))
    writer.setPageLayout(QPageLayout(QPageSize(QPageSize.PageSizeId.A4),
                                     QPageLayout.Orientation.Portrait,
                                     QMarginsF(15, 15, 15, 15), QPageLayout.Unit.Millimeter))
    writer.setResolution(96)  # lay out in CSS pixels; images keep their own pixels
    doc.setPageSize(QSizeF(writer.width(), writer.height()))
    doc.print_(writer)
    del writer  # flushes and closes the file
