"""What the terrain can fix: the σ of the DEM orientation's shift field along and across track,
expected before the run from the reference DEM's gradients and stated after it from the
adjustment, and the verdict against a stated target.

A cell of the relative DEM on a slope ``g = (∂h/∂E, ∂h/∂N)`` fixes the shift along ``g`` only,
to ``σ_cell / |g|``; the scene fixes the field through the normal matrix of all its cells
(:mod:`prismstation.core.orientation.field_adjust`). Before the run every reference cell over N's
footprint stands for a matched cell with the a-priori σ ``sigma_cell_m`` and a correlation area
of one reference cell (bilinear reading: ``(1.5 k_x)·(1.5 k_y)`` grid cells for a reference of
``k`` grid cells per own cell); after it, the adjustment's own covariance says it. The σ is
summarised as the RMS over a 5 × 5 lattice over the N image, per component, along and across
the flight direction, and in the worst horizontal direction.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

OK, TOO_SMOOTH, TOO_FEW, FAILED = "ok", "too_smooth", "too_few", "failed"
EXIT_NOT_TRUSTED = 3
#: the planimetric and height σ an orientation must reach to be trusted (m), by default: one
#: PRISM pixel, what the triplet's check points reach with GCPs (a user who needs less sets it)
TARGET_M = 2.5
#: patches needed to state the field's σ from the data (the jackknife, the patches' own shifts)
MIN_PATCHES = 6
#: a-priori σ (m) of a relative-DEM cell against a 90 m reference (SRTM: 6 m at 90 %)
SIGMA_CELL_M = 3.6
#: what helps a terrain too smooth for the target
ADVICE = ("GCPs (three or more, spread over the scene, used together with the reference DEM), "
          "a larger area (the σ falls with the square root of the area), a finer reference "
          "DEM (a 30 m DEM instead of 90 m SRTM sees more relief), or a larger target σ where "
          "the use allows it")


def information(gx, gy, phi, weight, psi=None) -> np.ndarray:
    """Normal matrix (9 + D, 9 + D) of the field's parameters (per component E, N, h: terms
    ``phi`` (m, 3)) and of the relative DEMs' height distortion (terms ``psi`` (m, D), optional:
    :class:`~prismstation.core.orientation.field_model.Distortion`) from cells with reference gradients
    ``gx, gy`` (m,) and weights (1/m²)."""
    g = np.column_stack([gx, gy, -np.ones_like(gx)])
    J = (g[:, :, None] * phi[:, None, :]).reshape(len(gx), 9)
    if psi is not None:
        J = np.column_stack([J, -psi])
    w = np.broadcast_to(np.asarray(weight, float), (len(gx),))
    return (J * w[:, None]).T @ J


def expected_cov(info: np.ndarray, prior_sigma) -> np.ndarray:
    """Covariance of the parameters from a normal matrix and a zero-mean prior (σ per parameter)."""
    return np.linalg.inv(info + np.diag(1.0 / np.square(np.asarray(prior_sigma, float))))


def a_priori_area(cells) -> float:
    """Correlation area (grid cells) of a reference of ``cells = (k_x, k_y)`` grid cells per own
    cell read bilinearly: per axis ``(Σ w)² / Σ w²`` of a tent of half-width ``k`` = 1.5 ``k``."""
    return float(np.prod([1.5 * max(float(k), 1.0) for k in cells]))


@dataclass(frozen=True)
class SigmaSummary:
    """σ (m) of the shift field, RMS over the N image: components ``E``, ``N``, ``h``;
    ``along`` and ``across`` the flight direction; ``worst`` in the weakest horizontal
    direction, at ``worst_azimuth_deg`` (clockwise from north, 0–180)."""

    E: float
    N: float
    h: float
    along: float
    across: float
    worst: float
    worst_azimuth_deg: float

    @property
    def plan(self) -> float:
        return float(math.hypot(self.E, self.N))

    def to_dict(self) -> dict:
        def num(v):
            return float(v) if math.isfinite(v) else None
        return {"E": num(self.E), "N": num(self.N), "h": num(self.h), "plan": num(self.plan),
                "along": num(self.along), "across": num(self.across), "worst": num(self.worst),
                "worst_azimuth_deg": num(self.worst_azimuth_deg)}

    @classmethod
    def from_dict(cls, d: dict) -> "SigmaSummary":
        g = lambda k: float("nan") if d.get(k) is None else float(d[k])  # noqa: E731
        return cls(g("E"), g("N"), g("h"), g("along"), g("across"), g("worst"), g("worst_azimuth_deg"))

    def text(self) -> str:
        return (f"σ {self.along:.1f} m along track, {self.across:.1f} m across "
                f"(planimetric {self.plan:.1f} m), {self.h:.1f} m in height")


def summarise(covs: np.ndarray, along) -> SigmaSummary:
    """Summary of the field's covariances ``covs`` (n, 3, 3) (dE, dN, dh; m²) at a lattice over
    the N image; ``along`` the flight direction on the map (unit (E, N))."""
    t = np.asarray(along, float) / np.linalg.norm(along)
    a = np.array([-t[1], t[0]])
    c2 = covs[:, :2, :2]
    var = np.einsum("nii->ni", covs)
    al = np.einsum("i,nij,j->n", t, c2, t)
    ac = np.einsum("i,nij,j->n", a, c2, a)
    w, v = np.linalg.eigh(c2.mean(0))
    e = v[:, 1]
    rms = lambda x: float(np.sqrt(np.mean(x)))  # noqa: E731
    return SigmaSummary(rms(var[:, 0]), rms(var[:, 1]), rms(var[:, 2]), rms(al), rms(ac),
                        float(np.sqrt(w[1])), float(np.degrees(np.arctan2(e[0], e[1])) % 180.0))


def lattice(shape, n: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """``n × n`` N positions (x, y) at the centres of an even grid over an image of ``shape``."""
    rows, cols = shape
    g = (np.arange(n) + 0.5) / n
    xx, yy = np.meshgrid(g * cols, g * rows)
    return xx.ravel(), yy.ravel()


@dataclass(frozen=True)
class OrientVerdict:
    """Whether the DEM orientation is trusted: ``status`` (``ok``, ``too_smooth``, ``too_few``,
    ``failed``), a one-line ``message``, what would help (``advice``, "" when ok), the
    ``target_m`` and the σ it was judged on (``sigma``, :class:`SigmaSummary`)."""

    status: str
    message: str
    advice: str
    target_m: float
    sigma: SigmaSummary | None = None

    @property
    def ok(self) -> bool:
        return self.status == OK

    @property
    def exit_status(self) -> int:
        return 0 if self.ok else EXIT_NOT_TRUSTED

    def to_dict(self) -> dict:
        return {"status": self.status, "message": self.message, "advice": self.advice,
                "target_m": float(self.target_m),
                "sigma_m": self.sigma.to_dict() if self.sigma is not None else None}


def weak_directions(s: SigmaSummary, target_m: float) -> str:
    """Which way the terrain leaves the shift undetermined, in words ("" when it does not)."""
    weak = [name for name, v in (("along track", s.along), ("across track", s.across)) if not v <= target_m]
    if not weak:
        if s.plan > target_m:
            return "in both horizontal directions together"
        return "" if s.h <= target_m else "in height"
    if len(weak) == 1:
        return weak[0]
    return "in both horizontal directions"


def judge(sigma: SigmaSummary, target_m: float, patches_used: int, prior_sigma_m: float,
          min_patches: int = MIN_PATCHES, unchecked: str = "") -> OrientVerdict:
    """The verdict on an orientation whose field has ``sigma`` with ``patches_used`` patches:
    ``ok`` when its planimetric and height σ are within ``target_m``; ``too_smooth`` (what
    direction, what would help) otherwise; ``too_few`` below ``min_patches``. ``unchecked``:
    what the σ holds that the data cannot check (said in the message when not empty)."""
    note = f" ({unchecked})" if unchecked else ""
    if patches_used < min_patches:
        return OrientVerdict(TOO_FEW, f"{patches_used} patches: at least {min_patches} are needed to "
                             f"state the orientation's σ from the data (choose smaller patches){note}",
                             "smaller patches, or a larger area", target_m, sigma)
    if sigma.plan <= target_m and sigma.h <= target_m:
        return OrientVerdict(OK, f"trusted: {sigma.text()} (target {target_m:g} m){note}", "", target_m, sigma)
    where = weak_directions(sigma, target_m)
    if sigma.worst >= 0.7 * prior_sigma_m:
        what = (f"the terrain fixes no shift {where}: σ {sigma.worst:.0f} m there is the a-priori "
                f"geolocation σ ({prior_sigma_m:g} m)")
    else:
        what = f"the terrain is too smooth {where}: {sigma.text()}"
    return OrientVerdict(TOO_SMOOTH, f"NOT TRUSTED: {what}; the target is {target_m:g} m{note}", ADVICE,
                         target_m, sigma)
