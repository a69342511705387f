"""What the window tells of the fit's own footing (no Qt): the one blunder threshold and why it
holds for every fit, and whether the chosen parallax model fits the GCPs.

Both tests run at one level α, the two-sided normal tail of ``Settings.blunder_threshold``
(3.29 ↔ α = 0.001).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from prismstation.core.solve import critical_value


def alpha_of(threshold: float) -> float:
    """The two-sided level α of a threshold on the normal scale (3.29 → 0.001)."""
    from scipy import special
    return float(2 * special.ndtr(-abs(threshold)))


@dataclass(frozen=True)
class BlunderTest:
    """The blunder test of a fit.

    ``fits``: ``((label, redundancy, critical |w|), ...)`` for the N bias and the parallax line
    fits: an externally studentised residual |w| beyond its fit's critical value (Student's t
    with redundancy − 1 degrees of freedom at α) is a blunder. The window shows each GCP's
    largest |w| on the normal scale (``PointResult.std_residual``), where that is the same
    as exceeding ``threshold`` for every fit. ``flagged``: ids beyond it."""

    threshold: float
    alpha: float
    fits: tuple
    flagged: tuple

    def reason(self) -> str:
        """One sentence: why one threshold holds for fits of different redundancy."""
        crit = "; ".join(f"{label}, redundancy {dof}: |w| > {c:.2f}" for label, dof, c in self.fits)
        return (f"A GCP is a blunder when its studentised residual |w| passes its fit's critical "
                f"value at α = {self.alpha:.2g} (Student's t: fewer GCPs, heavier tails"
                + (f" — {crit}" if crit else "") + f"); standardised residuals are shown on the "
                f"normal scale, where that is {self.threshold:.2f} for every fit.")


def blunder_test(sol) -> BlunderTest | None:
    """The blunder test of ``sol`` (a Solution; None without one)."""
    if sol is None:
        return None
    thr = float(sol.settings.blunder_threshold)
    fits = []
    lsq_n = getattr(sol.bias.get(sol.reference_view), "lsq", None)
    if lsq_n is not None and lsq_n.dof:
        fits.append((f"{sol.reference_view} bias", int(lsq_n.dof), critical_value(thr, int(lsq_n.dof))))
    par = sol.parallax
    if par is not None and par.lsq is not None and par.lsq.dof:
        fits.append(("parallax line", int(par.lsq.dof), critical_value(thr, int(par.lsq.dof))))
    return BlunderTest(thr, alpha_of(thr), tuple(fits), sol.columns.blunder_ids())


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
    if sol is None or sol.parallax is None or sol.settings.orientation != "gcp":
        return None
    par = sol.parallax
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
    from scipy import special
    p = float(special.fdtrc(dof[0], dof[1], F)) if math.isfinite(F) else 0.0
    return ParallaxCheck(par.used, n, math.sqrt(rss_model / n), math.sqrt(rss_line / n), F, dof, p,
                         alpha_of(sol.settings.blunder_threshold))
