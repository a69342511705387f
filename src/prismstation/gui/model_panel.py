"""Model panel: bias and parallax model choice, coefficients with σ, σ0, the statistics laid out
as the paper's Tables 1–3, blunders and messages.

Reads a :class:`~prismstation.core.solve.Solution`; a change of the choices is emitted as new
:class:`~prismstation.core.solve.Settings` (the window turns it into an undoable command).
"""
from __future__ import annotations

import html
import math
from dataclasses import replace

from PySide6.QtCore import Signal
from PySide6.QtWidgets import (QComboBox, QDoubleSpinBox, QFormLayout, QHBoxLayout, QTextBrowser,
                               QVBoxLayout, QWidget)

from prismstation.core.prism import BIAS_MODELS, PARALLAX_MODELS

CSS = """
body { font-family: sans-serif; font-size: 9pt; }
h3 { margin: 8px 0 2px 0; font-size: 9.5pt; color: #1d3c6e; }
table { border-collapse: collapse; }
th { background: #dde4ee; padding: 1px 6px; font-weight: 600; text-align: right; }
th.l, td.l { text-align: left; }
td { padding: 1px 6px; text-align: right; }
.warn { color: #a04000; }
.bad { color: #c00000; font-weight: bold; }
.dim { color: #777; }
"""


def _f(v, nd=2, sign=False) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "—"
    return f"{v:+.{nd}f}" if sign else f"{v:.{nd}f}"


def _table(head: list[str], rows: list[list[str]]) -> str:
    h = "".join(f"<th class='l'>{c}</th>" if i == 0 else f"<th>{c}</th>" for i, c in enumerate(head))
    body = "".join("<tr>" + "".join(f"<td class='l'>{c}</td>" if i == 0 else f"<td>{c}</td>"
                                    for i, c in enumerate(r)) + "</tr>" for r in rows)
    return f"<table cellspacing='0'><tr>{h}</tr>{body}</table>"


def _stat_rows(cols, stats=("n", "min", "max", "mean", "rms")) -> list[list[str]]:
    """``cols``: ComponentStats per column."""
    return [[s] + [str(c.n) if s == "n" else _f(getattr(c, s)) for c in cols] for s in stats]


def solution_html(sol) -> str:
    """The panel's text for a solution (HTML)."""
    if sol is None:
        return "<p class='dim'>No fit yet.</p>"
    out = [f"<style>{CSS}</style>"]
    ref = sol.reference_view
    # ---- coefficients
    for v, fit in sol.bias.items():
        s0 = fit.sigma0
        dof = fit.lsq.dof if fit.lsq is not None else None
        title = f"Bias {v} ({fit.model})" + (f" — σ0 = {_f(s0, 3)} px, dof {dof}" if s0 is not None else "")
        if not len(fit.names):
            out.append(f"<h3>{title}</h3><p class='dim'>not fitted</p>")
            continue
        rows = [[n, f"{p:+.6g}", f"{s:.2g}"] for n, p, s in zip(fit.names, fit.params, fit.std)]
        out.append(f"<h3>{title}</h3>" + _table(["", "value", "σ"], rows))
    par = sol.parallax
    if par is not None:
        s0 = par.sigma0
        out.append(f"<h3>Parallax line h = c0 + c1·py ({par.used})"
                   + (f" — σ0 = {_f(s0)} m" if s0 is not None else "") + "</h3>")
        out.append(_table(["", "value", "σ", "theory"],
                          [["c0 (m)", _f(par.c0, 2, True), _f(par.std_c0), "0"],
                           ["c1 (m/px)", _f(par.c1, 4), _f(par.std_c1, 4), _f(par.c1_theory, 4)]]))
    st = sol.stats
    # ---- Table 1: image residuals of the reference view (m)
    img = st.get("image", {}).get(ref, {})
    if img:
        g, i = img["GCP"]["m"], img["ICP"]["m"]
        rows = _stat_rows([g.x, g.y, i.x, i.y])
        rows.append(["plan. RMS", "", _f(g.planimetric_rms), "", _f(i.planimetric_rms)])
        out.append(f"<h3>Table 1 — image residuals, view {ref} (m)</h3>"
                   + _table(["", "GCP Rx", "GCP Ry", "ICP Rx", "ICP Ry"], rows))
    # ---- Table 2: across-track differences to N (px)
    if "F-N" in st:
        out.append("<h3>Table 2 — across-track differences to N (px)</h3>"
                   + _table(["", "F−N", "B−N"], _stat_rows([st["F-N"], st["B-N"]],
                                                           ("n", "min", "max", "mean", "std"))))
    if "height" in st and sol.scene.is_triplet:
        out.append("<h3>Table 3 — height residuals (m)</h3>"
                   + _table(["", "GCP Rh", "ICP Rh"], _stat_rows([st["height"]["GCP"], st["height"]["ICP"]])))
    if "ground" in st:
        g, i = st["ground"]["GCP"], st["ground"]["ICP"]
        rows = _stat_rows([g.x, g.y, i.x, i.y], ("n", "mean", "rms"))
        rows.append(["plan. RMS", "", _f(g.planimetric_rms), "", _f(i.planimetric_rms)])
        out.append("<h3>Ground residuals, estimated − known (m)</h3>"
                   + _table(["", "GCP dE", "GCP dN", "ICP dE", "ICP dN"], rows))
    bl = [r for r in sol.points if r.blunder]
    for r in bl:
        out.append(f"<p class='bad'>Possible blunder: {html.escape(r.id)} (standardised residual "
                   f"{_f(r.std_residual)} &gt; {_f(sol.settings.blunder_threshold, 1)})</p>")
    for m in sol.messages:
        out.append(f"<p class='warn'>{html.escape(m)}</p>")
    return "\n".join(out)


class ModelPanel(QWidget):
    """Model choices and the fit's numbers.

    Signals
    -------
    settings_requested(Settings)
        The operator changed a choice (not emitted for :meth:`set_settings`).
    """

    settings_requested = Signal(object)

    def __init__(self, parent=None):
        super().__init__(parent)
        self.bias = QComboBox()
        self.bias.addItems(list(BIAS_MODELS))
        self.parallax = QComboBox()
        self.parallax.addItems(list(PARALLAX_MODELS))
        self.sigma = QDoubleSpinBox(decimals=2, minimum=0.01, maximum=100.0, singleStep=0.1, suffix=" px")
        self.threshold = QDoubleSpinBox(decimals=2, minimum=1.0, maximum=20.0, singleStep=0.5)
        form = QFormLayout()
        form.addRow("Bias model", self.bias)
        form.addRow("Parallax model", self.parallax)
        row = QHBoxLayout()
        row.addWidget(self.sigma)
        row.addWidget(self.threshold)
        form.addRow("σ a priori / blunder at", row)
        self.text = QTextBrowser()
        self.text.setOpenLinks(False)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(4, 4, 4, 4)
        lay.addLayout(form)
        lay.addWidget(self.text, 1)
        self._settings = None
        self.solution = None
        self.bias.activated.connect(self._emit)
        self.parallax.activated.connect(self._emit)
        self.sigma.editingFinished.connect(self._emit)
        self.threshold.editingFinished.connect(self._emit)

    def set_settings(self, settings) -> None:
        """Show ``settings`` without emitting."""
        self._settings = settings
        for w in (self.bias, self.parallax, self.sigma, self.threshold):
            w.blockSignals(True)
        self.bias.setCurrentText(settings.bias_model)
        self.parallax.setCurrentText(settings.parallax_model)
        self.sigma.setValue(settings.sigma_px)
        self.threshold.setValue(settings.blunder_threshold)
        for w in (self.bias, self.parallax, self.sigma, self.threshold):
            w.blockSignals(False)

    def set_solution(self, sol) -> None:
        self.solution = sol
        if sol is not None:
            self.set_settings(sol.settings)
        sb = self.text.verticalScrollBar().value()
        self.text.setHtml(solution_html(sol))
        self.text.verticalScrollBar().setValue(sb)

    def _emit(self, *_) -> None:
        if self._settings is None:
            return
        new = replace(self._settings, bias_model=self.bias.currentText(),
                      parallax_model=self.parallax.currentText(), sigma_px=float(self.sigma.value()),
                      blunder_threshold=float(self.threshold.value()))
        if new != self._settings:
            self.settings_requested.emit(new)
