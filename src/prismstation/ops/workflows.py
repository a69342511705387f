"""Each sensor model's workflow functions, keyed by the model's name (``Scene.sensor.name``):
the one place the front ends and the fit look up which function makes a project's DSM, which
rebuilds its orientation from a reference DEM, and which orients it from a reference DEM.

The commands a model offers are its ``workflows``
(:attr:`SensorModel.workflows <prismstation.core.sensor.SensorModel>`,
:func:`prismstation.ops.project.require_workflow`); this table holds the functions behind them.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from prismstation.ops import dsm_export, orient_dem, rpc_project


@dataclass(frozen=True)
class SensorWorkflows:
    """``export_dsm(sol, project, request, *, reference, progress) → DsmExport``;
    ``control_from_record(scene, record)``: a saved orientation from a reference DEM as the
    fit's ``control``; ``orient`` and ``apply_orientation``: the orientation from a reference
    DEM and how it is stored (their arguments are the model's own)."""

    export_dsm: Callable
    control_from_record: Callable
    orient: Callable
    apply_orientation: Callable


WORKFLOWS = {
    "prism": SensorWorkflows(dsm_export.export_dsm, orient_dem.control_from_record,
                             orient_dem.orient_from_dem, orient_dem.apply_orientation),
    "rpc": SensorWorkflows(rpc_project.export_rpc_dsm, rpc_project.control_from_record,
                           rpc_project.orient_rpc_project, rpc_project.apply_rpc_orientation),
}


def workflows(project) -> SensorWorkflows:
    """The workflow functions of ``project``'s sensor model."""
    return WORKFLOWS[project.scene.sensor.name]
