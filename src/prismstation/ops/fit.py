"""Fitting a project: its heights made ellipsoidal through its geoid setting, its DEM control
(when the project is oriented from a reference DEM) rebuilt by its sensor model, then the
scene's sensor model fitted (:func:`prismstation.core.models.solution.solve`).

A caller that fits one project again and again (the window's solver, after every click) keeps
a :class:`FitMemo`: what the next fit may take again from the last ones."""
from __future__ import annotations

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

#: the bias and parallax models a fit can use, of every sensor model (their names: the front
#: ends' choices; a project's own are ``project.scene.sensor.bias_models``)
BIAS_MODELS = {k: n for m in sensors.MODELS.values() for k, n in m.bias_models.items()}
PARALLAX_MODELS = tuple(dict.fromkeys(k for m in sensors.MODELS.values() for k in m.parallax_models))
__all__ = ["BIAS_MODELS", "PARALLAX_MODELS", "FitMemo", "ellipsoidal_heights", "fit_report", "project_report",
           "solve_project"]


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
    ``height_sigma_m`` metres. ``memo``: the caller's :class:`FitMemo` (the same results,
    sooner); without one every fit computes everything.
    """
    h = memo.heights(project) if memo is not None else ellipsoidal_heights(project)
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
