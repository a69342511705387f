"""Model panel: bias and parallax model choice, coefficients with σ, σ0, the statistics laid out
as the paper's Tables 1–3, blunders and messages.

The choices are the scene's sensor model's (:meth:`ModelPanel.set_sensor`,
:mod:`prismstation.core.models.sensor`): its bias models; its height–parallax models, the row hidden
where it has none (RPC images: points are intersected); the view held fixed where the model
holds one as the datum. Reads a :class:`~prismstation.core.models.solution.Solution`; a change of the
choices is emitted as new :class:`~prismstation.core.models.solution.Settings` (the window turns it into
an undoable command).
"""
from __future__ import annotations

from dataclasses import replace

from PySide6.QtCore import QEvent, QRect, QSize, Qt, Signal
from PySide6.QtGui import QColor, QFont, QFontMetrics, QPainter, QPalette
from PySide6.QtWidgets import (QCheckBox, QComboBox, QDoubleSpinBox, QFormLayout, QHBoxLayout, QLabel,
                               QPushButton, QScrollArea, QSizePolicy, QVBoxLayout, QWidget)

from prismstation.core.models.prism import BIAS_MODELS, PARALLAX_MODELS
from prismstation.gui.fit_checks import blunder_test
from prismstation.gui.sensors import parts_of
from prismstation.gui.static_text import StaticTexts
from prismstation.io.formatting import fixed
from prismstation.ops.fit import DEFAULT_REFERENCE_SIGMA_M

SECTION_COLOR = QColor("#1d3c6e")
HEAD_BG = QColor("#dde4ee")
BAD_COLOR = QColor("#c00000")
WARN_COLOR = QColor("#a04000")
EVERY_VIEW = "every view"  # the bias-view choice that shows and sets the settings' bias_model
AUTO_FIXED = "auto"  # the fixed-view choice that holds none fixed by name (the model decides)


def _stat_rows(cols, stats=("n", "min", "max", "mean", "rms")) -> list[list[str]]:
    """``cols``: ComponentStats per column."""
    return [[s] + [str(c.n) if s == "n" else fixed(getattr(c, s)) for c in cols] for s in stats]


def solution_sections(sol) -> tuple[list, list]:
    """What the panel shows: ``([(title, head, rows), ...], [(text, severity), ...])`` with
    ``rows`` lists of strings; severity ``"bad"`` (a blunder, a parallax model that does not fit
    the GCPs), ``"warn"`` (engine message) or ``"info"``."""
    if sol is None:
        return [], [("No fit yet.", "warn")]
    sections = []
    for v, fit in sol.bias.items():
        s0 = fit.sigma0
        dof = fit.lsq.dof if fit.lsq is not None else None
        title = f"Bias {v} ({fit.model})" + (f" — σ0 = {fixed(s0, 3)} px, dof {dof}" if s0 is not None else "")
        rows = [[n, f"{p:+.6g}", f"{sd:.2g}" if sd == sd else "—"] for n, p, sd in zip(fit.names, fit.params, fit.std)]
        none = "held fixed (the datum)" if getattr(fit, "fixed", False) else "not fitted"
        sections.append((title, ["", "value", "σ"], rows or [[none, "", ""]]))
    own, own_notes = parts_of(sol.scene.sensor).panel_sections(sol)
    sections += own
    st = sol.stats
    ref = sol.reference_view
    img = st.get("image", {}).get(ref, {})
    if img and sol.scene.sensor.height_source != "parallax":
        sections.append(_per_view_table(st["image"]))
    elif img:
        g, i = img["GCP"]["m"], img["ICP"]["m"]
        rows = _stat_rows([g.x, g.y, i.x, i.y])
        rows.append(["plan. RMS", "", fixed(g.planimetric_rms), "", fixed(i.planimetric_rms)])
        sections.append((f"Table 1 — image residuals, view {ref} (m)",
                         ["", "GCP Rx", "GCP Ry", "ICP Rx", "ICP Ry"], rows))
    if "F-N" in st:
        sections.append(("Table 2 — across-track differences to N (px)", ["", "F−N", "B−N"],
                         _stat_rows([st["F-N"], st["B-N"]], ("n", "min", "max", "mean", "std"))))
    if "height" in st and sol.model.heights_fitted:
        sections.append(("Table 3 — height residuals (m)", ["", "GCP Rh", "ICP Rh"],
                         _stat_rows([st["height"]["GCP"], st["height"]["ICP"]])))
    if "ground" in st:
        g, i = st["ground"]["GCP"], st["ground"]["ICP"]
        rows = _stat_rows([g.x, g.y, i.x, i.y], ("n", "mean", "rms"))
        rows.append(["plan. RMS", "", fixed(g.planimetric_rms), "", fixed(i.planimetric_rms)])
        sections.append(("Ground residuals, estimated − known (m)",
                         ["", "GCP dE", "GCP dN", "ICP dE", "ICP dN"], rows))
    test = blunder_test(sol)
    thr = fixed(test.threshold, 2)
    if test.fits:
        sections.append((f"Blunder test — threshold {thr} (α = {test.alpha:.2g}) for every fit",
                         ["fit", "redundancy", "blunder at |w| >"],
                         [[label, str(dof), fixed(c, 2)] for label, dof, c in test.fits]))
    cols = sol.columns
    notes = [(f"Blunder: {cols.ids[i]} — standardised residual {fixed(float(cols.std_residual[i]))} > {thr}", "bad")
             for i, b in enumerate(cols.blunder.tolist()) if b]
    notes += own_notes
    notes += [(m, "warn") for m in sol.messages]
    if test.fits:
        notes.append((test.reason(), "info"))
    return sections, notes


def _per_view_table(image_stats: dict) -> tuple:
    """One row per view: n and RMS x, y (px) of the image residuals of each kind of point the
    fit has (GCP, ICP, tie points) — the table of a model with any number of views."""
    kinds = [k for k in ("GCP", "ICP", "TIE") if all(k in d for d in image_stats.values())]
    rows = [[v] + [t for k in kinds for t in (str(d[k]["px"].x.n), fixed(d[k]["px"].x.rms),
                                             fixed(d[k]["px"].y.rms))]
            for v, d in image_stats.items()]
    return ("Image residuals per view (px)",
            ["view"] + [f"{k} {c}" for k in kinds for c in ("n", "RMS x", "RMS y")], rows)


class _Sections(QWidget):
    """The fit's tables painted in one pass (titles, header rows, cells, notes): no child
    widgets, style sheets or layout, so a refit costs one cheap repaint. Column widths only
    grow while the layout keeps its shape (numbers changing width do not make it jitter)."""

    PAD = 5          # horizontal padding of a cell, px
    TITLE_GAP = 6    # space above a section title, px

    def __init__(self, parent=None):
        super().__init__(parent)
        self._sections: list = []
        self._notes: list = []
        self._widths: list[int] = []
        self._shape = None
        self._hint = QSize(0, 0)
        self._hint_shape = None
        self._advances: dict = {}
        self._note_rects: dict = {}
        self._line_cache = None
        self._bold = QFont(self.font())
        self._bold.setWeight(QFont.Weight.DemiBold)
        self._texts = StaticTexts()  # the cells' texts, laid out once (most come back)
        self.setSizePolicy(QSizePolicy.Policy.Preferred, QSizePolicy.Policy.Fixed)

    def show_sections(self, sections, notes) -> None:
        if sections == self._sections and notes == self._notes:
            return
        shape = [len(h) for _, h, _ in sections]
        ncols = max(shape or [1])
        widths = [0] * ncols if shape != self._shape else list(self._widths)
        for _, head, rows in sections:
            for c, t in enumerate(head):
                widths[c] = max(widths[c], self._advance(t, True) + 2 * self.PAD)
            for r in rows:
                for c, t in enumerate(r):
                    widths[c] = max(widths[c], self._advance(t, False) + 2 * self.PAD)
        before = self._line_cache if widths == self._widths else None
        self._sections, self._notes, self._widths, self._shape = sections, notes, widths, shape
        self._update_hint()
        after = self._line_cache = self._lines()
        if before is None or [(y, h) for y, h, _ in before] != [(y, h) for y, h, _ in after]:
            self.update()  # the layout moved: everything
            return
        # the same layout: repaint the lines whose text changed (a click in N changes the N
        # bias and the statistics, not the F and B fits)
        for (y, h, old), (_, _, new) in zip(before, after):
            if old != new:
                self.update(QRect(0, y, self.width(), h))

    def _lines(self) -> list:
        """``[(y, height, content), ...]`` of every line as :meth:`paintEvent` lays them out."""
        rh, out, y = self._row_height(), [], 2
        first = [n for n in self._notes if n[1] == "bad"]

        def notes(ns, y):
            for text, sev in ns:
                h = self._note_rect(text, sev == "bad").height() + 2
                out.append((y, h, (text, sev)))
                y += h
            return y
        y = notes(first, y)
        for title, head, rows in self._sections:
            y += self.TITLE_GAP
            for line in (title, head, *rows):
                out.append((y, rh, line))
                y += rh
        if first:
            y += self.TITLE_GAP
        notes([n for n in self._notes if n[1] != "bad"], y)
        return out

    def _advance(self, text: str, bold: bool) -> int:
        """Width of ``text`` in pixels (remembered: most texts come back at every refit)."""
        w = self._advances.get((text, bold))
        if w is None:
            if len(self._advances) > 5000:
                self._advances.clear()
            fm = QFontMetrics(self._bold) if bold else self.fontMetrics()
            w = self._advances[text, bold] = fm.horizontalAdvance(text)
        return w

    def _row_height(self) -> int:
        return self.fontMetrics().height() + 2

    def _note_width(self) -> int:
        """The width notes wrap to: what the scroll area shows of the panel (tables wider
        than that scroll sideways, a note read across them was cut at its edge)."""
        seen = self.parentWidget().width() if self.parentWidget() is not None else self.width()
        return max(min(seen, max(self.width(), sum(self._widths))) - 2 * self.PAD - 4, 50)

    def eventFilter(self, obj, ev) -> bool:
        """The scroll area's viewport (installed by :class:`ModelPanel`) changed width: the
        notes wrap anew."""
        if ev.type() == QEvent.Type.Resize and self._notes:
            self._line_cache = None
            self._update_hint()
            self.update()
        return False

    def _note_rect(self, text, bold) -> QRect:
        """The wrapped rectangle of a note (remembered per text and width: a refit asks for
        the same notes several times)."""
        width = self._note_width()
        key = (text, bold, width)
        r = self._note_rects.get(key)
        if r is None:
            if len(self._note_rects) > 500:
                self._note_rects.clear()
            fm = QFontMetrics(self._bold) if bold else self.fontMetrics()
            r = self._note_rects[key] = fm.boundingRect(QRect(0, 0, width, 10000),
                                                        int(Qt.TextFlag.TextWordWrap), text)
        return QRect(r)

    def _update_hint(self) -> None:
        rh = self._row_height()
        h = 4 + sum(self.TITLE_GAP + rh * (2 + len(rows)) for _, _, rows in self._sections)
        h += sum(self._note_rect(t, sev == "bad").height() + 2 for t, sev in self._notes) + self.TITLE_GAP
        # the height only grows while the layout keeps its shape: a note that comes and goes
        # with every click (a blunder) must not relayout the scroll area each time
        if self._shape == self._hint_shape:
            h = max(h, self._hint.height())
        self._hint_shape = self._shape
        hint = QSize(sum(self._widths) + 8, h)
        if hint != self._hint:
            self._hint = hint
            self.updateGeometry()

    def sizeHint(self) -> QSize:
        return self._hint

    def minimumSizeHint(self) -> QSize:
        return self._hint

    def resizeEvent(self, event) -> None:
        self._line_cache = None  # (laid out for the old width)
        if self._notes:  # wrapped notes change height with the width
            self._update_hint()
        super().resizeEvent(event)

    def paintEvent(self, event) -> None:
        """Only the lines inside the exposed region (the scroll area shows a part; a refit
        repaints the lines that changed)."""
        p = QPainter(self)
        rh, pad, x0 = self._row_height(), self.PAD, 4
        region, width = event.region(), self.width()

        def shown(y):
            return region.intersects(QRect(0, y, width, rh))
        total = sum(self._widths)
        text_color = self.palette().color(QPalette.ColorRole.WindowText)
        y = 2
        first = [n for n in self._notes if n[1] == "bad"]   # what is wrong: above the tables
        y = self._paint_notes(p, first, x0, y, region)
        for title, head, rows in self._sections:
            y += self.TITLE_GAP
            if shown(y):
                self._texts.set_font(p, self._bold)
                p.setPen(SECTION_COLOR)
                self._texts.draw(p, x0, y, max(total, self.width()), rh, False, title)
            y += rh
            if shown(y):
                p.fillRect(QRect(x0, y, total, rh), HEAD_BG)
            p.setPen(text_color)
            for r, font in ((head, self._bold), *((row, self.font()) for row in rows)):
                if shown(y):
                    self._texts.set_font(p, font)
                    x = x0
                    for c, t in enumerate(r):
                        w = self._widths[c]
                        self._texts.draw(p, x + pad, y, w - 2 * pad, rh, c > 0, t)
                        x += w
                y += rh
        if first:
            y += self.TITLE_GAP
        self._paint_notes(p, [n for n in self._notes if n[1] != "bad"], x0, y, region)
        p.end()

    def _paint_notes(self, p, notes, x0, y, region) -> int:
        """Draw ``notes`` wrapped from ``y`` down (those in ``region``); the y below them."""
        text_color = self.palette().color(QPalette.ColorRole.WindowText)
        for text, sev in notes:
            bold = sev == "bad"
            rect = self._note_rect(text, bold).translated(x0 + self.PAD, y)
            if region.intersects(rect.adjusted(-x0 - self.PAD, 0, 0, 2)):
                p.setFont(self._bold if bold else self.font())
                p.setPen(BAD_COLOR if bold else WARN_COLOR if sev == "warn" else text_color)
                p.drawText(rect, int(Qt.TextFlag.TextWordWrap), text)
            y += rect.height() + 2
        return y

    def plain_text(self) -> str:
        lines = []
        for title, head, rows in self._sections:
            lines += [title, *head]
            for r in rows:
                lines += r
        return "\n".join(lines + [t for t, _ in self._notes])


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
        # which view the bias model is shown and set for (models with a bias per view): every
        # view (the settings' bias_model), or one (its own, view_bias)
        self.bias_view = QComboBox()
        self.bias_view.addItem(EVERY_VIEW, None)
        self.parallax = QComboBox()
        self.parallax.addItems(list(PARALLAX_MODELS))
        self.fixed = QComboBox()  # the view held fixed (models that hold one): data = view or None
        self.fixed.addItem(AUTO_FIXED, None)
        self.sigma = QDoubleSpinBox(decimals=2, minimum=0.01, maximum=100.0, singleStep=0.1, suffix=" px")
        # models that hold tie points to the reference DEM (images with RPCs): its height σ and
        # whether GCPs enter the fit — the project's stored settings, as `fit --dem-sigma`,
        # `--gcps`/`--no-gcps` set them
        self.ref_sigma = QDoubleSpinBox(decimals=1, minimum=0.1, maximum=500.0, singleStep=1.0, suffix=" m")
        self.use_gcps = QCheckBox("GCPs in the fit")
        self.threshold = QDoubleSpinBox(decimals=2, minimum=1.0, maximum=20.0, singleStep=0.5)
        for w, tip in (
                (self.bias, "How each view's image coordinates are corrected: shift (2 parameters), "
                            "similarity (4) or affine (6); more parameters need more GCPs spread "
                            "over the image"),
                (self.bias_view, "Every view (one model for all), or the one view whose bias model is "
                                 "shown and set"),
                (self.parallax, "Height from the F−B parallax h = c0 + c1·py: line fits c0 and c1 on "
                                "the GCPs, offset fits c0 with the theoretical c1, theoretical "
                                "takes both from the geometry"),
                (self.fixed, "The view whose geolocation is the datum of a fit without GCPs: its "
                             "bias is not fitted and the others' are relative to it (auto: the "
                             "first view when there is no GCP, none with GCPs)"),
                (self.ref_sigma, "σ of the reference DEM's heights the tie points are held to when GCPs "
                                 "are too few (before the slope term: its cell on a slope adds "
                                 "slope × cell / √12)"),
                (self.use_gcps, "Unticked: GCPs are only checked (their residuals shown), the biases come "
                                "from the tie points and the reference DEM"),
                (self.sigma, "A-priori σ of one image measurement (pixels): weights the fit and "
                             "scales the standardised residuals; σ0 near 1× this means the "
                             "measurements are as good as assumed"),
                (self.threshold, "A GCP whose standardised residual exceeds this is flagged as a "
                                 "blunder: 3.29 tests at α = 0.001. Residuals are shown on the "
                                 "normal scale, so this one figure holds for every fit; the "
                                 "critical |w| it means for each fit's redundancy (Student's t) "
                                 "is listed under Blunder test")):
            w.setToolTip(tip)
        form = self.form = QFormLayout()
        brow = QHBoxLayout()
        brow.addWidget(self.bias, 1)
        brow.addWidget(self.bias_view, 1)
        form.addRow("Bias model", brow)
        form.addRow("Parallax model", self.parallax)
        form.addRow("View held fixed", self.fixed)
        form.addRow("Reference DEM σ", self.ref_sigma)
        form.addRow("", self.use_gcps)
        for w in (self.ref_sigma, self.use_gcps):  # shown for a model that holds tie points (set_sensor)
            form.setRowVisible(w, False)
        self.bias_view.setVisible(False)
        row = QHBoxLayout()
        row.addWidget(self.sigma)
        row.addWidget(self.threshold)
        form.addRow("σ a priori / blunder at", row)
        self.geoid = QLabel("—")
        self.geoid.setWordWrap(True)
        self.geoid.setToolTip("The geoid that makes orthometric heights ellipsoidal (h = H + N)")
        self.geoid_button = QPushButton("Change…")
        self.geoid_button.setToolTip("Choose a constant undulation or a geoid grid file")
        self.geoid_button.clicked.connect(self.geoid_requested)
        grow = QHBoxLayout()
        grow.addWidget(self.geoid, 1)
        grow.addWidget(self.geoid_button)
        form.addRow("Geoid", grow)
        self.sections = _Sections()
        self.text = QScrollArea()
        self.text.setWidgetResizable(True)
        self.text.setWidget(self.sections)
        self.text.viewport().installEventFilter(self.sections)  # (its width wraps the notes)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(4, 4, 4, 4)
        lay.addLayout(form)
        lay.addWidget(self.text, 1)
        self._settings = None
        self.solution = None
        self.bias.activated.connect(self._emit)
        self.bias_view.activated.connect(self._show_bias)
        self.parallax.activated.connect(self._emit)
        self.fixed.activated.connect(self._emit)
        self.ref_sigma.editingFinished.connect(self._emit)
        self.use_gcps.toggled.connect(self._emit)
        self.sigma.editingFinished.connect(self._emit)
        self.threshold.editingFinished.connect(self._emit)

    def set_sensor(self, sensor, views) -> None:
        """Offer the choices of sensor model class ``sensor`` (:mod:`prismstation.core.models.sensor`)
        on a scene of ``views`` (names, in order): its bias models, its parallax models (the row
        hidden when it has none), the view held fixed (the row shown when it holds one)."""
        self._settings = None  # shown again from the next settings
        for combo, items in ((self.bias, list(sensor.bias_models)), (self.parallax, list(sensor.parallax_models))):
            if [combo.itemText(i) for i in range(combo.count())] != items:
                combo.clear()
                combo.addItems(items)
        self.fixed.clear()
        self.fixed.addItem(AUTO_FIXED, None)
        self.bias_view.clear()
        self.bias_view.addItem(EVERY_VIEW, None)
        for v in views:
            self.fixed.addItem(v, v)
            self.bias_view.addItem(v, v)
        self.bias_view.setVisible(bool(sensor.holds_view_fixed))
        self.form.setRowVisible(self.parallax, bool(sensor.parallax_models))
        self.form.setRowVisible(self.fixed, bool(sensor.holds_view_fixed))
        self.form.setRowVisible(self.ref_sigma, bool(sensor.holds_view_fixed))
        self.form.setRowVisible(self.use_gcps, bool(sensor.holds_view_fixed))

    def set_settings(self, settings) -> None:
        """Show ``settings`` without emitting (nothing is touched when they are unchanged: a
        spin box set to its own value still repaints)."""
        if settings == self._settings:
            return
        self._settings = settings
        for w in (self.bias, self.parallax, self.fixed, self.sigma, self.threshold, self.ref_sigma, self.use_gcps):
            w.blockSignals(True)
        self._show_bias()
        self.parallax.setCurrentText(settings.parallax_model)
        self.fixed.setCurrentIndex(max(self.fixed.findData(settings.fixed_view), 0))
        self.sigma.setValue(settings.sigma_px)
        self.threshold.setValue(settings.blunder_threshold)
        self.ref_sigma.setValue(DEFAULT_REFERENCE_SIGMA_M if settings.reference_sigma_m is None
                                else settings.reference_sigma_m)
        self.use_gcps.setChecked(settings.use_gcps)
        for w in (self.bias, self.parallax, self.fixed, self.sigma, self.threshold, self.ref_sigma, self.use_gcps):
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

    def _show_bias(self, *_) -> None:
        """The bias combo shows the model of the view chosen beside it (every view's: the settings')."""
        if self._settings is None:
            return
        v = self.bias_view.currentData()
        self.bias.blockSignals(True)
        self.bias.setCurrentText(self._settings.bias_model if v is None else self._settings.bias_of(v))
        self.bias.blockSignals(False)

    def _emit(self, *_) -> None:
        if self._settings is None:
            return
        v, chosen = self.bias_view.currentData(), self.bias.currentText()
        every = chosen if v is None else self._settings.bias_model
        own = {} if v is None else {**dict(self._settings.view_bias), v: chosen}  # every view: one model
        view_bias = tuple(sorted((k, m) for k, m in own.items() if m != every))
        new = replace(self._settings, bias_model=every, view_bias=view_bias,
                      parallax_model=self.parallax.currentText() or self._settings.parallax_model,
                      fixed_view=self.fixed.currentData(), sigma_px=float(self.sigma.value()),
                      blunder_threshold=float(self.threshold.value()), use_gcps=self.use_gcps.isChecked())
        ref = round(float(self.ref_sigma.value()), 1)
        if self._settings.reference_sigma_m is not None or ref != DEFAULT_REFERENCE_SIGMA_M:
            new = replace(new, reference_sigma_m=ref)
        if new != self._settings:
            self.settings_requested.emit(new)
