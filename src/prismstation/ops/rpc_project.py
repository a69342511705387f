"""The RPC model's workflows on a project (:mod:`prismstation.ops.sensors`): its DSM
(:func:`export_dsm`) and its orientation from a reference DEM (:func:`orient`) as an
:class:`~prismstation.ops.orientation.Orientation`.

The project-level side of :func:`prismstation.ops.rpc_dsm.rpc_dsm` and
:func:`prismstation.ops.rpc_orient.orient_rpc_from_dem`: the fitted model's biased RPCs
(``Solution.model.models``), the fit's intersected tie points for the search ranges, the
project's geoid for an orthometric reference and for orthometric output, and the record an
orientation leaves in the project (``Project.dem_control``) for the fit to read back as each
image's a-priori bias (:func:`prismstation.core.models.rpc_solve.control_from_record`).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from prismstation.core.orientation import conditioning as cond
from prismstation.core.models.rpc_bias import BIAS_NAMES
from prismstation.errors import InputError, ModelError
from prismstation.io.atomic import check_writable
from prismstation.io.jsonfile import plain
from prismstation.io.project import project_geoid
from prismstation.ops.coregister import result_dict
from prismstation.ops.dsm_export import DsmExport, DsmRequest
from prismstation.ops.fit import stored_solution
from prismstation.ops.orientation import Orientation, OrientRequest
from prismstation.ops.progress import checkpoint
from prismstation.ops.reference_heights import datum_note
from prismstation.ops.rpc_dsm_export import write_rpc_dsm
from prismstation.ops.rpc_orient import DEFAULT_MAX_SHIFT_M, orient_rpc_from_dem

#: widening (m) of the tie points' height range into the DSM's a-priori range (tiles narrow it
#: further to their own points': :func:`prismstation.ops.rpc_dsm.tile_height_range`)
POINTS_MARGIN_M = 100.0


def images_and_models(sol, project) -> tuple[list, list]:
    """The views' image files and their fitted :class:`~prismstation.core.models.rpc_bias.BiasedRpc`,
    in the scene's order."""
    views = project.scene.views
    missing = [v for v, view in views.items() if not view.image]
    if missing:
        raise InputError(f"the scene gives no image file for {', '.join(missing)}", project.scene_path)
    return [views[v].image for v in views], [sol.model.models[v] for v in views]


def tie_points(sol, project):
    """``(lon°, lat°, h m)`` arrays of every point the fit placed by intersection (ellipsoidal
    heights), or None when there is none."""
    g = np.array([p.ground_est for p in sol.points if p.ground_est is not None and p.height_source == "intersection"],
                 float).reshape(-1, 3)
    g = g[np.all(np.isfinite(g), axis=1)]
    if not len(g):
        return None
    lon, lat = next(iter(project.scene.views.values())).projection.to_lonlat(g[:, 0], g[:, 1])
    return np.asarray(lon, float), np.asarray(lat, float), g[:, 2]


def height_range(points, margin_m: float | None) -> tuple | None:
    """The DSM's a-priori heights: the points' range ± ``margin_m`` (default
    max(:data:`POINTS_MARGIN_M`, 25 % of their spread)), or None (the RPCs' own domain)."""
    if points is None or len(points[2]) < 3:
        return None
    lo, hi = float(np.min(points[2])), float(np.max(points[2]))
    m = max(POINTS_MARGIN_M, 0.25 * (hi - lo)) if margin_m is None else float(margin_m)
    return lo - m, hi + m


def export_dsm(sol, project, request: DsmRequest, *, reference=None, progress=None) -> DsmExport:
    """:func:`prismstation.ops.dsm_export.export_dsm` for images with RPCs: every pair matched
    and fused through the fitted biases over the images' common footprint (the first image's
    limited to the request's window), written tile by tile
    (:func:`~prismstation.ops.rpc_dsm_export.write_rpc_dsm`), the search from the fit's tie
    points (± the request's height uncertainty, default :func:`height_range`) and the reference
    DEM's heights (``reference``: a :class:`~prismstation.ops.reference_heights.DemHeights`,
    its file read again on the DSM's grid through the project's geoid). ``dsm.info`` is
    JSON-safe; the pairs' agreement is ``info["pair_agreement"]``."""
    if request.heights != "auto":
        raise InputError("images with RPCs have one height model, the rays' intersection (--heights auto)")
    if not sol.ok and project.settings.orientation != "dem":
        raise ModelError("; ".join(sol.messages) or "the model could not be fitted")
    check_writable(request.output)
    paths, models = images_and_models(sol, project)
    points = tie_points(sol, project)
    geoid = project_geoid(project)
    dsm = write_rpc_dsm(request.output, paths, models, posting=request.posting_m, window=request.window,
                        fill=request.fill, orthometric_geoid=geoid if request.orthometric else None,
                        height_range=height_range(points, request.height_uncertainty_m), points=points,
                        reference=None if reference is None else reference.path, geoid=geoid,
                        scheduler=request.scheduler, workers=request.workers,
                        progress=progress,
                        before_keep=lambda: checkpoint(progress, 1.0, "written"))
    return DsmExport(str(request.output), replace(dsm, info=plain(dsm.info)), request)


def orient_rpc_project(sol, project, reference, *, posting_m: float | None = None,
                       max_shift_m: float | None = None, progress=None):
    """The project's relative DSM (its fitted biases, one view held fixed or not) laid on the
    reference DEM file ``reference`` (orthometric heights, through the project's geoid):
    ``(RpcDemOrientation, dsm)`` (:func:`~prismstation.ops.rpc_orient.orient_rpc_from_dem`),
    the new biases of the project's bias model (``shift`` when it is ``none``)."""
    paths, models = images_and_models(sol, project)
    points = tie_points(sol, project)
    kind = project.settings.bias_model if project.settings.bias_model != "none" else "shift"
    return orient_rpc_from_dem(paths, models, reference, bias=kind, geoid=project_geoid(project),
                               posting=posting_m, points=points, height_range=height_range(points, None),
                               max_shift_m=DEFAULT_MAX_SHIFT_M if max_shift_m is None else max_shift_m,
                               progress=progress)


def orientation_record(project, orientation, reference) -> dict:
    """The ``dem_control`` record of an RPC orientation: each view's bias (model, parameters,
    σ, reference point px), the ground shift and its σ (m), the reference's file."""
    biases = {}
    for v, m, s in zip(project.scene.views, orientation.models, orientation.bias_sigma):
        biases[v] = {"model": m.kind, "params": [float(p) for p in m.params],
                     "sigma": [float(x) for x in s], "x0": float(m.x0), "y0": float(m.y0)}
    return {"sensor": "rpc", "reference": str(reference), "biases": biases,
            "shift_m": [float(x) for x in orientation.shift_m], "sigma_m": [float(x) for x in orientation.sigma_m]}


def orientation_biases(project, orientation) -> dict:
    """View → ``{"model", "names", "params", "sigma", "change"}`` (px, px per 1,000 px) of an
    orientation's new biases: what the command line prints and writes."""
    return {v: {"model": m.kind, "names": list(BIAS_NAMES[m.kind]), "params": [float(x) for x in m.params],
                "sigma": [float(x) for x in e], "change": [float(x) for x in c]}
            for v, m, c, e in zip(project.scene.views, orientation.models, orientation.bias_change,
                                  orientation.bias_sigma)}


def orient(project, reference, request: OrientRequest = OrientRequest(), *, solution=None,
           progress=None) -> Orientation:
    """The images' relative DSM laid on the reference DEM file ``reference``
    (:func:`orient_rpc_project` on ``solution``, default the project's stored orientation,
    :func:`~prismstation.ops.fit.stored_solution`): each image's
    new bias with its σ, to become the fit's a-priori biases. The search bound is 3 ×
    ``request.sigma_apriori_m`` (default :data:`~prismstation.ops.rpc_orient.DEFAULT_MAX_SHIFT_M`).
    A co-registration that failed is refused (verdict ``failed``, nothing to apply)."""
    sol = stored_solution(project)[0] if solution is None else solution
    sigma = request.sigma_apriori_m
    o, dsm = orient_rpc_project(sol, project, reference, posting_m=request.posting_m,
                                max_shift_m=None if sigma is None else 3.0 * sigma, progress=progress)
    doc = {"coregistration": result_dict(o.coreg, str(reference), "relative DSM",
                                         crs_transform=tuple(dsm.transform)[:6]),
           "posting_m": dsm.posting_m, "fill": dsm.fill_fraction}
    if not o:
        verdict = cond.OrientVerdict(cond.FAILED, f"the images' DSM could not be laid on the reference: "
                                     f"{o.coreg.reason}", "", request.target_m)
        return Orientation(verdict, None, (), plain(doc), "RPC biases", o, "report")
    s, sg = o.shift_m, o.sigma_m
    doc["biases"] = orientation_biases(project, o)
    lines = [f"relative DSM at {dsm.posting_m:.1f} m ({100 * dsm.fill_fraction:.0f} % matched) laid on "
             f"{reference}: the block moves dE {s[0]:+.2f} ± {sg[0]:.2f}, dN {s[1]:+.2f} ± {sg[1]:.2f}, "
             f"dh {s[2]:+.2f} ± {sg[2]:.2f} m"]
    for v, b in doc["biases"].items():
        lines.append(f"  {v}: {b['model']} bias " + ", ".join(f"{n} {p:+.3f} ± {q:.3f}" for n, p, q in
                                                             zip(b["names"], b["params"], b["sigma"]))
                     + " (change " + ", ".join(f"{x:+.3f}" for x in b["change"]) + ")")
    verdict = cond.OrientVerdict(cond.OK, f"the images' DSM laid on the reference: the block moves by "
                                 f"({s[0]:+.2f}, {s[1]:+.2f}, {s[2]:+.2f}) ± ({sg[0]:.2f}, {sg[1]:.2f}, "
                                 f"{sg[2]:.2f}) m", "", request.target_m)
    return Orientation(verdict, orientation_record(project, o, reference), tuple(lines), plain(doc), "RPC biases",
                       o, "report").noting(datum_note(project, reference))
