"""Fitting a project: its heights made ellipsoidal through its geoid setting, its DEM control
(when the project is oriented from a reference DEM) rebuilt by its sensor model, then the
scene's sensor model fitted (:func:`prismstation.core.models.solution.solve`).

A caller that fits one project again and again (the window's solver, after every click) keeps
a :class:`FitMemo`: what the next fit may take again from the last ones.

The project's orientation is kept in the project: its settings (``project.settings``: the bias
model of each view, the view held fixed, whether GCPs are used, the reference DEM's σ) and its
reference DEM (``project.reference_dem``), which every command and the window fit with
(:func:`stored_solution`: one place), and the result ``fit`` stored
(:func:`orientation_record` → ``project.orientation``). :func:`heights_not_fixed` says when a
bias the data cannot determine decides the heights."""
from __future__ import annotations

import hashlib
import math
import threading

import numpy as np

from prismstation.core.models import sensors
from prismstation.core.models.recent import Recent
from prismstation.core.models.solution import Solution, solve
from prismstation.errors import InputError, ModelError
from prismstation.io.geoid import to_ellipsoidal
from prismstation.io.project import project_geoid
from prismstation.io.report import report_dict, report_header
from prismstation.model.project import Project, has_ground
from prismstation.ops.reference_heights import DemHeights, height_sigma, load_for_scene

#: the bias and parallax models a fit can use, of every sensor model (their names: the front
#: ends' choices; a project's own are ``project.scene.sensor.bias_models``)
BIAS_MODELS = {k: n for m in sensors.MODELS.values() for k, n in m.bias_models.items()}
PARALLAX_MODELS = tuple(dict.fromkeys(k for m in sensors.MODELS.values() for k in m.parallax_models))
__all__ = ["BIAS_MODELS", "PARALLAX_MODELS", "FitMemo", "ellipsoidal_heights", "fit_report", "heights_not_fixed",
           "orientation_record", "project_report", "reference_sigma", "solve_project", "stale_orientation",
           "stored_solution"]

#: σ (m) of a reference DEM's heights when the settings give none (an SRTM-class DEM: 16 m
#: LE90 absolute, about 10 m σ; the same as :data:`prismstation.ops.predict.DEFAULT_DEM_SIGMA_M`)
DEFAULT_REFERENCE_SIGMA_M = 10.0


class FitMemo:
    """What one caller's fits of a project take again from the last ones (thread-safe): the
    ellipsoidal heights of its points (:meth:`heights`: a click moves a measurement, not a
    point) and the model's pure fits of the same inputs (``recent``, a
    :class:`~prismstation.core.models.recent.Recent`: a click refits every view and moves one)."""

    def __init__(self, size: int = 16):
        self.recent = Recent(size)
        self._heights: tuple = (None, None)  # (what they were computed from, the heights)
        self._lock = threading.Lock()

    def heights(self, project: Project) -> dict[str, float]:
        """:func:`ellipsoidal_heights` of ``project``, the last ones again while the points, the
        geoid setting and the scene are the same. The dict is shared: read it, do not change it."""
        key = (tuple(project.points.values()), repr(project.geoid), project.scene)
        with self._lock:
            last_key, last = self._heights
        if last_key is not None and last_key[2] is key[2] and last_key[:2] == key[:2]:
            return last
        h = ellipsoidal_heights(project)
        with self._lock:
            self._heights = (key, h)
        return h


def ellipsoidal_heights(project: Project) -> dict[str, float]:
    """Point id → ellipsoidal height (m) of every point with ground coordinates; orthometric
    heights through the project's geoid, which must cover them."""
    ground = [p for p in project.points.values() if has_ground(p)]
    h = np.array([p.H for p in ground], float)
    ortho = np.array([p.height_kind == "orthometric" for p in ground], bool)
    if ortho.any():
        E = np.array([p.E for p in ground], float)[ortho]
        N = np.array([p.N for p in ground], float)[ortho]
        h[ortho] = to_ellipsoidal(h[ortho], project_geoid(project), E, N, project.scene.crs)
        if not np.all(np.isfinite(h)):
            raise InputError("the geoid grid does not cover every point with orthometric height")
    return {p.id: float(v) for p, v in zip(ground, h)}


def solve_project(project: Project, *, height_of=None, height_sigma_m: float | None = None,
                  memo: FitMemo | None = None) -> Solution:
    """Fit the model to the project (heights made ellipsoidal through its geoid).

    ``height_of``: optional ``(n, 2)`` map metres → ``(n,)`` ellipsoidal metres, the height of
    points no pair of rays places (a reference DEM; default the mean height), and, for a model
    that holds tie points to it (RPC images with too few GCPs), their height with σ
    ``height_sigma_m`` metres (default :func:`reference_sigma`: the settings' σ ⊕ the slope
    term of :func:`~prismstation.ops.reference_heights.height_sigma`). ``memo``: the caller's :class:`FitMemo` (the same results,
    sooner); without one every fit computes everything.
    """
    h = memo.heights(project) if memo is not None else ellipsoidal_heights(project)
    if height_of is not None and height_sigma_m is None:
        height_sigma_m = reference_sigma(project.settings, height_of)
    control = None
    if project.settings.orientation == "dem":
        if project.dem_control is None:
            raise InputError("the project is set to orientation from a reference DEM but holds no "
                             "DEM control: run orient-dem first")
        try:
            control = project.scene.sensor.control_from_record(project.scene, project.dem_control)
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f'the project\'s "dem_control" record is malformed ({exc!r}): run '
                             "orient-dem again") from None
    return solve(project.scene, project.point_obs(h), project.settings, height_of=height_of,
                 height_sigma_m=height_sigma_m, revision=project.revision, control=control,
                 recent=None if memo is None else memo.recent)


def project_report(project: Project, sol: Solution, project_path=None, *, operator: str | None = None,
                   created=None) -> dict:
    """The report of ``sol`` fitted on ``project`` (:func:`prismstation.io.report.report_dict`):
    header (date ``created``, default now; ``operator``, default the login name; program
    version; project; scene and product ids) and the known coordinates of every point with
    ground coordinates beside its residuals."""
    h = ellipsoidal_heights(project)
    known = {pid: {"E": p.E, "N": p.N, "h": h[pid], "H": p.H, "height_kind": p.height_kind}
             for pid, p in project.points.items() if pid in h}
    header = report_header(project.scene, scene_path=project.scene_path, project_path=project_path,
                           operator=operator, created=created, orientation=project.settings.orientation)
    geoid = project_geoid(project).describe() if project.geoid else None
    return report_dict(sol, project_path=project_path, geoid=geoid, header=header, known=known)


def fit_report(project: Project, project_path=None, *, height_of=None, height_sigma_m: float | None = None,
               operator: str | None = None) -> tuple[Solution, dict]:
    """Fit ``project`` and build its report (:func:`project_report`); a model that could not be
    fitted → :class:`ModelError` with the solver's messages. A project oriented from a DEM is
    reported even when its GCP fit is not ok (it may have no GCP)."""
    sol = solve_project(project, height_of=height_of, height_sigma_m=height_sigma_m)
    if not sol.ok and project.settings.orientation != "dem":
        raise ModelError("; ".join(sol.messages) or "the model could not be fitted")
    return sol, project_report(project, sol, project_path, operator=operator)


def reference_sigma(settings, height_of):
    """The σ of the reference DEM's heights the fit holds tie points to: the settings'
    ``reference_sigma_m`` (default :data:`DEFAULT_REFERENCE_SIGMA_M`), with the resolution's
    slope term where ``height_of`` is a :class:`DemHeights` (a function of map points), else
    the number."""
    s = DEFAULT_REFERENCE_SIGMA_M if settings.reference_sigma_m is None else float(settings.reference_sigma_m)
    return height_sigma(height_of, s) if isinstance(height_of, DemHeights) else s


def stored_solution(project: Project, *, reference: DemHeights | None = None, progress=None) -> tuple:
    """The project fitted as it is stored: its settings and its reference DEM
    (``project.reference_dem``, read through its geoid unless ``reference`` is that DEM read
    already): ``(Solution, DemHeights or None)``. The one fit ``fit``, ``report``, ``dsm``,
    ``orient-dem``, ``ortho`` and the window's save make."""
    if reference is None and project.reference_dem:
        reference = load_for_scene(project.reference_dem, project, progress)
    return solve_project(project, height_of=reference), reference


def _inputs_digest(project: Project) -> str:
    """A digest of what a fit takes from the project (points, measurements, settings, geoid,
    reference DEM, DEM control): equal digests, equal fits."""
    h = hashlib.sha256()
    for part in (sorted(project.points.values(), key=lambda p: p.id),
                 sorted(project.measurements.values(), key=lambda m: (m.id, m.view)),
                 project.settings, sorted((project.geoid or {}).items()), project.reference_dem,
                 project.dem_control):
        h.update(repr(part).encode())
    return h.hexdigest()[:16]


def _num(x):
    x = float(x)
    return x if math.isfinite(x) else None


def orientation_record(project: Project, sol: Solution) -> dict | None:
    """The result of a fit as the project stores it (``project.orientation``): each view's
    bias (model, parameter names, values, covariance, reference point px, held fixed, which
    parameters the data determined), σ0 and redundancy, how many GCPs and reference heights
    held it, the reference DEM, the fit's messages and a digest of its inputs. None for a model
    that keeps none (the PRISM model's orientation is its GCPs' or its ``dem_control``)."""
    model = sol.model
    if not hasattr(model, "undetermined"):
        return None
    views, s0, dof = {}, None, 0
    for v, b in model.bias.items():
        weak = set(model.undetermined.get(v, ()))
        views[v] = {"model": b.model, "names": list(b.names), "params": [_num(x) for x in b.params],
                    "cov": [[_num(x) for x in row] for row in np.asarray(b.cov, float)],
                    "x0": _num(b.x0), "y0": _num(b.y0), "fixed": bool(b.fixed),
                    "determined": [n not in weak for n in b.names]}
        if b.lsq is not None and s0 is None:
            s0, dof = b.sigma0, b.dof
    return {"sensor": model.name, "sigma0": None if s0 is None else _num(s0), "dof": int(dof), "views": views,
            "gcps": int(model.gcps), "reference_heights": int(model.held),
            "reference_dem": project.reference_dem, "ok": bool(sol.ok), "messages": list(sol.messages),
            "inputs": _inputs_digest(project)}


def stale_orientation(project: Project) -> str:
    """One line when the stored orientation was fitted on other inputs than the project holds
    now (points measured or settings changed since ``fit`` stored it), else ""."""
    rec = project.orientation
    if not rec or rec.get("inputs") == _inputs_digest(project):
        return ""
    return ("the project changed since fit stored its orientation: this run fits it again with the stored "
            "settings; run fit to store the new result")


def heights_not_fixed(sol: Solution) -> str:
    """Why the heights rest on bias parameters the data do not determine — no GCP in the fit,
    no tie point held to a reference DEM, no orientation from one, and a view's parameter left
    at its a-priori σ (:func:`prismstation.core.models.rpc_solve.undetermined`) — in one line;
    "" when the data fix them (or the model has no such parameters)."""
    model = sol.model
    weak = getattr(model, "undetermined", None)
    if not weak or model.gcps or model.held or sol.settings.orientation == "dem":
        return ""
    hs = [p.ground_sigma[2] for p in sol.points if p.ground_sigma is not None
          and p.height_source == "intersection" and math.isfinite(p.ground_sigma[2])]
    sigma = f" (the tie points' height σ median {float(np.median(hs)):.0f} m)" if hs else ""
    what = "; ".join(f"{v}: {', '.join(n)}" for v, n in weak.items())
    return (f"the heights rest on bias parameters the data do not determine ({what}): with no GCP and no "
            f"reference DEM a shift along the lines is a height{sigma}; fit --dem REFERENCE (or GCPs) fixes it")
