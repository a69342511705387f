"""Ground points and image measurements as the project holds them (docs/formats.md).

Coordinates: ``E``, ``N`` in metres of the project CRS; ``H`` in metres, of the kind named by
``height_kind`` (``"ellipsoidal"`` or ``"orthometric"``). Image coordinates ``x`` (column), ``y``
(row) in pixels, origin at the top-left corner of the top-left pixel (docs/model.md §1).
"""
from __future__ import annotations

from dataclasses import dataclass, field

KINDS = ("GCP", "ICP", "TIE")
HEIGHT_KINDS = ("ellipsoidal", "orthometric")


@dataclass(frozen=True)
class GroundPoint:
    """A point with known ground coordinates (kind ``GCP`` or ``ICP``)."""

    id: str
    E: float
    N: float
    H: float
    height_kind: str = "ellipsoidal"
    kind: str = "GCP"
    sigma_xy_m: float | None = None
    sigma_h_m: float | None = None
    extra: dict = field(default_factory=dict, compare=False)  # unknown CSV columns, kept


@dataclass(frozen=True)
class Measurement:
    """One point measured in one view."""

    id: str
    view: str
    x: float
    y: float
    sigma_px: float | None = None
