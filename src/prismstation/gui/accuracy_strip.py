"""The accuracy strip: the numbers an operator watches, always in the same place.

One row above the images: the RMSE of the check points (ICPs) on the ground — E, N,
planimetric, and h — in metres, the reference view's σ0 in pixels, the number of GCPs and ICPs
in the fit, and the one residual-exaggeration control of the window (the vectors on the images
and in the residual-vector plot). Values are :class:`TextLabel` s with a fixed width: a refit
never relayouts the window.
"""
from __future__ import annotations

from PySide6.QtCore import Signal
from PySide6.QtWidgets import QDoubleSpinBox, QFrame, QHBoxLayout, QLabel

from prismstation.gui.palette import html
from prismstation.io.formatting import fixed
from prismstation.gui.sensors import parts_of
from prismstation.gui.text_label import TextLabel
from prismstation.gui.plain import plain

FIELDS = (("E", "ICP RMSE of easting, estimated − known ground position (m)"),
          ("N", "ICP RMSE of northing, estimated − known ground position (m)"),
          ("plan", "ICP planimetric RMSE √(E² + N²) (m)"),
          ("h", "ICP RMSE of the ellipsoidal height, from the F−B parallax (PRISM) or the "
                "intersection of the rays (RPC images) (m)"),
          ("σ0", "a-posteriori σ0 of the reference view's bias fit (px): about the a-priori σ "
                 "when the measurements are as good as assumed"))


WARN_COLOR = "#c00000"


def accuracy_values(sol) -> dict:
    """``{field: text}`` of the strip for a Solution (None: all "—")."""
    out = dict.fromkeys([f for f, _ in FIELDS], "—")
    out["count"] = "no fit"
    if sol is None:
        return out
    st = sol.stats
    g = st.get("ground", {}).get("ICP")
    if g is not None:
        out.update(E=fixed(g.x.rms), N=fixed(g.y.rms), plan=fixed(g.planimetric_rms))
    hgt = st.get("height", {}).get("ICP") if sol.model.heights_fitted else None
    if hgt is not None:
        out["h"] = fixed(hgt.rms)
    s0 = sol.bias[sol.reference_view].sigma0 if sol.reference_view in sol.bias else None
    out["σ0"] = fixed(s0, 3)
    cols = sol.columns
    measured = [k for k, m in zip(cols.kinds, cols.measured_anywhere().tolist()) if m]
    n = {k: measured.count(k) for k in ("GCP", "ICP")}
    out["count"] = f"{n['GCP']} GCP · {n['ICP']} ICP"
    return out


def accuracy_warning(sol) -> tuple[tuple[str, ...], str]:
    """``(wordings, full text)`` of what the strip's figures stand on that does not hold (the
    sensor model's own check: the PRISM parallax model does not fit the GCPs), longest wording
    first; ``((), "")`` when nothing."""
    if sol is None:
        return (), ""
    return parts_of(sol.scene.sensor).fit_warning(sol)


class AccuracyStrip(QFrame):
    """ICP RMSE E / N / plan / h (m), σ0 (px), point counts and the residual exaggeration.

    Signals
    -------
    exaggeration_changed(float)
        Residuals drawn this many times their length (images: screen px per px of residual).
    """

    exaggeration_changed = Signal(float)

    def __init__(self, exaggeration: float = 40.0, parent=None):
        super().__init__(parent)
        self.setObjectName("accuracy_strip")
        self.setFrameShape(QFrame.Shape.StyledPanel)
        lay = QHBoxLayout(self)
        lay.setContentsMargins(6, 1, 6, 1)
        lay.setSpacing(4)
        title = QLabel(f"<b><span style='color:{html('ICP')}'>ICP</span> RMSE</b>")
        title.setToolTip("Accuracy on the check points: independent of the fit")
        lay.addWidget(title)
        lay.addSpacing(6)
        self.values: dict[str, TextLabel] = {}
        for f, tip in FIELDS:
            if f == "σ0":
                lay.addSpacing(8)
            name = QLabel(f)
            name.setToolTip(tip)
            lay.addWidget(name)
            lab = TextLabel("—", "00.000 px" if f == "σ0" else "0000.00 m", bold=True)
            lab.setToolTip(tip)
            lay.addWidget(lab)
            self.values[f] = lab
        lay.addSpacing(8)
        self.count = TextLabel("no fit", "000 GCP · 000 ICP")
        self.count.setToolTip("Measured GCPs (in the fit) and ICPs (checks only)")
        lay.addWidget(self.count)
        lay.addSpacing(8)
        # what the figures stand on that does not hold (elided when narrow; whole in its tip)
        self.warning = TextLabel("", "⚠ h from the parallax model", color=WARN_COLOR, bold=True,
                                 stretch=True)
        lay.addWidget(self.warning, 1)
        lab = QLabel("Residuals ×")
        self.exaggeration = QDoubleSpinBox(decimals=0, minimum=1, maximum=5000, singleStep=10)
        tip = ("Residual vectors drawn this many times their length: on the images (screen pixels "
               "per pixel of residual, the same at every zoom) and in the residual-vector plot")
        for w in (lab, self.exaggeration):
            w.setToolTip(tip)
            lay.addWidget(w)
        self.exaggeration.setValue(exaggeration)
        self.exaggeration.valueChanged.connect(self.exaggeration_changed)

    def set_solution(self, sol) -> None:
        vals = accuracy_values(sol)
        for f, lab in self.values.items():
            unit = "" if vals[f] == "—" else (" px" if f == "σ0" else " m")
            lab.setText(vals[f] + unit)
        self.count.setText(vals["count"])
        wordings, full = accuracy_warning(sol)
        self.warning.setText(*(wordings or ("",)))
        if self.warning.toolTip() != plain(full):
            self.warning.setToolTip(plain(full))
        self.values["h"].set_color(WARN_COLOR if wordings else None)

    def text(self) -> str:
        """What the strip shows, one line (tests)."""
        return ("  ".join(f"{f} {lab.text()}" for f, lab in self.values.items()) + "  " + self.count.text()
                + (f"  {self.warning.text()}" if self.warning.text() else ""))
