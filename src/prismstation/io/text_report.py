"""The residual report as plain text for the terminal: the header and the statistics of the
report dict (:func:`prismstation.io.report.report_dict`); the points are in its other formats."""
from __future__ import annotations

from prismstation.core.models.scene import reference_view
from prismstation.io.formatting import fixed


def _table(title, cols, rows) -> list[str]:
    w = max(len(r[0]) for r in rows) if rows else 8
    out = [title, " " * (w + 2) + "".join(f"{c:>11}" for c in cols)]
    out += [f"{r[0]:<{w + 2}}" + "".join(f"{x:>11}" for x in r[1:]) for r in rows]
    return out + [""]


def format_report(r: dict) -> str:
    h = r.get("header") or {}
    sids, pids = h.get("scene_ids") or {}, h.get("product_ids") or {}
    products = ", ".join(f"{v} {' '.join(x for x in (sids.get(v), pids.get(v)) if x)}"
                         for v in dict.fromkeys([*sids, *pids]))
    lines = [f"{h.get('title', 'ALOS-PRISM orientation report')} — {r.get('project') or ''}",
             f"{str(h.get('created', '')).replace('T', ' ').replace('Z', ' UTC')}  operator {h.get('operator', '—')}  {h.get('software', r.get('program', ''))}",
             f"scene {h.get('scene_id') or '—'}" + (f"  products {products}" if products else "")
             + f"  orientation from {h.get('orientation', 'GCP')}",
             f"CRS {r['crs']}  geoid {r.get('geoid')}  heights ellipsoidal", ""]
    par = r["model"].get("parallax")
    biases = r["model"]["bias"]
    b = biases.get("N") or next(iter(biases.values()))
    # the PRISM model (heights from the parallax line): the reference view's bias; a model
    # intersecting rays: every view's
    from_parallax = r["model"].get("height_source", "parallax") == "parallax"
    for view, b in ([(None, b)] if from_parallax else list(biases.items())):
        head = f"Bias compensation ({b['model']})" + (f", view {view}" if view else "")
        if b.get("fixed"):
            lines.append(f"{head}: held fixed (the datum)")
            continue
        lines.append(f"{head}, σ0 = {fixed(b.get('sigma0'), 3)} px  dof = {b.get('dof') if b.get('dof') is not None else '—'}")
        for name, p in b["parameters"].items():
            sd = "" if p["std"] is None else f"  ± {p['std']:.2g}"
            lines.append(f"  {name:>3} = {p['value']:+.6g}{sd}")
    if par:
        lines.append(f"Parallax line ({par['used']}): h = {par['c0']:+.2f} + {par['c1']:.4f}·py"
                     f"   (theoretical c1 = {par['c1_theoretical']:.4f}; σ0 = {fixed(par['sigma0_m'], 2)} m)")
    lines.append("")
    st = r["statistics"]
    if from_parallax:  # the PRISM model: the reference view's residuals in metres, F and B against N
        ref = reference_view(st["image"])
        rows = []
        for stat in ("n", "min", "max", "mean", "rms"):
            row = [stat]
            for kind in ("GCP", "ICP"):
                m = st["image"][ref][kind]["m"]
                for c in ("x", "y"):
                    v = m[c][stat]
                    row.append(str(v) if stat == "n" else fixed(v, sign=True))
            rows.append(row)
        rows.append(["planimetric RMS", "", fixed(st["image"][ref]["GCP"]["m"]["planimetric_rms"], sign=True), "",
                     fixed(st["image"][ref]["ICP"]["m"]["planimetric_rms"], sign=True)])
        lines += _table(f"Table 1. Image residuals, view {ref} (m)", ["GCP Rx", "GCP Ry", "ICP Rx", "ICP Ry"], rows)
        if "F-N" in st:
            rows = [[s] + [fixed(st[k][s], sign=True) if s != "n" else str(st[k][s]) for k in ("F-N", "B-N")]
                    for s in ("n", "min", "max", "mean", "std")]
            lines += _table("Table 2. Across-track differences to N (px)", ["F−N", "B−N"], rows)
            rows = [[s] + [fixed(st["height"][k][s], sign=True) if s != "n" else str(st["height"][k][s]) for k in ("GCP", "ICP")]
                    for s in ("n", "min", "max", "mean", "rms")]
            lines += _table("Table 3. Height residuals, from parallax − known (m)", ["GCP Rh", "ICP Rh"], rows)
    else:  # a model intersecting rays: every view's residuals
        lines += _per_view_table(st)
        rows = [[s] + [fixed(st["height"][k][s], sign=True) if s != "n" else str(st["height"][k][s]) for k in ("GCP", "ICP")]
                for s in ("n", "min", "max", "mean", "rms")]
        lines += _table("Table 2. Height residuals, from intersection − known (m)", ["GCP Rh", "ICP Rh"], rows)
    g = st["ground"]
    rows = [[s] + [fixed(g[k][c][s], sign=True) if s != "n" else str(g[k][c][s]) for k in ("GCP", "ICP") for c in ("x", "y")]
            for s in ("n", "mean", "rms")]
    rows.append(["planimetric RMS", "", fixed(g["GCP"]["planimetric_rms"], sign=True), "", fixed(g["ICP"]["planimetric_rms"], sign=True)])
    lines += _table(f"Table {4 if 'F-N' in st else 2 if from_parallax else 3}. Ground residuals, estimated − known (m)", ["GCP dE", "GCP dN", "ICP dE", "ICP dN"], rows)
    flagged = [p["id"] for p in r["points"] if p.get("blunder")]
    if flagged:
        lines.append("Possible blunder (largest standardised residual): " + ", ".join(flagged))
    lines += [f"note: {m}" for m in r.get("messages", [])]
    return "\n".join(lines)


def _per_view_table(st) -> list[str]:
    """Image residuals per view (px): n and RMS x, y of the GCPs, ICPs and tie points."""
    kinds = [k for k in ("GCP", "ICP", "TIE") if any(k in v for v in st["image"].values())]
    rows = []
    for view, by_kind in st["image"].items():
        row = [view]
        for k in kinds:
            px = by_kind.get(k, {}).get("px") or {"x": {}, "y": {}}
            row += [str(px["x"].get("n", 0)), fixed(px["x"].get("rms"), 3), fixed(px["y"].get("rms"), 3)]
        rows.append(row)
    cols = [f"{k} {c}" for k in kinds for c in ("n", "RMS x", "RMS y")]
    return _table("Table 1. Image residuals per view (px)", cols, rows)
