"""Each sensor model's workflows on a project, by the model's name (``Scene.sensor.name``,
:mod:`prismstation.core.models.sensors`): the one place the front ends find which function orients a
project from a reference DEM and which makes its DSM. ``prismstation orient-dem``, ``dsm`` and
the window's tools call :func:`workflows_of` and never ask which model it is.

A model's workflows (:class:`SensorWorkflows`, a module that has these functions):

``orient(project, reference, request, *, solution=None, progress=None) → Orientation``
    the orientation from the reference DEM file ``reference``
    (:class:`~prismstation.ops.orientation.OrientRequest` in,
    :class:`~prismstation.ops.orientation.Orientation` out: one verdict, one record to store with
    :func:`~prismstation.ops.orientation.apply_orientation`); ``solution`` the project's fit
    where the window has one (the model fits the project when it needs one and is given none);
``export_dsm(sol, project, request, *, reference=None, progress=None) → DsmExport``
    the DSM of the fitted solution written as ``request`` asks
    (:class:`~prismstation.ops.dsm_export.DsmRequest`,
    :class:`~prismstation.ops.dsm_export.DsmExport`).

The commands a model offers at all are its ``workflows`` names
(:func:`prismstation.ops.project.require_workflow`).
"""
from __future__ import annotations

from typing import Protocol

from prismstation.ops import prism_project, rpc_project


class SensorWorkflows(Protocol):
    """What a sensor model does on a project beyond its fit (module docstring)."""

    def orient(self, project, reference, request, *, solution=None, progress=None): ...

    def export_dsm(self, sol, project, request, *, reference=None, progress=None): ...


#: model name → its workflows
WORKFLOWS: dict[str, SensorWorkflows] = {"prism": prism_project, "rpc": rpc_project}


def workflows_of(project) -> SensorWorkflows:
    """The workflows of ``project``'s sensor model."""
    return WORKFLOWS[project.scene.sensor.name]
