"""The plot of an orthoimage's check (``prismstation validate-ortho --plot OUT.svg``): an SVG
document, no plotting library.

Left, the ortho (a thumbnail of its overviews) with each point at its known ground position and
an arrow to where the ortho shows it, exaggerated by a stated factor; points not found are
crosses. Right, the displacements (east, north, metres) as a scatter, with the circle of the
expected σ (dashed) and of each kind's RMSE. GCPs blue, ICPs orange, as the window's palette.
"""
from __future__ import annotations

import base64
import html
import math
import warnings

import numpy as np
from rasterio.errors import NotGeoreferencedWarning
from rasterio.io import MemoryFile

from prismstation.io.atomic import write_atomic
from prismstation.io.ortho import read_ortho_overview

COLOURS = {"GCP": "#1f77b4", "ICP": "#ff7f0e", "TIE": "#2ca02c"}
PANEL = 460
MARGIN = 40


def _png(values: np.ndarray) -> bytes:
    """A grey PNG of float32 ``values`` (NaN: transparent black), stretched 2–98 %."""
    ok = np.isfinite(values)
    lo, hi = (np.percentile(values[ok], (2, 98)) if ok.any() else (0.0, 1.0))
    g = np.clip((values - lo) / max(hi - lo, 1e-9) * 255.0, 0, 255)
    g = np.where(ok, g, 0).astype(np.uint8)
    alpha = np.where(ok, 255, 0).astype(np.uint8)
    with warnings.catch_warnings(), MemoryFile() as mem:
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        with mem.open(driver="PNG", width=g.shape[1], height=g.shape[0], count=2, dtype="uint8") as ds:
            ds.write(g, 1)
            ds.write(alpha, 2)
        return mem.read()


def ortho_svg(validation, ortho_path) -> str:
    """The SVG text of ``validation`` (:class:`prismstation.ops.ortho_validate.OrthoValidation`)
    over the ortho ``ortho_path``."""
    values, t = read_ortho_overview(ortho_path, max_px=PANEL)
    rows, cols = values.shape
    scale = PANEL / max(rows, cols)
    w, h = cols * scale, rows * scale
    a, _, c, _, e, f = t

    def to_panel(E, N):
        return MARGIN + (E - c) / a * scale, MARGIN + (N - f) / e * scale
    pts = validation.points
    found = [p for p in pts if p.found]
    dmax = max([math.hypot(*p.d) for p in found] + [validation.expected_sigma_m or 0.0, 1e-3])
    # arrows: the largest displacement drawn 40 panel pixels long, the factor rounded
    k = 10 ** math.floor(math.log10(max(40.0 / (dmax / abs(a) * scale), 1.0)))
    k = max(1.0, k * math.floor(40.0 / (dmax / abs(a) * scale) / k))
    png = base64.b64encode(_png(values)).decode("ascii")
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{2 * PANEL + 3 * MARGIN}" height="{PANEL + 2 * MARGIN + 30}" '
           'font-family="sans-serif" font-size="12">',
           '<rect width="100%" height="100%" fill="white"/>',
           f'<text x="{MARGIN}" y="24" font-size="14">{html.escape(_title(validation))}</text>',
           f'<image x="{MARGIN}" y="{MARGIN}" width="{w:.1f}" height="{h:.1f}" preserveAspectRatio="none" '
           f'href="data:image/png;base64,{png}"/>',
           f'<rect x="{MARGIN}" y="{MARGIN}" width="{w:.1f}" height="{h:.1f}" fill="none" stroke="#888"/>']
    for p in pts:
        x, y = to_panel(*p.known)
        col = COLOURS.get(p.kind, "#444")
        if not p.found:
            out.append(f'<path d="M{x - 4:.1f},{y - 4:.1f}L{x + 4:.1f},{y + 4:.1f}M{x - 4:.1f},{y + 4:.1f}'
                       f'L{x + 4:.1f},{y - 4:.1f}" stroke="red" stroke-width="1.5"><title>{html.escape(p.id)}: '
                       f'{html.escape(p.reason or p.status)}</title></path>')
            continue
        x1, y1 = to_panel(p.known[0] + k * p.d[0], p.known[1] + k * p.d[1])
        out.append(f'<circle cx="{x:.1f}" cy="{y:.1f}" r="3" fill="{col}"><title>{html.escape(p.id)} {p.kind}: '
                   f'{p.d[0]:+.2f} m E, {p.d[1]:+.2f} m N</title></circle>')
        out.append(f'<line x1="{x:.1f}" y1="{y:.1f}" x2="{x1:.1f}" y2="{y1:.1f}" stroke="{col}" stroke-width="1.5"/>')
    out.append(f'<text x="{MARGIN}" y="{MARGIN + PANEL + 20}">arrows: known position → where the ortho shows '
               f'it, × {k:g}; red ×: not found</text>')
    out.extend(_scatter(validation, 2 * MARGIN + PANEL, MARGIN, dmax))
    out.append("</svg>")
    return "\n".join(out) + "\n"


def _title(v) -> str:
    parts = []
    for kind, s in v.stats.items():
        if s.get("n"):
            parts.append(f"{kind} {s['rmse_m']:.2f} m RMS ({s['n']})")
    exp = f"; expected σ {v.expected_sigma_m:.2f} m" if v.expected_sigma_m is not None else ""
    return f"Ortho of view {v.view}: where it shows the points — " + ", ".join(parts) + exp


def _scatter(v, x0, y0, dmax):
    lim = 1.15 * dmax
    s = PANEL / (2 * lim)
    cx, cy = x0 + PANEL / 2, y0 + PANEL / 2
    out = [f'<rect x="{x0}" y="{y0}" width="{PANEL}" height="{PANEL}" fill="none" stroke="#888"/>',
           f'<line x1="{x0}" y1="{cy}" x2="{x0 + PANEL}" y2="{cy}" stroke="#ccc"/>',
           f'<line x1="{cx}" y1="{y0}" x2="{cx}" y2="{y0 + PANEL}" stroke="#ccc"/>']
    if v.expected_sigma_m:
        out.append(f'<circle cx="{cx}" cy="{cy}" r="{v.expected_sigma_m * s:.1f}" fill="none" stroke="#444" '
                   'stroke-dasharray="4 3"><title>expected σ</title></circle>')
    for kind, st in v.stats.items():
        if st.get("n"):
            out.append(f'<circle cx="{cx}" cy="{cy}" r="{st["rmse_m"] * s:.1f}" fill="none" '
                       f'stroke="{COLOURS.get(kind, "#444")}"><title>{kind} RMSE</title></circle>')
    for p in v.points:
        if p.found:
            out.append(f'<circle cx="{cx + p.d[0] * s:.1f}" cy="{cy - p.d[1] * s:.1f}" r="3" '
                       f'fill="{COLOURS.get(p.kind, "#444")}"><title>{html.escape(p.id)}</title></circle>')
    out.append(f'<text x="{x0}" y="{y0 + PANEL + 20}">shown − known (m, east →, north ↑) ±{lim:.2f} m; '
               'dashed: expected σ; rings: RMSE</text>')
    return out


def write_ortho_svg(path, validation, ortho_path) -> None:
    """Write :func:`ortho_svg` at ``path`` (atomic)."""
    write_atomic(path, ortho_svg(validation, ortho_path), keep_backup=False)
