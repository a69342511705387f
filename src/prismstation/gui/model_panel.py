"""Model panel: bias and parallax model choice, coefficients with σ, σ0, the statistics laid out
as the paper's Tables 1–3, blunders and messages.

Reads a :class:`~prismstation.core.solve.Solution`; a change of the choices is emitted as new
:class:`~prismstation.core.solve.Settings` (the window turns it into an undoable command).
"""
from __future__ import annotations

import math
from dataclasses import replace

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (QComboBox, QDoubleSpinBox, QFormLayout, QGridLayout, QHBoxLayout,
                               QLabel, QPushButton, QScrollArea, QVBoxLayout, QWidget)

from prismstation.core.prism import BIAS_MODELS, PARALLAX_MODELS

SECTION_STYLE = "font-weight: 600; color: #1d3c6e; padding-top: 6px;"
HEAD_STYLE = "background: #dde4ee; padding: 1px 5px; font-weight: 600;"
CELL_STYLE = "padding: 0px 5px;"


def _f(v, nd=2, sign=False) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "—"
    return f"{v:+.{nd}f}" if sign else f"{v:.{nd}f}"


def _stat_rows(cols, stats=("n", "min", "max", "mean", "rms")) -> list[list[str]]:
    """``cols``: ComponentStats per column."""
    return [[s] + [str(c.n) if s == "n" else _f(getattr(c, s)) for c in cols] for s in stats]


def solution_sections(sol) -> tuple[list, list]:
    """What the panel shows: ``([(title, head, rows), ...], [(text, severity), ...])`` with
    ``rows`` lists of strings; severity ``"bad"`` (blunder) or ``"warn"`` (engine message)."""
    if sol is None:
        return [], [("No fit yet.", "warn")]
    sections = []
    for v, fit in sol.bias.items():
        s0 = fit.sigma0
        dof = fit.lsq.dof if fit.lsq is not None else None
        title = f"Bias {v} ({fit.model})" + (f" — σ0 = {_f(s0, 3)} px, dof {dof}" if s0 is not None else "")
        rows = [[n, f"{p:+.6g}", f"{sd:.2g}" if sd == sd else "—"] for n, p, sd in zip(fit.names, fit.params, fit.std)]
        sections.append((title, ["", "value", "σ"], rows or [["not fitted", "", ""]]))
    par = sol.parallax
    if par is not None:
        s0 = par.sigma0
        sections.append((f"Parallax line h = c0 + c1·py ({par.used})" + (f" — σ0 = {_f(s0)} m" if s0 is not None else ""),
                         ["", "value", "σ", "theory"],
                         [["c0 (m)", _f(par.c0, 2, True), _f(par.std_c0), "0"],
                          ["c1 (m/px)", _f(par.c1, 4), _f(par.std_c1, 4), _f(par.c1_theory, 4)]]))
    st = sol.stats
    ref = sol.reference_view
    img = st.get("image", {}).get(ref, {})
    if img:
        g, i = img["GCP"]["m"], img["ICP"]["m"]
        rows = _stat_rows([g.x, g.y, i.x, i.y])
        rows.append(["plan. RMS", "", _f(g.planimetric_rms), "", _f(i.planimetric_rms)])
        sections.append((f"Table 1 — image residuals, view {ref} (m)",
                         ["", "GCP Rx", "GCP Ry", "ICP Rx", "ICP Ry"], rows))
    if "F-N" in st:
        sections.append(("Table 2 — across-track differences to N (px)", ["", "F−N", "B−N"],
                         _stat_rows([st["F-N"], st["B-N"]], ("n", "min", "max", "mean", "std"))))
    if "height" in st and sol.scene.is_triplet:
        sections.append(("Table 3 — height residuals (m)", ["", "GCP Rh", "ICP Rh"],
                         _stat_rows([st["height"]["GCP"], st["height"]["ICP"]])))
    if "ground" in st:
        g, i = st["ground"]["GCP"], st["ground"]["ICP"]
        rows = _stat_rows([g.x, g.y, i.x, i.y], ("n", "mean", "rms"))
        rows.append(["plan. RMS", "", _f(g.planimetric_rms), "", _f(i.planimetric_rms)])
        sections.append(("Ground residuals, estimated − known (m)",
                         ["", "GCP dE", "GCP dN", "ICP dE", "ICP dN"], rows))
    notes = [(f"Possible blunder: {r.id} (standardised residual {_f(r.std_residual)}, threshold "
              f"{_f(sol.settings.blunder_threshold, 2)})", "bad") for r in sol.points if r.blunder]
    notes += [(m, "warn") for m in sol.messages]
    return sections, notes


class _Sections(QWidget):
    """Titled grids of plain-text labels; :meth:`show_sections` only sets texts when the
    layout is unchanged (a click repaints in a millisecond, unlike rich-text documents)."""

    def __init__(self, parent=None):
        super().__init__(parent)
        self.grid = QGridLayout(self)
        self.grid.setContentsMargins(4, 2, 4, 2)
        self.grid.setHorizontalSpacing(0)
        self.grid.setVerticalSpacing(0)
        self._shape = None
        self._labels: list[QLabel] = []
        self._notes: list[QLabel] = []

    @staticmethod
    def _label(style="", align=Qt.AlignmentFlag.AlignRight):
        lab = QLabel()
        lab.setTextFormat(Qt.TextFormat.PlainText)
        lab.setStyleSheet(style)
        lab.setAlignment(align | Qt.AlignmentFlag.AlignVCenter)
        return lab

    def show_sections(self, sections, notes) -> None:
        shape = ([(len(h), len(r)) for _, h, r in sections], len(notes))
        if shape != self._shape:
            self._rebuild(sections, notes)
            self._shape = shape
        self.setUpdatesEnabled(False)  # one repaint for the whole batch of labels
        try:
            self._set_texts(sections, notes)
        finally:
            self.setUpdatesEnabled(True)

    def _set_texts(self, sections, notes) -> None:
        texts = []
        for title, head, rows in sections:
            texts.append(title)
            texts += head
            for r in rows:
                texts += r
        for lab, t in zip(self._labels, texts):
            if lab.text() != t:
                lab.setText(t)
        for lab, (t, sev) in zip(self._notes, notes):
            lab.setText(t)
            lab.setStyleSheet("color: #c00000; font-weight: bold;" if sev == "bad" else "color: #a04000;")

    def _rebuild(self, sections, notes) -> None:
        while self.grid.count():
            w = self.grid.takeAt(0).widget()
            if w is not None:
                w.deleteLater()
        self._labels, self._notes = [], []
        row = 0
        left = Qt.AlignmentFlag.AlignLeft
        ncols = max([len(h) for _, h, _ in sections] or [1])
        for _, head, rows in sections:
            t = self._label(SECTION_STYLE, left)
            self.grid.addWidget(t, row, 0, 1, ncols)
            self._labels.append(t)
            row += 1
            for c in range(len(head)):
                lab = self._label(HEAD_STYLE, left if c == 0 else Qt.AlignmentFlag.AlignRight)
                self.grid.addWidget(lab, row, c)
                self._labels.append(lab)
            row += 1
            for r in rows:
                for c in range(len(r)):
                    lab = self._label(CELL_STYLE, left if c == 0 else Qt.AlignmentFlag.AlignRight)
                    self.grid.addWidget(lab, row, c)
                    self._labels.append(lab)
                row += 1
        for _ in notes:
            lab = self._label("", left)
            lab.setWordWrap(True)
            self.grid.addWidget(lab, row, 0, 1, ncols)
            self._notes.append(lab)
            row += 1
        self.grid.setRowStretch(row, 1)
        self.grid.setColumnStretch(ncols, 1)

    def plain_text(self) -> str:
        return "\n".join(lab.text() for lab in self._labels + self._notes)


class ModelPanel(QWidget):
    """Model choices and the fit's numbers.

    Signals
    -------
    settings_requested(Settings)
        The operator changed a choice (not emitted for :meth:`set_settings`).
    geoid_requested()
        The operator asked to change the geoid (the geoid tool answers).
    """

    settings_requested = Signal(object)
    geoid_requested = Signal()

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
        self.geoid = QLabel("—")
        self.geoid.setWordWrap(True)
        self.geoid.setToolTip("The geoid that makes orthometric heights ellipsoidal (h = H + N)")
        self.geoid_button = QPushButton("Change…")
        self.geoid_button.clicked.connect(self.geoid_requested)
        grow = QHBoxLayout()
        grow.addWidget(self.geoid, 1)
        grow.addWidget(self.geoid_button)
        form.addRow("Geoid", grow)
        self.sections = _Sections()
        self.text = QScrollArea()
        self.text.setWidgetResizable(True)
        self.text.setWidget(self.sections)
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
        self.sections.show_sections(*solution_sections(sol))

    def set_geoid(self, text: str, error: bool = False) -> None:
        """Show the active geoid (``error``: it cannot be used, in red)."""
        self.geoid.setText(text)
        self.geoid.setStyleSheet("color: #c00000;" if error else "")

    def plain_text(self) -> str:
        """Everything the panel shows, one label per line (tests, clipboard)."""
        return f"Geoid: {self.geoid.text()}\n" + self.sections.plain_text()

    def _emit(self, *_) -> None:
        if self._settings is None:
            return
        new = replace(self._settings, bias_model=self.bias.currentText(),
                      parallax_model=self.parallax.currentText(), sigma_px=float(self.sigma.value()),
                      blunder_threshold=float(self.threshold.value()))
        if new != self._settings:
            self.settings_requested.emit(new)
