"""Which heights a DSM follows: the fitted model's parallax line, or the rays through its biases.

One GCP fit gives two heights for a point seen in F and B. The matching intersects **rays**
through each view's fitted bias affine (six parameters per view) and the relief geometry; the
model's **line** turns the F–B parallax into a height by ``h = c0 + c1·py`` (two parameters,
docs/model.md §2, what the check points report). The line cannot follow a height error that drifts
across the scene (attitude drift: metres over a 35 km PRISM scene); the rays follow any drift
linear in the image, at the price of extrapolating the biases' noise. Measured at the check
points of simulated scenes (9 GCPs): 14,000 px, rays 1.44 m against the line's 2.38 m; 6,000 px
1.48 m against 1.42 m; 2,000 px 1.65 m against 1.49 m. Neither is better everywhere, so the
GCPs decide (:func:`choose_heights`): each is left out of the fit in turn and its height
predicted by both; the DSM follows the one with the smaller leave-one-out RMS.

Heights are ellipsoidal metres; map coordinates metres of the scene's CRS.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from prismstation.core.models import prism
from prismstation.core.models.solution import Solution, solve

HEIGHT_MODELS = ("auto", "line", "rays")
#: fewer GCPs measured in N, F and B than this: leave-one-out says nothing, the line is kept
MIN_GCPS_TO_CHOOSE = 5


@dataclass(frozen=True)
class HeightCorrection:
    """``Δ(E, N, h) = c0 + cE·(E − E0) + cN·(N − N0) + ch·h`` (metres): what turns a height
    from the matching's geometry into the fitted model's height (see
    :func:`model_height_correction`). ``origin`` (E0, N0), ``coef`` (c0, cE, cN, ch)."""

    origin: tuple
    coef: tuple

    def __call__(self, en, h) -> np.ndarray:
        en = np.asarray(en, float)
        c0, ce, cn, ch = self.coef
        return c0 + ce * (en[..., 0] - self.origin[0]) + cn * (en[..., 1] - self.origin[1]) + ch * np.asarray(h, float)


def model_height_correction(sol: Solution, h_lo: float, h_hi: float, n: int = 9) -> HeightCorrection:
    """The difference between the fitted model's height and the matching's, as an affine
    function of ground position and height.

    The matching (:func:`prismstation.core.surfaces.stereo_tile.match_pair`) intersects rays through each view's fitted bias and the
    relief geometry; the model judges heights by the F–B parallax line calibrated on the GCPs
    (docs/model.md §2, what its check points report). Away from the GCPs the two differ by a tilt
    (the F and B biases, six parameters each, extrapolate their noise) and a scale (c1 against
    its theoretical value) — measured ±1.7 m across a 5 km simulated scene. Evaluated on an
    ``n × n`` lattice over the N image at ``h_lo`` and ``h_hi``: predict F and B from the model,
    take their parallax through the line; the difference is affine in (E, N, h) to well under
    a millimetre there."""
    sc = sol.scene
    rows, cols = sc.views["N"].shape
    g = (np.arange(n) + 0.5) / n
    xy = np.column_stack([np.tile(g * cols, n), np.repeat(g * rows, n)])
    A, y = [], []
    origin = None
    for h in (float(h_lo), float(h_hi) if h_hi > h_lo else float(h_lo) + 100.0):
        hh = np.full(len(xy), h)
        en = sol.image_to_ground("N", xy, hh)
        origin = en.mean(axis=0) if origin is None else origin
        py, mid = prism.fb_parallax(sc, sol.ground_to_image("F", en, hh), sol.ground_to_image("B", en, hh))
        A.append(np.column_stack([np.ones(len(en)), en - origin, hh]))
        y.append(sol.model.parallax.height(py, mid) - hh)
    coef, *_ = np.linalg.lstsq(np.vstack(A), np.concatenate(y), rcond=None)
    return HeightCorrection(tuple(float(v) for v in origin), tuple(float(v) for v in coef))


@dataclass(frozen=True)
class HeightChoice:
    """The heights a DSM follows. ``model``: ``line`` or ``rays``; ``requested``: one of
    :data:`HEIGHT_MODELS`; ``loo_rms_m``: leave-one-out height RMS (m) of the GCPs per model
    (empty when not computed); ``n``: the GCPs left out in turn; ``reason`` in words."""

    model: str
    requested: str
    loo_rms_m: dict
    n: int
    reason: str

    def record(self) -> dict:
        return {"model": self.model, "requested": self.requested, "n_gcps": self.n,
                "loo_rms_m": dict(self.loo_rms_m), "reason": self.reason}


def loo_height_errors(sol: Solution) -> tuple[np.ndarray, np.ndarray]:
    """Leave-one-out height errors (m, predicted − known, ``(n,)`` each, line and rays) of the
    GCPs measured in N, F and B: each left out of the fit in turn (as a check point). Points
    whose refit fails (too few GCPs left for a bias) are skipped."""
    obs = list(sol.observations)
    line, rays = [], []
    for k, o in enumerate(obs):
        if o.kind != "GCP" or o.ground is None or not {"N", "F", "B"} <= set(o.image):
            continue
        rest = obs[:k] + [dataclasses.replace(o, kind="ICP")] + obs[k + 1:]
        fit = solve(sol.scene, rest, sol.settings)
        p = fit.point(o.id)
        if not fit.ok or fit.model.parallax is None or p is None or p.ground_est is None:
            continue
        e, n, h = p.ground_est
        corr = model_height_correction(fit, h - 100.0, h + 100.0)
        line.append(h - o.ground[2])
        rays.append(h - float(corr(np.array([e, n]), h)) - o.ground[2])
    return np.array(line), np.array(rays)


def choose_heights(sol: Solution, requested: str = "auto") -> HeightChoice:
    """The heights a DSM of ``sol`` follows: ``requested`` ``line`` or ``rays``, or ``auto``:
    the one whose leave-one-out GCP heights have the smaller RMS (the line with fewer than
    :data:`MIN_GCPS_TO_CHOOSE` GCPs in N, F and B, or an orientation without GCPs, whose line
    already follows the reference DEM's height field)."""
    if requested not in HEIGHT_MODELS:
        raise ValueError(f"unknown height model {requested!r}; choose one of {', '.join(HEIGHT_MODELS)}")
    if requested != "auto":
        return HeightChoice(requested, requested, {}, 0, f"{requested} as asked")
    if not sol.observations:
        return HeightChoice("line", requested, {}, 0, "no GCP fit: the model's parallax line")
    line, rays = loo_height_errors(sol)
    if len(line) < MIN_GCPS_TO_CHOOSE:
        return HeightChoice("line", requested, {}, len(line),
                            f"{len(line)} GCPs in N, F and B (fewer than {MIN_GCPS_TO_CHOOSE}): the parallax line")
    rms = {"line": float(np.sqrt(np.mean(line ** 2))), "rays": float(np.sqrt(np.mean(rays ** 2)))}
    model = "rays" if rms["rays"] < rms["line"] else "line"
    return HeightChoice(model, requested, rms, len(line),
                        f"leave-one-out over {len(line)} GCPs: line {rms['line']:.2f} m, rays {rms['rays']:.2f} m RMS")
