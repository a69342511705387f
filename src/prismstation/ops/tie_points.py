"""Automatic tie points: a lattice over the reference view's image, each point transferred to
every other view (:func:`prismstation.ops.transfer.transfer`: shape-aware matching through the
fitted model, the rays' consistency checked), then the points that disagree with the others
across the parallax rejected. Image (x, y) = (column, row) px, pixel centre at +0.5.

:func:`auto_tie_points` is the matcher; :func:`find_tie_points` runs it on a project (in two
passes when the fit has not placed every view yet: the window's Tools ▸ Automatic tie
points…), :func:`add_tie_points` also adds what it keeps (``prismstation ties``, ``new
--images``), each measurement with its σ; :func:`ties_summary` says what it did.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from prismstation.core.models import prism
from prismstation.core.models.solution import Solution
from prismstation.core.adjustment.stats import nmad
from prismstation.io.windows import ImageWindows
from prismstation.model.points import GroundPoint, Measurement
from prismstation.model.project import Project
from prismstation.ops.fit import solve_project
from prismstation.ops.progress import ProgressFn, checkpoint, scaled
from prismstation.ops.predict import height_spread
from prismstation.ops.transfer import known_ground, search_sigmas, transfer


#: a lattice point this close (px) to a point measured in the reference view already is not
#: searched again (a second run of the same lattice adds nothing)
EXISTING_PX = 2.0


def lattice(scene, grid: int, margin: float = 0.05) -> np.ndarray:
    """``(grid², 2)`` px: the centres of a ``grid × grid`` division of the reference view's
    image less ``margin`` of it on every side, row by row."""
    rows, cols = scene.views[scene.reference_view].shape
    g = margin + (1 - 2 * margin) * (np.arange(grid) + 0.5) / grid
    return np.array([(cx * cols, cy * rows) for cy in g for cx in g])


def auto_tie_points(sol: Solution, images: ImageWindows, *, grid: int = 8, margin: float = 0.05,
                    height_of=None, progress: ProgressFn | None = None,
                    summary: dict | None = None, existing=None, nodes=None) -> list[dict]:
    """Tie points on a ``grid × grid`` lattice of the reference view's image (N for a
    triplet, else the scene's first view; :func:`lattice`, or the points ``nodes`` ``(n, 2)``
    px), transferred to every other view; lattice points within :data:`EXISTING_PX` of
    ``existing`` (``(n, 2)`` px of the reference view: points measured there already) are
    left out.

    Returns ``[{view: (x, y), …, "score": s, "sigma": {view: σ}}]`` for the points found in
    every other view whose rays meet (:func:`transfer`; ``score`` the lowest fitted
    correlation; ``sigma`` each measurement's σ in px, :func:`measurement_sigmas`; ``progress`` per
    :mod:`prismstation.ops.progress`; a cancel raises :class:`~prismstation.errors.Cancelled`)
    and consistent with the others: a point whose difference to the source across the
    parallax direction (:func:`_across_parallax`: across the track for a triplet) departs
    from the median by more than 3 NMAD (at least 1 px) is a blunder. ``summary``, when given,
    is filled with ``tried`` (grid points), ``failed`` (``{status: count}``: the first failed
    view's status, in the scene's order; ``outside`` when a view could not be searched),
    ``blunders`` (rejected by the test across the parallax), ``rms_px`` (RMS of the kept
    points' differences across the parallax about the median, every view together, source
    pixels; NaN with fewer than 4 found) and ``existing`` (lattice points left out).
    """
    sc = sol.scene
    source = sc.reference_view
    targets = [v for v in sc.views if v != source]
    sigma_dem, sigma_mean = search_sigmas(sol, height_of)
    if not known_ground(sol):
        sigma_mean = tie_height_spread(sol, sigma_mean)
    found, failed = [], {}
    nodes = lattice(sc, grid, margin) if nodes is None else np.asarray(nodes, float).reshape(-1, 2)
    n_nodes = len(nodes)
    if existing is not None and len(existing):
        ex = np.asarray(existing, float).reshape(-1, 2)
        d = np.hypot(nodes[:, None, 0] - ex[None, :, 0], nodes[:, None, 1] - ex[None, :, 1])
        nodes = nodes[~np.any(d <= EXISTING_PX, axis=1)]
    for k, (x, y) in enumerate(nodes):
        checkpoint(progress, k / len(nodes), f"point {k + 1} of {len(nodes)}")
        tr = transfer(sol, images, source, (x, y), height_of=height_of, sigma_dem=sigma_dem,
                      sigma_mean=sigma_mean)
        bad = [tr[v].match.status if v in tr else "outside" for v in targets if v not in tr or not tr[v].ok]
        if not bad:
            found.append({source: (float(x), float(y)), **{v: (tr[v].x, tr[v].y) for v in targets},
                          "score": min(tr[v].match.rho for v in targets),
                          "sigma": measurement_sigmas(source, {v: tr[v].match.cov for v in targets})})
        else:
            failed[bad[0]] = failed.get(bad[0], 0) + 1
    if summary is not None:
        summary.update(tried=len(nodes), failed=failed, blunders=0, rms_px=math.nan,
                       existing=n_nodes - len(nodes))
    if len(found) < 4:
        return found
    keep = np.ones(len(found), bool)
    xs = np.array([p[source] for p in found])
    dev = []
    for v in targets:
        a = _across_parallax(sol, source, xs, v, np.array([p[v] for p in found]))
        med = np.median(a)
        spread = max(nmad(a), 1.0 / 3)
        keep &= np.abs(a - med) <= 3 * spread
        dev.append(a - med)
    if summary is not None:
        summary.update(blunders=int((~keep).sum()),
                       rms_px=float(np.sqrt(np.mean(np.concatenate([e[keep] for e in dev]) ** 2))))
    return [p for p, k in zip(found, keep) if k]


#: tie points a fit must have intersected before their heights' spread stands for the
#: spread of the terrain's (fewer: the a-priori spread)
MIN_TIE_HEIGHTS = 5


def tie_height_spread(sol: Solution, default: float) -> float:
    """σ (m) of the height of a point nothing places, from the heights of the fit's
    intersected tie points when it has :data:`MIN_TIE_HEIGHTS` or more (a project without
    known ground; :func:`prismstation.ops.predict.height_spread`), else ``default``."""
    h = [p.ground_est[2] for p in sol.points if p.ground_est is not None]
    return height_spread(h) if len(h) >= MIN_TIE_HEIGHTS else default


def measurement_sigmas(source: str, covs: dict) -> dict:
    """σ (px) of each measurement of a transferred point: a match measures the target's
    position relative to the source's template, so its variance (``covs``: view → 2×2 px²,
    the mean of its two axes) is shared equally by the two images, as for every matched tie
    point of the project; the source, in every match, takes the mean of their variances."""
    var = {v: float(np.trace(np.asarray(c, float))) / 4.0 for v, c in covs.items()}
    out = {source: math.sqrt(float(np.mean(list(var.values()))))}
    out.update({v: math.sqrt(w) for v, w in var.items()})
    return out


def new_tie_ids(project, n: int, prefix: str = "T") -> list[str]:
    """``n`` new point ids: the project's next id with ``prefix``
    (:meth:`~prismstation.model.project.Project.new_point_id`: one more than the highest
    number after it, zero-padded as the project's ids are) and the ones after it."""
    first = project.new_point_id(prefix)
    digits = re.search(r"\d+$", first).group()
    k, width = int(digits), len(digits) if digits.startswith("0") else 0
    return [f"{prefix}{k + i:0{width}d}" for i in range(n)]


def tie_point_edits(project, ties: list[dict]) -> tuple[list[str], list[GroundPoint], list[Measurement]]:
    """The new ids, tie points and measurements (with their σ when the tie has one) of
    :func:`auto_tie_points`'s ``ties`` for ``project`` (not added: the caller adds them, in
    one step)."""
    ids = new_tie_ids(project, len(ties))
    points = [GroundPoint(pid, math.nan, math.nan, math.nan, kind="TIE") for pid in ids]
    def sigma(t, v):
        s = t.get("sigma", {}).get(v)
        return float(s) if s is not None and math.isfinite(s) and s > 0 else None
    ms = [Measurement(pid, v, float(t[v][0]), float(t[v][1]), sigma(t, v))
          for pid, t in zip(ids, ties) for v in project.scene.views]
    return ids, points, ms


def ties_summary(summary: dict, ids: list[str], scene=None) -> str:
    """What the automatic tie points did, in one paragraph: how many of the grid points were
    added (their ids), how many were not found in the other views of ``scene`` and why (the
    search's status; ``inconsistent``: the three rays did not meet), how many were rejected
    as blunders, and the RMS of the kept ones' differences across the parallax (across the
    track for a PRISM triplet)."""
    triplet = scene is None or scene.is_triplet
    others = ("F", "B") if scene is None else [v for v in scene.views if v != scene.reference_view]
    tried, failed, blunders = summary.get("tried", 0), summary.get("failed", {}), summary.get("blunders", 0)
    text = f"{len(ids)} of {tried} grid points added" + (f" ({ids[0]}–{ids[-1]})" if ids else "")
    if summary.get("existing"):
        text += f" ({summary['existing']} others measured already, not searched again)"
    n_failed = sum(failed.values())
    if n_failed:
        why = ", ".join(f"{n} {status}" for status, n in sorted(failed.items(), key=lambda kv: -kv[1]))
        text += f"; {n_failed} not found in {' and '.join(others)} ({why})"
    if blunders:
        text += (f"; {blunders} rejected as blunders ("
                 + ("across-track F−N or B−N" if triplet else "across the parallax") + " beyond 3 NMAD of the median)")
    rms = summary.get("rms_px", math.nan)
    if math.isfinite(rms):
        text += f"; {'across-track' if triplet else 'across the parallax'} RMS {rms:.2f} px"
    return text + "."


@dataclass(frozen=True)
class TieRun:
    """What :func:`add_tie_points` did: ``ids`` of the points added, ``summary`` (as
    :func:`auto_tie_points` fills it), ``sigma_px`` the σ of every measurement added."""

    ids: tuple
    summary: dict
    sigma_px: tuple

    def text(self, scene) -> str:
        """:func:`ties_summary`, and the measurements' σ."""
        s = ties_summary(self.summary, list(self.ids), scene)
        if self.sigma_px:
            q = np.percentile(self.sigma_px, [50, 90])
            s = s[:-1] + f"; measurement σ median {q[0]:.2f} px, 90 % {q[1]:.2f} px."
        return s


#: lattice points a first pass searches (every other one along both axes) before the
#: refit narrows the searches of the others, when the project's fit has not placed every
#: view yet (:func:`find_tie_points`): the a-priori searches cost about three times as much
#: per point
FIRST_PASS_STRIDE = 2


def find_tie_points(project, *, grid: int = 8, height_of=None, height_sigma_m: float | None = None,
                    progress: ProgressFn | None = None, sol: Solution | None = None) -> tuple[list, dict]:
    """:func:`auto_tie_points` on ``project``'s images (the project is not changed): the
    tie points and the summary, as :func:`auto_tie_points` returns and fills them.

    The fit is ``sol`` or :func:`prismstation.ops.fit.solve_project` of the project as it is
    (with no point, the products' own geometry; with tie points or GCPs, their fitted biases
    and heights, which narrow the searches). When it has not placed every view, every other
    lattice point along both axes is searched first, a copy of the project refitted with what
    they found, and the rest searched through that fit. ``height_of``, ``height_sigma_m``: a
    reference DEM's heights, given to the fits and to the searches; ``grid`` points per side
    of the lattice; lattice points measured already (within :data:`EXISTING_PX`) are left out."""
    if sol is None:
        sol = solve_project(project, height_of=height_of, height_sigma_m=height_sigma_m)
    scene = project.scene
    source = scene.reference_view
    existing = [(m.x, m.y) for m in project.measurements.values() if m.view == source]
    nodes = lattice(scene, grid)
    i, j = np.divmod(np.arange(len(nodes)), grid)
    first = (i % FIRST_PASS_STRIDE == 0) & (j % FIRST_PASS_STRIDE == 0)
    if all(sol.model.fitted(v) for v in scene.views) or first.all():
        first[:] = True
    summary: dict = {}
    with ImageWindows(scene) as im:
        ties = auto_tie_points(sol, im, nodes=nodes[first], height_of=height_of, summary=summary,
                               existing=existing, progress=scaled(progress, 0.0, 1.0 if first.all() else 0.4))
        if not first.all():
            _, points, ms = tie_point_edits(project, ties)
            trial = Project(scene, project.scene_path, settings=project.settings, geoid=project.geoid,
                            points=[*project.points.values(), *points],
                            measurements=[*project.measurements.values(), *ms],
                            dem_control=project.dem_control)
            refit = solve_project(trial, height_of=height_of, height_sigma_m=height_sigma_m)
            more: dict = {}
            ties += auto_tie_points(refit if refit.ok else sol, im, nodes=nodes[~first], height_of=height_of,
                                    summary=more, existing=existing, progress=scaled(progress, 0.4, 1.0))
            summary = _merged(summary, more)
    return ties, summary


def add_tie_points(project, *, grid: int = 8, height_of=None, height_sigma_m: float | None = None,
                   progress: ProgressFn | None = None) -> TieRun:
    """:func:`find_tie_points` and add what it keeps to ``project`` (one change; nothing
    added when cancelled: :class:`~prismstation.errors.Cancelled`)."""
    ties, summary = find_tie_points(project, grid=grid, height_of=height_of, height_sigma_m=height_sigma_m,
                                    progress=progress)
    ids, points, ms = tie_point_edits(project, ties)
    project.load(points, ms)
    return TieRun(tuple(ids), summary, tuple(m.sigma_px for m in ms if m.sigma_px is not None))


def _merged(a: dict, b: dict) -> dict:
    """Two passes' summaries as one (the RMS over both passes' kept points)."""
    kept = [a["tried"] - sum(a["failed"].values()) - a["blunders"],
            b["tried"] - sum(b["failed"].values()) - b["blunders"]]
    rms = [(k, r) for k, r in zip(kept, (a["rms_px"], b["rms_px"])) if k > 0 and math.isfinite(r)]
    failed = dict(a["failed"])
    for k, n in b["failed"].items():
        failed[k] = failed.get(k, 0) + n
    return {"tried": a["tried"] + b["tried"], "failed": failed, "blunders": a["blunders"] + b["blunders"],
            "existing": a.get("existing", 0) + b.get("existing", 0),
            "rms_px": math.sqrt(sum(k * r * r for k, r in rms) / sum(k for k, _ in rms)) if rms else math.nan}


def _across_parallax(sol: Solution, source: str, xs: np.ndarray, view: str, xt: np.ndarray) -> np.ndarray:
    """``(n,)`` px: the difference of ``view``'s points ``xt`` ``(n, 2)`` to the source's ``xs``
    across the direction a height moves them. A PRISM triplet: F or B in N space across the
    track; any other model: ``xt`` back to the source's image through the ground at the mean
    height, across the direction 100 m of height moves it there."""
    sc = sol.scene
    if sc.is_triplet:
        d = prism.along_track_unit(sc, sc.views[source].map_to_image.inverse()(xs))
        cross = np.column_stack([d[:, 1], -d[:, 0]])
        return np.einsum("ij,ij->i", prism.to_nadir_space(sc, sc.views[view])(xt) - xs, cross)
    h = float(sol.mean_height)
    back = [sol.ground_to_image(source, sol.image_to_ground(view, xt, hh), hh) for hh in (h, h + 100.0)]
    d = back[1] - back[0]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.einsum("ij,ij->i", back[0] - xs, np.column_stack([d[:, 1], -d[:, 0]]))