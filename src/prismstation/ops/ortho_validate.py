"""An orthoimage checked against the project's points: for each GCP or ICP measured in the
ortho's view, where the ortho shows it, against its known ground position.

**The match.** Around the known position ``K`` the ortho shows the view's image at ``f(g)`` —
``f`` the fitted model on the ortho's heights, ``g`` a cell. The template is the same image,
resampled by the same kernel on the same cells at ``f(g) + r``, ``r = m − f(K)`` the operator's
measurement ``m`` less where the model puts ``K``: so the template shows the point at ``K``, in
exactly the ortho's geometry (relief, scale, rotation, the kernel's smoothing), and differs from
the ortho only by the translation the ortho is off by there. A raw image chip matched against the
ortho would carry the view's own rotation and relief into the match; a chip of another view would
carry its own geometry and radiometry. The template is matched in the ortho (normalised
cross-correlation, then least-squares matching: :func:`prismstation.core.matching.matching.match_point`)
within ``±R`` cells of ``K``, ``R`` from the ortho's stated accuracy (four times its expected σ,
at least :data:`MIN_SEARCH_PX`): where it lands is where the ortho shows the point. A point not
found there is reported as such, not moved.

The displacement ``shown − known`` (metres east, north) per point, RMSE per kind, and the
model's own figure for it (``J⁻¹·r`` with ``J = ∂(x, y)/∂(E, N)``: what the fit says, against
what the file shows).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from prismstation.core.matching.matching import OK, match_point
from prismstation.errors import InputError
from prismstation.io.ortho import read_ortho_info, read_ortho_window
from prismstation.io.project import project_geoid
from prismstation.ops.ortho import _with_undulation
from prismstation.ops.ortho_tiles import Heights, sample_view
from prismstation.ops.predict import known_ground
from prismstation.ops.progress import checkpoint

#: the template's half size (cells): 2·12 + 1 = 25 cells
HALF = 12
MIN_SEARCH_PX = 4
MAX_SEARCH_PX = 64
#: the search when the ortho states no accuracy (cells)
DEFAULT_SEARCH_PX = 16


@dataclass(frozen=True)
class PointCheck:
    """One point: ``known`` (E, N) and where the ortho ``shown`` it (NaN when not found), the
    displacement ``d`` = shown − known (m E, N), the model's ``predicted`` displacement, the
    match's ``score`` (NCC) and ``sigma_m`` (its σ per axis), ``status`` (``ok`` or why not)."""

    id: str
    kind: str
    known: tuple
    shown: tuple
    d: tuple
    predicted: tuple
    score: float
    sigma_m: tuple
    status: str
    reason: str = ""

    @property
    def found(self) -> bool:
        return self.status == OK


@dataclass(frozen=True)
class OrthoValidation:
    """The check of one ortho: its ``path`` and ``view``, each point's :class:`PointCheck`, the
    statistics per kind (``n``, ``rmse_e_m``, ``rmse_n_m``, ``rmse_m`` planimetric, ``mean_e_m``,
    ``mean_n_m``, ``not_found``), the ortho's expected σ (m, RMS radial) and the search radius."""

    path: str
    view: str
    posting_m: float
    points: tuple
    stats: dict
    expected_sigma_m: float | None
    search_px: int
    notes: tuple = ()

    def as_dict(self) -> dict:
        d = asdict(self)
        d["points"] = [asdict(p) for p in self.points]
        d["notes"] = list(self.notes)
        return d


def heights_of_ortho(info: dict, project) -> Heights:
    """The :class:`Heights` an ortho was made on, from its metadata (the project's geoid for
    orthometric heights)."""
    tags = info["tags"]
    kind = tags.get("ORTHO_DEM_KIND")
    if kind not in ("orthometric", "ellipsoidal"):
        raise InputError("not an orthoimage of prismstation (no ORTHO_DEM_KIND tag)")
    crs = project.scene.crs
    if tags.get("ORTHO_DEM_PATH"):
        if not Path(tags["ORTHO_DEM_PATH"]).exists():
            raise InputError(f"the ortho's DEM {tags['ORTHO_DEM_PATH']} is not found")
        heights = Heights(crs, kind, tags["ORTHO_DEM_PATH"])
    else:
        heights = Heights(crs, kind, constant=float(tags["ORTHO_DEM_CONSTANT_M"]))
    if kind == "orthometric":
        a, _, c, _, e, f = info["transform"]
        rows, cols = info["shape"]
        heights = _with_undulation(heights, project_geoid(project), (c, f + e * rows, c + a * cols, f))
    return heights


def project_points(project, view: str, kinds=("GCP", "ICP")) -> list:
    """``(id, kind, (E, N, h), (x, y))`` of the project's points of ``kinds`` with ground
    coordinates measured in ``view`` (heights ellipsoidal)."""
    ground = known_ground(project)
    out = []
    for pid, g in ground.items():
        p = project.points[pid]
        m = project.measurements.get((pid, view))
        if p.kind in kinds and m is not None:
            out.append((pid, p.kind, tuple(g), (float(m.x), float(m.y))))
    return out


def validate_ortho(sol, project, path, *, points=None, kinds=("GCP", "ICP"), half: int = HALF,
                   progress=None) -> OrthoValidation:
    """Check the ortho ``path`` (made from ``project``; ``sol`` its fit) at ``points`` (default
    :func:`project_points` of ``kinds``): see the module docstring."""
    info = read_ortho_info(path)
    tags = info["tags"]
    view = tags.get("ORTHO_VIEW")
    if view is None:
        raise InputError("not an orthoimage of prismstation (no ORTHO_VIEW tag)", file=path)
    if view not in sol.scene.views:
        raise InputError(f"the ortho is of view {view!r}, not a view of the project "
                         f"({', '.join(sol.scene.views)})", file=path)
    notes = []
    if str(sol.revision) != tags.get("ORTHO_REVISION", str(sol.revision)):
        notes.append(f"the ortho was made at the project's revision {tags.get('ORTHO_REVISION')}, the fit is of "
                     f"revision {sol.revision}: the model may differ")
    heights = heights_of_ortho(info, project)
    a, _, c, _, e, f = info["transform"]
    posting = abs(a)
    resampling = tags.get("ORTHO_RESAMPLING", "bilinear")
    v = sol.scene.views[view]
    factor = max(1, int(math.floor(posting / v.pixel_size_m + 1e-6)))
    try:
        expected = float(tags.get("ORTHO_EXPECTED_SIGMA_M", "unknown"))
    except ValueError:
        expected = None
    search = (DEFAULT_SEARCH_PX if expected is None
              else int(min(max(math.ceil(4 * expected / posting), MIN_SEARCH_PX), MAX_SEARCH_PX)))
    pts = project_points(project, view, kinds) if points is None else list(points)
    model = sol.model
    g2i = lambda en, h: model.ground_to_image(view, en, h)  # noqa: E731
    checks = []
    for k, (pid, kind, g, m) in enumerate(pts):
        checkpoint(progress, k / max(len(pts), 1), f"point {pid}")
        checks.append(_check_point(pid, kind, g, m, g2i, model, view, v, heights, (a, c, e, f), posting,
                                   resampling, factor, search, half, path))
    checkpoint(progress, 1.0, "done")
    return OrthoValidation(str(path), view, posting, tuple(checks), _stats(checks), expected, search, tuple(notes))


def _check_point(pid, kind, g, m, g2i, model, view, v, heights, grid, posting, resampling, factor, search,
                 half, path) -> PointCheck:
    a, c, e, f = grid
    E, N = float(g[0]), float(g[1])
    nan2 = (math.nan, math.nan)

    def fail(status, reason, predicted=nan2):
        return PointCheck(pid, kind, (E, N), nan2, nan2, predicted, math.nan, nan2, status, reason)
    col, row = (E - c) / a, (N - f) / e                  # continuous cell coordinates of K
    n = half + search + 4
    r0, c0 = int(math.floor(row)) - n, int(math.floor(col)) - n
    size = 2 * n + 1
    patch = read_ortho_window(path, (r0, c0, size, size))
    if not np.isfinite(patch[n - half:n + half + 1, n - half:n + half + 1]).all():
        return fail("outside", "the ortho has no data around the point")
    t = (a, 0.0, c + a * c0, 0.0, e, f + e * r0)
    hk = heights.at(np.array([[E, N]]))[0]
    if not np.isfinite(hk):
        return fail("outside", "the DEM has no height at the point")
    fk = np.asarray(g2i(np.array([[E, N]]), np.array([hk])), float)[0]
    r = np.asarray(m, float) - fk
    # the model's own displacement: J⁻¹·r at K
    _, J = model.partials(view, np.array([[E, N]]), np.array([hk]))
    dEN = np.linalg.solve(J[0, :, :2], r)
    predicted = (float(dEN[0]), float(dEN[1]))
    tile = sample_view(lambda en, h: np.asarray(g2i(en, h), float) + r, view, v.image, v.shape, t,
                       heights.on_grid(t, (size, size)), resampling, factor)
    template = tile.values
    kx, ky = col - c0, row - r0
    if not np.isfinite(template[int(ky) - half:int(ky) + half + 1, int(kx) - half:int(kx) + half + 1]).all():
        return fail("outside", "the image has no data around the measurement", predicted)
    res = match_point(np.nan_to_num(template), kx, ky, np.nan_to_num(patch), kx, ky, search_range=float(search),
                      half_window=half, lsm=True)
    if res.status != OK:
        return fail(res.status, res.reason or res.status, predicted)
    sx, sy = c + a * (c0 + res.x), f + e * (r0 + res.y)
    return PointCheck(pid, kind, (E, N), (sx, sy), (sx - E, sy - N), predicted, float(res.score),
                      (float(res.sigma_x) * posting, float(res.sigma_y) * posting), OK)


def _stats(checks) -> dict:
    out = {}
    for kind in sorted({p.kind for p in checks}):
        sel = [p for p in checks if p.kind == kind]
        d = np.array([p.d for p in sel if p.found], float).reshape(-1, 2)
        n = len(d)
        s = {"n": n, "not_found": len(sel) - n}
        if n:
            rms = np.sqrt(np.mean(d ** 2, axis=0))
            s.update(rmse_e_m=float(rms[0]), rmse_n_m=float(rms[1]), rmse_m=float(np.hypot(*rms)),
                     mean_e_m=float(d[:, 0].mean()), mean_n_m=float(d[:, 1].mean()))
        out[kind] = s
    return out
