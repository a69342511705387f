"""The PRISM model's own parts of the window (:mod:`prismstation.gui.sensors`; no Qt): the
parallax line in the model panel and the plots, whether the chosen parallax model fits the
GCPs (:func:`parallax_check`: an F test at the blunder test's level, in the panel and as the
accuracy strip's warning), and the orientation from a reference DEM: the request the
orientation dialog makes and the stored record in words (its patches are the dock's table).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import special

from prismstation.core.orientation.conditioning import SigmaSummary
from prismstation.gui.fit_checks import alpha_of
from prismstation.gui.plain import counted
from prismstation.io.formatting import fixed
from prismstation.io.jsonfile import number
from prismstation.ops.orientation import OrientRequest


def panel_sections(sol) -> tuple[list, list]:
    """The model panel's sections of the PRISM model: the parallax line with its σ, σ0 and the
    theoretical c1 (``[(title, head, rows)]``), and the parallax check's note
    (``[(text, severity)]``)."""
    par = sol.model.parallax
    check = parallax_check(sol)
    sections = []
    if par is not None:
        s0 = par.sigma0
        sections.append((f"Parallax line h = c0 + c1·py ({par.used})"
                         + (f" — σ0 = {fixed(s0)} m" if s0 is not None else "")
                         + (" — does not fit the GCPs" if check is not None and not check.fits else ""),
                         ["", "value", "σ", "theory"],
                         [["c0 (m)", fixed(par.c0, 2, True), fixed(par.std_c0), "0"],
                          ["c1 (m/px)", fixed(par.c1, 4), fixed(par.std_c1, 4), fixed(par.c1_theory, 4)]]
                         + ([[f"c0 tilt {a} (m per 1000 px)", fixed(1000 * t, 3, True), "—", "0"]
                             for a, t in zip("xy", par.tilt)] if any(par.tilt) else [])))
    notes = [] if check is None else [(check.text(), "info" if check.fits else "bad")]
    return sections, notes


def fit_warning(sol) -> tuple[tuple[str, ...], str]:
    """``(wordings, full text)`` of what the accuracy strip's heights stand on that does not
    hold (the parallax model does not fit the GCPs): the strip shows the longest wording it has
    room for, the full text in its tool tip; ``((), "")`` when nothing."""
    check = parallax_check(sol)
    if check is None or check.fits:
        return (), ""
    return ((f"⚠ h from the '{check.model}' parallax model, which does not fit the GCPs "
             f"({check.rms_model:.3g} m RMS)",
             f"⚠ h: the '{check.model}' parallax model does not fit the GCPs",
             "⚠ h: the parallax model does not fit", "⚠ h: model off", "⚠ h"), check.text())


def orientable(scene) -> bool:
    """The orientation from a reference DEM needs an N, F, B triplet."""
    return scene.is_triplet


def orient_request(patch_m: float, posting_m: float, sigma_m: float, target_m: float) -> OrientRequest:
    """The orientation dialog's choices as the request: every one of them is the PRISM
    engine's."""
    return OrientRequest(sigma_m, posting_m, patch_m, target_m)


def orientation_text(record: dict, state: str, scale: float | None = None) -> str:
    """A stored orientation in words: the reference, whether it is in use (``state``), the
    a-priori σ, the patches used and the view offsets (``scale``: the N view's vectors)."""
    patches = record.get("patches", [])
    used = sum(1 for p in patches if p.get("used"))
    off = {k: [number(c) for c in v] for k, v in (record.get("offsets_px") or {}).items()}
    nan2 = [float("nan")] * 2
    vec = f"; vectors on N × {scale:.0f}" if scale else ""
    ref = str(record.get("reference", "?"))
    return (f"Reference {ref.replace(chr(92), '/').rsplit('/', 1)[-1]} — {state}. A-priori geolocation σ "
            f"{number(record.get('sigma_apriori_m')):.0f} m per view. {used} of {counted(len(patches), 'patch', 'patches')} used; "
            f"from the ancillary model F−N ({off.get('F', nan2)[0]:+.1f}, {off.get('F', nan2)[1]:+.1f}) px, "
            f"B−N ({off.get('B', nan2)[0]:+.1f}, {off.get('B', nan2)[1]:+.1f}) px{vec}.")


def applied_text(record: dict) -> str:
    """The status line once the orientation is applied: only when it is not trusted."""
    if (record.get("verdict") or {}).get("status") == "ok":
        return ""
    return f"Applied, not trusted: {verdict_text(record)}"


def verdict_text(record) -> str:
    """Whether the stored orientation can be trusted: the σ the terrain was expected to allow
    before the run, the σ stated after it, the verdict and what would help."""
    v = (record or {}).get("verdict")
    if not v:
        return "No verdict (an orientation made by an earlier version): not tested."
    def sigma(key, label):
        d = (record or {}).get(key)
        if not d:
            return ""
        s = SigmaSummary.from_dict(d)
        return (f" {label}: planimetric {s.plan:.1f} m ({s.along:.1f} m along track, {s.across:.1f} m across), "
                f"height {s.h:.1f} m.")
    text = sigma("expected_sigma_m", "Expected from the terrain before the run") + sigma("sigma_m", "After the run")
    if v.get("status") == "ok":
        return f"Verdict: trusted ({v.get('message', '').removeprefix('trusted: ')}).{text}"
    advice = f" What would help: {v['advice']}." if v.get("advice") else ""
    message = v.get("message", "").removeprefix("NOT TRUSTED: ")
    return f"Verdict: NOT TRUSTED ({v.get('status')}) — {message}.{text}{advice}"


def plot_line(sol) -> tuple | None:
    """``(c0, c1, c1 theoretical)`` of the parallax line the plots draw, or None."""
    par = sol.model.parallax
    return None if par is None else (par.c0, par.c1, par.c1_theory)


@dataclass(frozen=True)
class ParallaxCheck:
    """Does the chosen parallax model fit the GCPs? The GCPs' height residuals under the chosen
    model (``rms_model``, m) against those of a line fitted to the same GCPs (``rms_line``):
    the nested-model F test, ``F`` with ``dof`` = (parameters the model does not fit,
    GCPs − 2) and its tail probability ``p``; ``fits`` is ``p ≥ alpha``."""

    model: str
    n: int
    rms_model: float
    rms_line: float
    F: float
    dof: tuple
    p: float
    alpha: float

    @property
    def fits(self) -> bool:
        return self.p >= self.alpha

    def text(self) -> str:
        verdict = "fits" if self.fits else "does not fit"
        return (f"The '{self.model}' parallax model {verdict} the GCPs: their heights miss it by "
                f"{self.rms_model:.2f} m RMS, a line fitted to the {self.n} GCPs by "
                f"{self.rms_line:.2f} m (F = {self.F:.3g}, p = {self.p:.2g}"
                f" {'≥' if self.fits else '<'} α = {self.alpha:.2g})"
                + ("" if self.fits else "; heights from it are wrong by about the first figure"
                   " — choose 'line', or measure more GCPs in F and B"))


def parallax_check(sol) -> ParallaxCheck | None:
    """The F test of the parallax model of ``sol`` against a line fitted to its GCPs; None when
    the model is the fitted line itself, or when there are too few GCPs (3) to test it."""
    if sol is None or sol.model.parallax is None or sol.settings.orientation != "gcp":
        return None
    par = sol.model.parallax
    if par.used == "line":
        return None
    py, h = [], []
    for r in sol.points:
        if r.kind == "GCP" and r.parallax_px is not None and r.ground_est is not None \
                and r.ground_residual is not None:
            py.append(r.parallax_px)
            h.append(r.ground_est[2] - r.ground_residual[2])
    n = len(py)
    if n < 3:
        return None
    py, h = np.asarray(py, float), np.asarray(h, float)
    if np.ptp(py) < 1.0:
        return None
    rss_model = float(np.sum((par.c0 + par.c1 * py - h) ** 2))
    A = np.column_stack([np.ones(n), py - py.mean()])
    coef, *_ = np.linalg.lstsq(A, h, rcond=None)
    rss_line = float(np.sum((A @ coef - h) ** 2))
    k = 2 - (1 if par.used == "offset" else 0)  # parameters the line has and the model lacks
    dof = (k, n - 2)
    if rss_line <= 0:
        F = math.inf if rss_model > 0 else 0.0
    else:
        F = max(rss_model - rss_line, 0.0) / k / (rss_line / dof[1])
    p = float(special.fdtrc(dof[0], dof[1], F)) if math.isfinite(F) else 0.0
    return ParallaxCheck(par.used, n, math.sqrt(rss_model / n), math.sqrt(rss_line / n), F, dof, p,
                         alpha_of(sol.settings.blunder_threshold))
