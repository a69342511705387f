"""Are the patch shifts consistent with their σ? A χ² test of the shift field.

The patches' shifts (e.g. dE, dN, dh in metres) are modelled as an affine function of patch
position per component (docs/model.md §3 step 4), weighted by their formal σ. If those σ are right
and the model holds, the weighted residuals' sum ``χ² = Σ (v/σ)²`` follows a χ² law with
``dof = k·(n − 3)`` (n patches, k components; ``model="constant"``: ``k·(n − 1)``). The test:

* ``ok`` — χ² ≤ its ``1 − α`` quantile (default α = 0.05: 5 % false alarms on consistent
  fields); the σ are kept (scale 1, or ŝ0 if ``rescale_always``);
* ``inconsistent`` — χ² beyond it: the patches disagree more than their σ claim (a blunder
  patch, σ too optimistic, or a field that is not affine). The variance factor ``ŝ0² = χ²/dof``
  says by how much; σ are rescaled by ``scale = ŝ0``; the worst patch is the one with the
  largest normalised residual ``w = v / σ_v`` (Baarda), flagged when ``|w|`` exceeds the
  Bonferroni critical value for ``n·k`` residuals at α;
* ``too_few`` — fewer than ``min_patches`` (default 6: three redundant patches per component).

:func:`snoop` removes the worst patch while the field is inconsistent and that patch's ``|w|``
is beyond the critical value (data snooping), at most ``max_reject`` times, and tests again; the
verdict lists what it removed.

The verdict is meant for the report, the window and the exit status alike:
``Verdict.exit_status`` is 0 when ok, :data:`EXIT_NOT_TRUSTED` (3) otherwise, and
``Verdict.to_dict()`` is JSON-safe (no NaN) with a one-line ``message``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import special   # stats.chi2.ppf and stats.norm.ppf's own functions: no scipy.stats import (~0.3 s)

OK, INCONSISTENT, TOO_FEW = "ok", "inconsistent", "too_few"
EXIT_NOT_TRUSTED = 3
ALPHA = 0.05
MIN_PATCHES = 6


@dataclass(frozen=True)
class Verdict:
    """Outcome of :func:`shift_field_verdict` / :func:`snoop` (see the module docstring).

    n, k, dof : patches used, components, degrees of freedom ``k·(n − 3)``.
    chi2, chi2_critical, alpha : the statistic, its ``1 − α`` quantile, the test level.
    variance_factor : ``χ²/dof`` (ŝ0²); ``scale`` the factor applied to the σ.
    worst, worst_w, w_critical : index (into the input) of the patch with the largest
        normalised residual, that |w|, and the Bonferroni critical value.
    w : per input patch, the largest |w| over its components (NaN for removed patches).
    rejected : input indices removed by :func:`snoop`.
    """

    status: str
    message: str
    n: int
    k: int
    dof: int
    chi2: float
    chi2_critical: float
    alpha: float
    variance_factor: float
    scale: float
    worst: int | None
    worst_w: float
    w_critical: float
    w: tuple = ()
    rejected: tuple = field(default_factory=tuple)

    @property
    def ok(self) -> bool:
        return self.status == OK

    @property
    def exit_status(self) -> int:
        return 0 if self.ok else EXIT_NOT_TRUSTED

    def to_dict(self) -> dict:
        def num(v):
            return float(v) if v is not None and math.isfinite(v) else None
        return {"status": self.status, "message": self.message, "patches": self.n,
                "components": self.k, "dof": self.dof, "chi2": num(self.chi2),
                "chi2_critical": num(self.chi2_critical), "alpha": self.alpha,
                "variance_factor": num(self.variance_factor), "sigma_scale": num(self.scale),
                "worst_patch": self.worst, "worst_w": num(self.worst_w),
                "w_critical": num(self.w_critical), "w": [num(v) for v in self.w],
                "rejected": list(self.rejected)}


def _design(x, y, model="affine"):
    if model == "constant":
        return np.ones((x.size, 1))
    xm, ym = x.mean(), y.mean()
    s = max(np.abs(x - xm).max(), np.abs(y - ym).max(), 1e-12)
    return np.column_stack([np.ones_like(x), (x - xm) / s, (y - ym) / s])


def shift_field_verdict(x, y, shifts, sigmas, *, alpha: float = ALPHA, min_patches: int = MIN_PATCHES,
                        rescale_always: bool = False, model: str = "affine") -> Verdict:
    """χ² test of an affine shift field against the shifts' σ.

    Parameters
    ----------
    x, y : (n,) patch positions (e.g. N-image pixels; any unit, only their geometry matters).
    shifts, sigmas : (n, k) shift components and their formal σ (same units, σ > 0).
    alpha : test level (false-alarm rate on consistent fields).
    min_patches : fewer patches give ``too_few``.
    rescale_always : scale σ by ŝ0 even when consistent (else only when inconsistent).
    model : ``"affine"`` (3 parameters per component) or ``"constant"`` (1).
    """
    x, y = np.asarray(x, float).ravel(), np.asarray(y, float).ravel()
    n = x.size
    s = np.asarray(shifts, float).reshape(n, -1)
    sig = np.asarray(sigmas, float).reshape(n, -1)
    k = s.shape[1]
    u = 1 if model == "constant" else 3
    least = max(min_patches, u + 1)
    nan = float("nan")
    if n < least or not np.all(np.isfinite(s)) or not np.all(sig > 0):
        if n >= least:
            raise ValueError("shifts must be finite and σ positive")
        return Verdict(TOO_FEW, f"{n} patches: at least {least} are needed to test "
                       "the shift field against its σ", n, k, max(k * (n - u), 0), nan, nan, alpha,
                       nan, 1.0, None, nan, nan, (nan,) * n)
    A = _design(x, y, model)
    if np.linalg.matrix_rank(A) < u:
        return Verdict(TOO_FEW, "the patches lie on a line: the affine field is undetermined",
                       n, k, 0, nan, nan, alpha, nan, 1.0, None, nan, nan, (nan,) * n)
    chi2, w = 0.0, np.zeros((n, k))
    for c in range(k):
        p = 1.0 / sig[:, c] ** 2
        N = A.T @ (A * p[:, None])
        Ninv = np.linalg.inv(N)
        v = s[:, c] - A @ (Ninv @ (A.T @ (p * s[:, c])))
        chi2 += float(np.sum(p * v ** 2))
        qvv = sig[:, c] ** 2 - np.einsum("ij,jk,ik->i", A, Ninv, A)       # cofactors of v
        w[:, c] = v / np.sqrt(np.maximum(qvv, 1e-12 * sig[:, c] ** 2))
    dof = k * (n - u)
    crit = float(special.chdtri(dof, 1.0 - (1 - alpha)))      # = stats.chi2.ppf(1 - alpha, dof), to the bit
    vf = chi2 / dof
    wmax = np.abs(w).max(axis=1)
    worst = int(np.argmax(wmax))
    w_crit = float(special.ndtri(1 - alpha / (2 * n * k)))
    consistent = chi2 <= crit
    scale = math.sqrt(vf) if (not consistent or rescale_always) else 1.0
    if consistent:
        msg = (f"consistent: χ² {chi2:.1f} ≤ {crit:.1f} ({dof} dof, α {alpha}); "
               f"variance factor {vf:.2f}")
    else:
        msg = (f"inconsistent: χ² {chi2:.1f} > {crit:.1f} ({dof} dof, α {alpha}): the patches "
               f"scatter {math.sqrt(vf):.1f}× more than their σ claim; σ scaled by "
               f"{math.sqrt(vf):.1f}; worst patch {worst} (|w| {wmax[worst]:.1f}"
               + (f" > {w_crit:.1f}, a blunder)" if wmax[worst] > w_crit else ")"))
    return Verdict(OK if consistent else INCONSISTENT, msg, n, k, dof, chi2, crit, alpha, vf, scale,
                   worst, float(wmax[worst]), w_crit, tuple(float(v) for v in wmax))


def snoop(x, y, shifts, sigmas, *, alpha: float = ALPHA, min_patches: int = MIN_PATCHES,
          max_reject: int | None = None, model: str = "affine") -> Verdict:
    """:func:`shift_field_verdict`, removing the worst patch while the field is inconsistent and
    that patch is a blunder (``|w|`` beyond the critical value), at most ``max_reject`` times
    (default a quarter of the patches); indices in the verdict refer to the input."""
    x, y = np.asarray(x, float).ravel(), np.asarray(y, float).ravel()
    n = x.size
    s = np.asarray(shifts, float).reshape(n, -1)
    sig = np.asarray(sigmas, float).reshape(n, -1)
    keep = np.arange(n)
    limit = n // 4 if max_reject is None else max_reject
    rejected: list[int] = []
    while True:
        v = shift_field_verdict(x[keep], y[keep], s[keep], sig[keep], alpha=alpha,
                                min_patches=min_patches, model=model)
        if (v.status != INCONSISTENT or len(rejected) >= limit or v.worst is None
                or not v.worst_w > v.w_critical):
            break
        rejected.append(int(keep[v.worst]))
        keep = np.delete(keep, v.worst)
    w = np.full(n, np.nan)
    w[keep] = v.w if len(v.w) == keep.size else np.nan
    msg = v.message
    if rejected:
        msg += f"; {len(rejected)} patch(es) rejected as blunders: {rejected}"
    worst = int(keep[v.worst]) if v.worst is not None else None
    return Verdict(v.status, msg, v.n, v.k, v.dof, v.chi2, v.chi2_critical, v.alpha,
                   v.variance_factor, v.scale, worst, v.worst_w, v.w_critical,
                   tuple(float(a) for a in w), tuple(rejected))
