"""Tools ▸ Space resection…: a frame-camera resection of one view on its GCPs, with the
Gauss–Newton history plotted (Subaryono et al., Figs 4.1–4.2), and the B/H ratio of two resections
or of two typed sensor positions (docs/model.md §6).

Ground coordinates are the points' ``E, N, H`` (metres, project CRS); image coordinates pixels
(column, row, origin top-left corner). A pushbroom image only approximates a frame camera: the
dialog says so next to every result.

The B/H line says what it stands on: each resection's σ0 and whether it converged (a B/H of
a resection that did not converge is not usable), its σ from the two resections' covariances,
and — for views with a known along-track viewing angle — the B/H that geometry implies
(:func:`geometry_bh`). A level 1B2 PRISM view is resampled to the map grid while its rays look
about 26° forward or backward: no central projection gives both, so a frame resection settles
on a much smaller look angle, with σ0 of several pixels, and its position — hence B — is not
where the satellite was (the demo's N–F: B/H 0.16 from the resections, 0.50 from its 26.4°).
"""
from __future__ import annotations

from html import escape
import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (QComboBox, QDialog, QDoubleSpinBox, QFormLayout, QGridLayout,
                               QGroupBox, QHBoxLayout, QLabel, QPushButton, QRadioButton,
                               QTextBrowser, QVBoxLayout)

from prismstation.core.models.resection import PUSHBROOM_NOTE, FrameCamera, base_height, resect
from prismstation.errors import PrismError
from prismstation.gui.plot_figures import legend_below
from prismstation.gui.titles import fit_title
from prismstation.gui.tools._rect_common import view_points
from prismstation.io.report import scene_identity

ANGLE_COLOURS = ("#d62728", "#2ca02c", "#1f77b4")
PRISM_CAMERA = (1939.0, 7.0)    # PRISM's telescopes: focal length (mm), CCD detector pitch (µm)
GENERIC_CAMERA = (1500.0, 7.0)  # any other project: a start the operator is expected to change


def is_prism(project) -> bool:
    """The project is a PRISM scene: made from a JAXA product, or its scene file names PRISM
    scene or product ids (``ALPSM…``) or a 1B2 product level."""
    if project.product:
        return True
    ident = scene_identity(project.scene, project.scene_path)
    ids = [ident["scene_id"] or "", *ident["scene_ids"].values(), *ident["product_ids"].values()]
    return (any(i.upper().startswith("ALPSM") for i in ids)
            or (ident["source"] or "").upper().startswith("JAXA")
            or str(ident["product_level"] or "").upper().startswith("1B2"))


def geometry_bh(scene, left: str, right: str) -> float | None:
    """B/H of two views from their along-track viewing angles at the ground:
    ``|s_L·tan θ_L − s_R·tan θ_R|`` (``s`` +1 forward, −1 backward, 0 nadir); None when the
    scene gives neither view an angle."""
    a, b = scene.views.get(left), scene.views.get(right)
    if a is None or b is None or not (getattr(a, "along_track_angle_deg", None)  # (RPC views: none)
                                      or getattr(b, "along_track_angle_deg", None)):
        return None
    return abs(a.look_sign * a.tan_theta - b.look_sign * b.tan_theta)


def look_angle_deg(res, ground) -> float:
    """The look angle of a resected camera, degrees from the vertical: of the line from the
    centre of the ground points (``ground`` (n, 3) m) to the projection centre."""
    d = res.position - np.asarray(ground, float).mean(axis=0)
    return float(np.degrees(np.arctan2(np.hypot(d[0], d[1]), d[2])))


def bh_sigma(left, right) -> float:
    """σ of B/H from the two resections' position covariances (independent), first order."""
    pl, pr = left.position, right.position
    d = pr - pl
    b = float(np.linalg.norm(d))
    h = float((pl[2] + pr[2]) / 2.0)
    u = d / b
    dz = np.array([0.0, 0.0, 0.5 * b / h ** 2])
    g_r, g_l = u / h - dz, -u / h - dz
    var = g_l @ left.cov[:3, :3] @ g_l + g_r @ right.cov[:3, :3] @ g_r
    return float(np.sqrt(var)) if np.isfinite(var) and var >= 0 else float("nan")


def _spin(lo, hi, value, decimals, suffix="") -> QDoubleSpinBox:
    s = QDoubleSpinBox()
    s.setRange(lo, hi)
    s.setDecimals(decimals)
    s.setValue(value)
    if suffix:
        s.setSuffix(suffix)
    return s


class ResectionDialog(QDialog):
    """Interior orientation in, exterior orientation (± σ) and iteration history out."""

    def __init__(self, ctx):
        super().__init__(ctx.widget)
        self.ctx = ctx
        self.setWindowTitle("Space resection")
        self.results: dict = {}   # view -> ResectionResult
        self.ground: dict = {}    # view -> (n, 3) the GCPs it was resected on
        lay = QHBoxLayout(self)
        left = QVBoxLayout()
        lay.addLayout(left, 0)
        io = QGroupBox("Interior orientation")
        f = QFormLayout(io)
        self.view = QComboBox()
        self.focal = _spin(0.1, 1e5, GENERIC_CAMERA[0], 3, " mm")
        self.pitch = _spin(0.01, 1e4, GENERIC_CAMERA[1], 3, " µm")
        self._defaults_for = None  # the project the interior orientation was last defaulted for
        self.cx = _spin(-1e6, 1e6, 0.0, 2, " px")
        self.cy = _spin(-1e6, 1e6, 0.0, 2, " px")
        f.addRow("View", self.view)
        f.addRow("Focal length", self.focal)
        f.addRow("Pixel pitch", self.pitch)
        f.addRow("Principal point x", self.cx)
        f.addRow("Principal point y", self.cy)
        centre = QPushButton("Principal point at the image centre")
        centre.clicked.connect(self.centre_pp)
        f.addRow(centre)
        run = QPushButton("Resect on the view's GCPs")
        run.clicked.connect(self.run)
        f.addRow(run)
        left.addWidget(io)
        self.text = QTextBrowser()
        self.text.setMinimumWidth(380)
        left.addWidget(self.text, 1)
        note = QLabel("⚠ " + PUSHBROOM_NOTE)
        note.setWordWrap(True)
        note.setStyleSheet("color: #b45309;")
        left.addWidget(note)
        left.addWidget(self._bh_box())
        right = QVBoxLayout()
        lay.addLayout(right, 1)
        self.plot_angles = pg.PlotWidget(title="Corrections of ω, φ, κ per iteration (Fig. 4.1)")
        self.plot_angles.setLabel("left", "correction (°)")
        self.plot_angles.setLabel("bottom", "iteration")
        self.plot_pos = pg.PlotWidget(title="Corrections of X0, Y0, Z0 per iteration (Fig. 4.2)")
        self.plot_pos.setLabel("left", "correction (m)")
        self.plot_pos.setLabel("bottom", "iteration")
        for p in (self.plot_angles, self.plot_pos):
            p.setBackground("w")
            legend_below(p.getPlotItem(), columns=3)  # (inside, it hid the first iterations)
            p.showGrid(x=True, y=True, alpha=0.3)
            right.addWidget(p)
        self.resize(1100, 720)
        fit_title(self)
        self.refresh_views()

    def _bh_box(self) -> QGroupBox:
        box = QGroupBox("B/H")
        g = QGridLayout(box)
        self.bh_two = QRadioButton("from the resections of")
        self.bh_two.setChecked(True)
        self.bh_typed = QRadioButton("from typed positions (X, Y, Z m)")
        self.left_view, self.right_view = QComboBox(), QComboBox()
        g.addWidget(self.bh_two, 0, 0)
        g.addWidget(self.left_view, 0, 1)
        g.addWidget(self.right_view, 0, 2)
        g.addWidget(self.bh_typed, 1, 0, 1, 3)
        self.pos = [[_spin(-1e8, 1e8, 0.0, 2) for _ in range(3)] for _ in range(2)]
        for r, row in enumerate(self.pos):
            g.addWidget(QLabel(("left", "right")[r]), 2 + r, 0)
            for c, s in enumerate(row):
                s.valueChanged.connect(lambda *_: self.bh_typed.setChecked(True))
                g.addWidget(s, 2 + r, 1 + c) if c < 2 else g.addWidget(s, 2 + r, 3)
        b = QPushButton("Compute B/H")
        b.clicked.connect(self.compute_bh)
        g.addWidget(b, 4, 0)
        self.bh_label = QLabel("")
        self.bh_label.setWordWrap(True)
        self.bh_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        g.addWidget(self.bh_label, 4, 1, 1, 3)
        self.bh_note = QLabel("")
        self.bh_note.setWordWrap(True)
        self.bh_note.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        g.addWidget(self.bh_note, 5, 0, 1, 4)
        return box

    def refresh_views(self) -> None:
        p = self.ctx.project
        if p is not None and p is not self._defaults_for:  # a new project: its camera defaults
            self._defaults_for = p
            focal, pitch = PRISM_CAMERA if is_prism(p) else GENERIC_CAMERA
            self.focal.setValue(focal)
            self.pitch.setValue(pitch)
            self.cx.setValue(0.0)  # the principal point goes to the new image's centre below
            self.cy.setValue(0.0)
        names = [] if p is None else list(p.scene.views)
        for c in (self.view, self.left_view, self.right_view):
            cur = c.currentText()
            c.clear()
            c.addItems(names)
            if cur in names:
                c.setCurrentText(cur)
        if len(names) > 1 and self.right_view.currentIndex() == 0:
            self.right_view.setCurrentIndex(1)
        if names and self.cx.value() == 0 and self.cy.value() == 0:
            self.centre_pp()

    def centre_pp(self) -> None:
        iv = self.ctx.views.views.get(self.view.currentText())
        if iv is not None and iv.source is not None:
            self.cx.setValue(iv.source.width / 2.0)
            self.cy.setValue(iv.source.height / 2.0)

    def camera(self) -> FrameCamera:
        return FrameCamera(self.focal.value() / 1000.0, self.pitch.value() * 1e-6,
                           self.cx.value(), self.cy.value())

    def resect_view(self, view: str):
        """Resect ``view`` on its GCPs with the dialog's camera (raises PrismError)."""
        ids, xy, g, chk = view_points(self.ctx.project, view)
        res = resect(self.camera(), xy[~chk], g[~chk])
        self.results[view] = res
        self.ground[view] = g[~chk]
        return res

    def run(self):
        """Resect the chosen view, show the result and plot the history; returns the result."""
        view = self.view.currentText()
        if self.ctx.project is None or not view:
            return None
        try:
            res = self.resect_view(view)
        except PrismError as exc:
            self.text.setHtml(f"<p style='color:#b91c1c'>Resection of {escape(view)} failed: {escape(str(exc))}</p>")
            return None
        self.show_result(view, res)
        return res

    def show_result(self, view: str, res) -> None:
        names = ("X0", "Y0", "Z0", "ω", "φ", "κ")
        rows = []
        for i, n in enumerate(names):
            v, s = res.params[i], res.sigma[i]
            if i < 3:
                rows.append(f"<tr><td>{n}</td><td align=right>{v:.3f} m</td><td align=right>± {s:.3f} m</td></tr>")
            else:
                rows.append(f"<tr><td>{n}</td><td align=right>{np.degrees(v):.6f}°</td>"
                            f"<td align=right>± {np.degrees(s) * 3600:.2f}″</td></tr>")
        rmse = float(np.sqrt(np.mean((res.residuals_px ** 2).sum(axis=1))))
        state = "converged" if res.converged else "<b style='color:#b91c1c'>not converged</b>"
        look = look_angle_deg(res, self.ground[view])
        v = self.ctx.project.scene.views.get(view)
        scene_look = (f" (the scene's viewing angle: {v.along_track_angle_deg:.1f}°)"
                      if getattr(v, "along_track_angle_deg", None) else "")
        self.text.setHtml(
            f"<b>View {view}</b>: {len(res.residuals_px)} GCPs, {len(res.corrections)} iterations, "
            f"{state}<br>σ0 = {res.sigma0_px:.3f} px · RMSE = {rmse:.3f} px<br>"
            f"look angle of the resected camera {look:.1f}°{scene_look}"
            f"<table cellspacing=4>{''.join(rows)}</table>")
        k = np.arange(1, len(res.corrections) + 1)
        self.plot_angles.clear()
        self.plot_pos.clear()
        for i, n in enumerate(("ω", "φ", "κ")):
            self.plot_angles.plot(k, np.degrees(res.corrections[:, 3 + i]), name=f"d{n}",
                                  pen=pg.mkPen(ANGLE_COLOURS[i], width=2), symbol="o",
                                  symbolBrush=ANGLE_COLOURS[i], symbolSize=6)
        for i, n in enumerate(("X0", "Y0", "Z0")):
            self.plot_pos.plot(k, res.corrections[:, i], name=f"d{n}",
                               pen=pg.mkPen(ANGLE_COLOURS[i], width=2), symbol="s",
                               symbolBrush=ANGLE_COLOURS[i], symbolSize=6)

    def compute_bh(self):
        """B/H from two resections (run as needed) or the typed positions; returns BaseHeight.
        The line says what the figure stands on (see the module doc)."""
        self.bh_note.setText("")
        try:
            if self.bh_typed.isChecked():
                a, b = (np.array([s.value() for s in row]) for row in self.pos)
                bh = base_height(a, b)
                self.bh_label.setText(f"B = {bh.base_m:.1f} m, H = {bh.height_m:.1f} m, "
                                      f"<b>B/H = {bh.b_over_h:.4f}</b> (typed positions)")
                return bh
            lv, rv = self.left_view.currentText(), self.right_view.currentText()
            if not lv or lv == rv:
                raise PrismError("choose two different views")
            ra, rb = (self.resect_view(v) for v in (lv, rv))
            bh = base_height(ra.position, rb.position)
        except PrismError as exc:
            self.bh_label.setText(f"<span style='color:#b91c1c'>{escape(str(exc))}</span>")
            return None
        self._show_bh(bh, {lv: ra, rv: rb})
        return bh

    def _show_bh(self, bh, res: dict) -> None:
        (lv, ra), (rv, rb) = res.items()
        sigma = bh_sigma(ra, rb)
        failed = [v for v, r in res.items() if not r.converged]
        state = "; ".join(f"{v} {'converged' if r.converged else 'did NOT converge'} "
                          f"(σ0 {r.sigma0_px:.2f} px)" for v, r in res.items())
        red = "color:#b91c1c; font-weight:bold"
        head = (f"B = {bh.base_m:.0f} m, H = {bh.height_m:.0f} m, <b>B/H = {bh.b_over_h:.4f}</b>"
                + (f" ± {sigma:.3f}" if np.isfinite(sigma) else "") + f" (resections of {lv} and {rv}: {state})")
        if failed:
            head += (f"<br><span style='{red}'>Not a usable B/H: the resection of {' and '.join(failed)} "
                     "did not converge.</span>")
        self.bh_label.setText(head)
        p = self.ctx.project
        implied = geometry_bh(p.scene, lv, rv)
        if implied is None:
            return
        angles = ", ".join(f"{v} {p.scene.views[v].along_track_angle_deg:.1f}°" for v in (lv, rv))
        looks = ", ".join(f"{v} {look_angle_deg(r, self.ground[v]):.1f}°" for v, r in res.items())
        note = f"The scene's viewing angles ({angles}) imply <b>B/H = {implied:.3f}</b>."
        if abs(bh.b_over_h - implied) > 0.1 * implied:
            note += (" The resections disagree: a pushbroom view resampled to the map grid (as a "
                     "PRISM level 1B2 product is) keeps square ground pixels while its rays "
                     f"look along the track at those angles, and no frame camera gives both — the "
                     f"resected cameras look {looks}, so their positions, and B, are not where the "
                     f"satellite was. Use the geometry's B/H for a pushbroom product.")
            self.bh_note.setStyleSheet("color: #b45309;")
        else:
            self.bh_note.setStyleSheet("")
        self.bh_note.setText(note)


class ResectionTool:
    def __init__(self, ctx):
        self.ctx = ctx
        self.dialog: ResectionDialog | None = None
        ctx.tools_menu.addAction("Space resection…", self.open)

    def open(self) -> ResectionDialog | None:
        if self.ctx.project is None:
            return None
        if self.dialog is None:
            self.dialog = ResectionDialog(self.ctx)
        else:
            self.dialog.refresh_views()
        self.dialog.show()
        self.dialog.raise_()
        return self.dialog


def install(ctx) -> None:
    ctx.tools["resection"] = ResectionTool(ctx)
