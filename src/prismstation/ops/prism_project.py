"""The PRISM model's workflows on a project (:mod:`prismstation.ops.sensors`): its orientation
from a reference DEM (:func:`orient`, the engine of :mod:`prismstation.ops.orient_dem`) as an
:class:`~prismstation.ops.orientation.Orientation`, and its DSM
(:func:`prismstation.ops.dsm_export.export_dsm`).
"""
from __future__ import annotations

import math

from prismstation.core.orientation.conditioning import SigmaSummary
from prismstation.model.project import Project
from prismstation.ops.coarse_offsets import SIGMA_APRIORI_M
from prismstation.ops.dsm_export import export_dsm
from prismstation.ops.orient_dem import DemOrientation, control_points, orient_from_dem
from prismstation.ops.orientation import Orientation, OrientRequest, default_patch_km
from prismstation.ops.progress import ProgressFn
from prismstation.ops.reference_heights import datum_note

__all__ = ["export_dsm", "orient", "orientation_lines"]

#: the matching's grid posting when the request gives none (m)
POSTING_M = 30.0


def orient(project: Project, reference, request: OrientRequest = OrientRequest(), *, solution=None,
           progress: ProgressFn | None = None) -> Orientation:
    """The triplet oriented from the reference DEM file ``reference``
    (:func:`~prismstation.ops.orient_dem.orient_from_dem`; ``solution`` is not needed: the
    engine starts from the ancillary model). Its verdict judges the field's σ against
    ``request.target_m``; an orientation that is not trusted is still one to apply (the
    operator decides)."""
    sigma = SIGMA_APRIORI_M if request.sigma_apriori_m is None else request.sigma_apriori_m
    gcps = control_points(project) if request.with_gcps else None
    patch_m = default_patch_km(project.scene) * 1000.0 if request.patch_m is None else request.patch_m
    result = orient_from_dem(project, reference, sigma_apriori_m=sigma, gcps=gcps, patch_m=patch_m,
                             posting_m=POSTING_M if request.posting_m is None else request.posting_m,
                             target_m=request.target_m, progress=progress)
    record = result.to_dict()
    used = sum(1 for p in result.patches if p.used)
    out = Orientation(result.verdict, record, tuple(orientation_lines(project, result, gcps is not None)),
                      {"dem_control": record}, f"{used} patch{'' if used == 1 else 'es'}", result)
    return out.noting("" if gcps else datum_note(project, reference))


def orientation_lines(project: Project, result: DemOrientation, with_gcps: bool = False) -> list[str]:
    """The orientation in words: the a-priori σ, the view offsets and their drift, the second
    pass, the GCPs' part, the σ expected and stated, every patch and the verdict."""
    out = []
    off = result.offsets_px
    out.append(f"a-priori geolocation σ {result.sigma_apriori_m:g} m per view; F−N ({off['F'][0]:+.2f}, "
               f"{off['F'][1]:+.2f}) px, B−N ({off['B'][0]:+.2f}, {off['B'][1]:+.2f}) px from the ancillary model"
               " at N's centre")
    rows, cols = project.scene.views["N"].shape
    for v, g in (result.gradients_px or {}).items():
        if any(c for row in g for c in row):
            span = [abs(g[k][0]) * cols + abs(g[k][1]) * rows for k in range(2)]
            out.append(f"  {v}−N varies over N (attitude drift): up to ±{span[0] / 2:.2f} px in x, "
                       f"±{span[1] / 2:.2f} px in y from its centre value")
    first = result.coarse.get("first_pass")
    if first:
        moved = [max(abs(a - b) for a, b in zip(off[v], first["offsets_px"][v])) for v in "FB"]
        out.append(f"  second pass with N placed by the patches: the offsets moved by up to {max(moved):.2f} px")
    elif result.coarse.get("second_pass"):
        out.append(f"  second pass {result.coarse['second_pass']}")
    adj = result.adjustment or {}
    if with_gcps:
        out.append(f"{adj.get('gcp_observations', 0)} GCPs in the adjustment with the reference DEM's patches; "
                   f"the reference's own offset from them (E, N, h): "
                   f"{', '.join(f'{v:+.2f}' for v in (result.field or {}).get('offset', []))} m")
    out.append(f"expected from the terrain before the run: "
               f"{SigmaSummary.from_dict(result.expected_sigma_m or {}).text()}")
    used = [p for p in result.patches if p.used]
    out.append(f"{len(used)} of {len(result.patches)} patches used, {adj.get('cells', 0)} cells in one adjustment; "
               f"each patch's own shift beyond its cells' noise σ_b (E, N, h) "
               f"{', '.join(f'{v:.2f}' for v in adj.get('sigma_b_m') or [])} m")
    for p in result.patches:
        state = "used" if p.used else f"not used: {p.reason}"
        if math.isfinite(p.dE):
            sig = ", ".join("—" if not math.isfinite(v) else f"{v:.2f}" for v in (p.sigma_E, p.sigma_N, p.sigma_h))
            shift = f"dE {p.dE:+7.2f} dN {p.dN:+7.2f} dh {p.dh:+7.2f} m  σ ({sig})"
        else:
            shift = "no shift"
        out.append(f"  patch at ({p.x:7.0f}, {p.y:7.0f}) px: {shift}  {state}")
    frame = "the GCPs'" if with_gcps else "the reference DEM's"
    out.append(f"after the run: {SigmaSummary.from_dict(result.sigma_m).text()} (in {frame} frame)")
    out.append(f"verdict: {result.verdict.message}")
    if result.verdict.advice:
        out.append(f"  what would help: {result.verdict.advice}")
    return out
