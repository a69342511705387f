"""The project's points transferred in one run (``prismstation transfer``): each point measured
in some views and not in others is searched from its reference view's measurement (N where it
is measured, else the first of the scene's views it is in) in the views it lacks, as the
window's Ctrl+T searches it (:func:`prismstation.ops.transfer.transfer`: the fitted model,
the reference DEM's heights and slope, the rays' test). Image ``(x, y)`` = (column, row) px.
"""
from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

import numpy as np

from prismstation.core.models.scene import reference_view
from prismstation.core.models.solution import Solution
from prismstation.errors import InputError
from prismstation.io.windows import ImageWindows
from prismstation.model.points import Measurement
from prismstation.ops.progress import ProgressFn, checkpoint
from prismstation.ops.transfer import Transfer, search_sigmas, transfer


#: why a view was not searched: the model puts the point outside its image
OUTSIDE_REASON = "the prediction lies outside the image"


@dataclass(frozen=True)
class PointTransfer:
    """One point's transfer: from ``source`` at ``xy`` (px) to the views it lacked
    (``found``: view → :class:`~prismstation.ops.transfer.Transfer`, a view that could not be
    searched — its prediction outside the image — absent)."""

    pid: str
    source: str
    xy: tuple
    targets: tuple
    found: dict


def to_transfer(project, ids=None) -> list[tuple[str, str, tuple, tuple]]:
    """``[(id, source view, (x, y), target views)]``: the points of ``project`` (``ids``, in
    their order, or every point in id order) measured in at least one view and not in all.
    Raises :class:`~prismstation.errors.InputError` for an id the project does not hold and
    where a view has no image (the search needs every view's)."""
    scene = project.scene
    blind = [v for v, view in scene.views.items() if not view.image]
    if blind:
        raise InputError(f"point transfer needs every view's image; the scene names none for {', '.join(blind)}")
    if ids is None:
        ids = sorted(project.points)
    else:
        unknown = [i for i in ids if i not in project.points]
        if unknown:
            raise InputError(f"no point {', '.join(map(repr, unknown))} in the project")
    out = []
    for pid in dict.fromkeys(ids):
        measured = [v for v in scene.views if project.measurement(pid, v) is not None]
        if not measured or len(measured) == len(scene.views):
            continue
        source = reference_view(measured)
        m = project.measurement(pid, source)
        out.append((pid, source, (float(m.x), float(m.y)), tuple(v for v in scene.views if v not in measured)))
    return out


def transfer_points(project, sol: Solution, todo, *, height_of=None,
                    progress: ProgressFn | None = None) -> list[PointTransfer]:
    """Each of ``todo`` (:func:`to_transfer`) searched through ``sol`` with the reference DEM
    ``height_of`` (map metres → ellipsoidal metres, or None) and the σ its heights and the
    terrain's spread show at the fit's known points (:func:`~prismstation.ops.transfer.search_sigmas`,
    as the window's predictions measure them). ``progress`` per :mod:`prismstation.ops.progress`
    (a cancel raises :class:`~prismstation.errors.Cancelled`)."""
    sigma_dem, sigma_mean = search_sigmas(sol, height_of)
    out = []
    with ImageWindows(project.scene) as im:
        for k, (pid, source, xy, targets) in enumerate(todo):
            checkpoint(progress, k / max(len(todo), 1), f"point {k + 1} of {len(todo)}")
            res = transfer(sol, im, source, xy, height_of=height_of, sigma_dem=sigma_dem, sigma_mean=sigma_mean)
            out.append(PointTransfer(pid, source, xy, targets, {v: t for v, t in res.items() if v in targets}))
    checkpoint(progress, 1.0, "done")
    return out


def found_measurements(results: list[PointTransfer]) -> list[Measurement]:
    """The measurements the found transfers make, as the window's Enter places them (the
    project's a-priori σ of a measurement: the match measures the point the source's
    measurement marks, whose own error it carries)."""
    return [Measurement(r.pid, v, float(t.x), float(t.y)) for r in results for v, t in sorted(r.found.items())
            if t.ok]


def parallax_sigmas(t: Transfer) -> tuple[float, float]:
    """``(σ along, σ across)`` px of a match: its covariance along its view's parallax
    direction (where a height moves the point) and across it; x and y where it has none."""
    cov = np.asarray(t.match.cov, float)
    d = np.asarray(t.match.extra.get("d", (1.0, 0.0)), float)
    if not np.all(np.isfinite(cov)) or not np.hypot(*d) > 0:
        return math.nan, math.nan
    d = d / np.hypot(*d)
    e = np.array([-d[1], d[0]])
    return float(np.sqrt(d @ cov @ d)), float(np.sqrt(e @ cov @ e))


def transfer_summary(results: list[PointTransfer], views) -> str:
    """One line: per target view how many of the points that lacked it were found, and why the
    rest were not (the search's status; ``outside``: the prediction left the image)."""
    parts, why = [], Counter()
    for v in views:
        asked = [r for r in results if v in r.targets]
        if not asked:
            continue
        ok = sum(1 for r in asked if v in r.found and r.found[v].ok)
        parts.append(f"{v} {ok} of {len(asked)}")
        why.update(r.found[v].match.status if v in r.found else "outside"
                   for r in asked if not (v in r.found and r.found[v].ok))
    text = f"found: {', '.join(parts)}" if parts else "found: nothing to search"
    if why:
        text += "; not found: " + ", ".join(f"{n} {s}" for s, n in why.most_common())
    return text


def transfer_record(results: list[PointTransfer]) -> dict:
    """The JSON document of a run (docs/formats.md, point transfer report): per point its source
    view and position, and per target view the status, position (px; null where not found),
    σ along and across the parallax (px), covariance (px², x then y), parallax direction (unit),
    correlation and why it was not found."""
    def view(t):
        if t is None:
            return {"status": "outside", "reason": OUTSIDE_REASON}
        along, across = parallax_sigmas(t)
        ok = t.ok
        return {"status": t.match.status, "x": float(t.x) if ok else None, "y": float(t.y) if ok else None,
                "sigma_along_px": along if ok else None, "sigma_across_px": across if ok else None,
                "cov_px2": np.asarray(t.match.cov, float).tolist() if ok else None,
                "parallax": np.asarray(t.match.extra.get("d", (math.nan, math.nan)), float).tolist(),
                "rho": float(t.match.rho), "reason": t.match.reason}
    return {"points": [{"id": r.pid, "source": r.source, "x": r.xy[0], "y": r.xy[1],
                        "views": {v: view(r.found.get(v)) for v in r.targets}} for r in results]}

