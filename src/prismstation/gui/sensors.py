"""Each sensor model's own parts of the window, by the model's name (``Scene.sensor.name``,
:mod:`prismstation.core.models.sensors`): the one place the window picks a model's widgets. Generic
parts (the model panel, the accuracy strip, the plots, the orientation tool) ask
:func:`parts_of` and never which model it is.

A model's parts (:class:`SensorParts`, a module that has these functions; no Qt):

``panel_sections(sol) → (sections, notes)``
    the model panel's sections of the model's own (the PRISM parallax line) and their notes;
``fit_warning(sol) → (wordings, full)``
    what the accuracy strip's figures stand on that does not hold ("" when nothing);
``plot_line(sol)``
    ``(c0, c1, c1 theoretical)`` of a height–parallax line the plots draw, or None;
``orientable(scene)``, ``orient_request(patch_m, posting_m, sigma_m, target_m)``
    whether the orientation from a reference DEM applies to the scene; the orientation
    dialog's choices as the model's :class:`~prismstation.ops.orientation.OrientRequest`;
``orientation_text(record, state, scale)``, ``verdict_text(record)``, ``applied_text(record)``
    a stored orientation (``Project.dem_control``) in words for the dock, its verdict, and
    the status line once it is applied.
"""
from __future__ import annotations

from typing import Protocol

from prismstation.gui import prism_parts, rpc_parts


class SensorParts(Protocol):
    """A sensor model's own parts of the window (module docstring)."""

    def panel_sections(self, sol) -> tuple[list, list]: ...

    def fit_warning(self, sol) -> tuple[tuple[str, ...], str]: ...

    def plot_line(self, sol): ...

    def orientable(self, scene) -> bool: ...

    def orient_request(self, patch_m: float, posting_m: float, sigma_m: float, target_m: float): ...

    def orientation_text(self, record: dict, state: str, scale: float | None = None) -> str: ...

    def verdict_text(self, record: dict) -> str: ...

    def applied_text(self, record: dict) -> str: ...


#: model name → its parts
PARTS: dict[str, SensorParts] = {"prism": prism_parts, "rpc": rpc_parts}


def parts_of(sensor) -> SensorParts:
    """The parts of sensor model class ``sensor`` (``Scene.sensor``)."""
    return PARTS[sensor.name]
