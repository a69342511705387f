"""What the window tells of the fit's own footing (no Qt): the one blunder threshold and why it
holds for every fit of the sensor model (:meth:`SensorModel.adjustments
<prismstation.core.models.sensor.SensorModel>`).

The test runs at one level α, the two-sided normal tail of ``Settings.blunder_threshold``
(3.29 ↔ α = 0.001); a model's own checks (the PRISM parallax model's F test) run at the same
level (:func:`alpha_of`).
"""
from __future__ import annotations

from dataclasses import dataclass

from scipy import special

from prismstation.core.models.solution import critical_value


def alpha_of(threshold: float) -> float:
    """The two-sided level α of a threshold on the normal scale (3.29 → 0.001)."""
    return float(2 * special.ndtr(-abs(threshold)))


@dataclass(frozen=True)
class BlunderTest:
    """The blunder test of a fit.

    ``fits``: ``((label, redundancy, critical |w|), ...)`` for the model's adjustments (the N
    bias, the parallax line): an externally studentised residual |w| beyond its fit's critical
    value (Student's t with redundancy − 1 degrees of freedom at α) is a blunder. The window
    shows each GCP's largest |w| on the normal scale (``PointResult.std_residual``), where that
    is the same as exceeding ``threshold`` for every fit. ``flagged``: ids beyond it."""

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
    fits = [(label, int(lsq.dof), critical_value(thr, int(lsq.dof)))
            for label, lsq in sol.model.adjustments() if lsq.dof]
    return BlunderTest(thr, alpha_of(thr), tuple(fits), sol.columns.blunder_ids())
