"""The project: one source of truth for points, measurements and settings.

Plain Python. Every edit goes through a method, bumps :attr:`Project.revision` and emits
:attr:`Project.changed` (with the revision). Solving is separate (:meth:`point_obs` feeds
:func:`prismstation.core.solve.solve`).
"""
from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import replace

from prismstation.core.scene import Scene
from prismstation.core.solve import PointObs, Settings
from prismstation.errors import InputError
from prismstation.model.points import KINDS, GroundPoint, Measurement
from prismstation.model.signal import Signal


class Project:
    """Points (ordered by id of creation), measurements keyed ``(id, view)``, settings.

    ``geoid`` is the setting dict (``{"kind": "constant", "value": 55}``, ``{"kind": "grid",
    "path": ...}``); turning it into undulations is the io layer's job.
    """

    def __init__(self, scene: Scene, scene_path: str | None = None, *, settings: Settings = Settings(),
                 geoid: dict | None = None):
        self.scene = scene
        self.scene_path = scene_path
        self.settings = settings
        self.geoid = geoid or {"kind": "constant",
                               "value": scene.geoid_undulation_m if scene.geoid_undulation_m is not None else 0.0}
        self.points: dict[str, GroundPoint] = {}
        self.measurements: dict[tuple[str, str], Measurement] = {}
        self.extra: dict = {}
        self.revision = 0
        self.changed = Signal()

    # ------------------------------------------------------------------ notifications
    def _touch(self) -> None:
        self.revision += 1
        self.changed.emit(self.revision)

    # ------------------------------------------------------------------ points
    def add_point(self, point: GroundPoint) -> None:
        if point.id in self.points:
            raise InputError(f"point {point.id!r} already exists")
        if point.kind not in KINDS:
            raise InputError(f"point kind {point.kind!r} is not one of {', '.join(KINDS)}")
        self.points[point.id] = point
        self._touch()

    def new_point_id(self, prefix: str = "P") -> str:
        i = len(self.points) + 1
        while f"{prefix}{i}" in self.points:
            i += 1
        return f"{prefix}{i}"

    def add_tie(self, pid: str | None = None) -> str:
        pid = pid or self.new_point_id("T")
        self.add_point(GroundPoint(pid, math.nan, math.nan, math.nan, kind="TIE"))
        return pid

    def remove_point(self, pid: str) -> tuple[GroundPoint, list[Measurement]]:
        """Remove a point and its measurements; returns both (for undo)."""
        point = self.points.pop(pid)
        ms = [self.measurements.pop(k) for k in [k for k in self.measurements if k[0] == pid]]
        self._touch()
        return point, ms

    def set_kind(self, pid: str, kind: str) -> str:
        """Switch GCP / ICP / TIE; returns the previous kind. A point without ground
        coordinates can only be a tie point."""
        p = self.points[pid]
        if kind not in KINDS:
            raise InputError(f"point kind {kind!r} is not one of {', '.join(KINDS)}")
        if kind != "TIE" and not has_ground(p):
            raise InputError(f"point {pid} has no ground coordinates: it can only be a tie point")
        self.points[pid] = replace(p, kind=kind)
        self._touch()
        return p.kind

    def replace_point(self, point: GroundPoint) -> GroundPoint:
        old = self.points[point.id]
        self.points[point.id] = point
        self._touch()
        return old

    # ------------------------------------------------------------------ measurements
    def set_measurement(self, m: Measurement) -> Measurement | None:
        """Place or move a measurement; creates a tie point if the id is new. Returns the old one."""
        if m.view not in self.scene.views:
            raise InputError(f"view {m.view!r} is not in the scene")
        if not (math.isfinite(m.x) and math.isfinite(m.y)):
            raise InputError("image coordinates must be finite numbers")
        if m.id not in self.points:
            self.points[m.id] = GroundPoint(m.id, math.nan, math.nan, math.nan, kind="TIE")
        old = self.measurements.get((m.id, m.view))
        self.measurements[m.id, m.view] = m
        self._touch()
        return old

    def remove_measurement(self, pid: str, view: str) -> Measurement | None:
        old = self.measurements.pop((pid, view), None)
        self._touch()
        return old

    def measurement(self, pid: str, view: str) -> Measurement | None:
        return self.measurements.get((pid, view))

    # ------------------------------------------------------------------ bulk and settings
    def load(self, points, measurements) -> None:
        """Add many points and measurements with one notification (imports)."""
        for p in points:
            if p.id in self.points and has_ground(self.points[p.id]) and has_ground(p):
                raise InputError(f"point {p.id!r} already exists")
            self.points[p.id] = p
        for m in measurements:
            if m.view not in self.scene.views:
                raise InputError(f"measurement of {m.id}: view {m.view!r} is not in the scene")
            if m.id not in self.points:
                self.points[m.id] = GroundPoint(m.id, math.nan, math.nan, math.nan, kind="TIE")
            self.measurements[m.id, m.view] = m
        self._touch()

    def set_settings(self, settings: Settings) -> Settings:
        old, self.settings = self.settings, settings
        self._touch()
        return old

    def set_geoid(self, geoid: dict) -> dict:
        old, self.geoid = self.geoid, dict(geoid)
        self._touch()
        return old

    # ------------------------------------------------------------------ for the solver
    def point_obs(self, ellipsoidal_heights: dict[str, float]) -> list[PointObs]:
        """Points as the solver takes them; ``ellipsoidal_heights`` maps id → h for every
        point with ground coordinates, and only those (the io layer converts orthometric
        heights): a GCP or ICP in it is a point with ground."""
        images: dict[str, dict] = defaultdict(dict)
        sigmas: dict[str, dict] = defaultdict(dict)
        for (pid, view), m in self.measurements.items():
            images[pid][view] = (m.x, m.y)
            if m.sigma_px is not None:
                sigmas[pid][view] = m.sigma_px
        out = []
        for pid, p in self.points.items():
            ground = None
            h = ellipsoidal_heights.get(pid)
            if h is not None and p.kind != "TIE":
                ground = (p.E, p.N, h)
            out.append(PointObs(pid, p.kind, ground, images.get(pid, {}), sigmas.get(pid, {})))
        return out


def has_ground(p: GroundPoint) -> bool:
    """E, N and H are all finite numbers (written out: called for every point of every fit)."""
    E, N, H = p.E, p.N, p.H
    return (isinstance(E, (int, float)) and isinstance(N, (int, float)) and isinstance(H, (int, float))
            and math.isfinite(E) and math.isfinite(N) and math.isfinite(H))
