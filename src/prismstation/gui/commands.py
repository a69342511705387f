"""Undoable edits of a :class:`~prismstation.model.project.Project` (one ``QUndoStack``).

Every gesture becomes one command that calls the Project API only; Project emits ``changed``
and the solver refits. Consecutive moves of one measurement merge into one step (``mergeWith``).
"""
from __future__ import annotations

import math

from PySide6.QtGui import QUndoCommand

from prismstation.errors import InputError
from prismstation.model.points import GroundPoint, Measurement
from prismstation.model.project import has_ground

MOVE_ID = 1001


class PlaceMeasurement(QUndoCommand):
    """Place (or move) point ``pid`` in ``view`` at image ``(x, y)`` pixels.

    A new id creates a tie point, which undo removes again. With ``merge=True`` (a drag in
    progress, a nudge) consecutive commands for the same point and view merge into one step.
    """

    def __init__(self, project, pid: str, view: str, x: float, y: float, merge: bool = False):
        super().__init__()
        self.project = project
        self.pid, self.view = pid, view
        self.new = Measurement(pid, view, float(x), float(y))
        self.old = project.measurement(pid, view)
        if self.old is not None and self.old.sigma_px is not None:
            self.new = Measurement(pid, view, float(x), float(y), self.old.sigma_px)
        self.created = pid not in project.points
        self.merge = merge
        verb = "Move" if self.old is not None else "Place"
        self.setText(f"{verb} {pid} in {view}")

    def id(self) -> int:
        return MOVE_ID if self.merge else -1

    def mergeWith(self, other) -> bool:
        if not (isinstance(other, PlaceMeasurement) and other.merge and other.pid == self.pid
                and other.view == self.view and not other.created):
            return False
        self.new = other.new
        return True

    def redo(self) -> None:
        self.project.set_measurement(self.new)

    def undo(self) -> None:
        if self.created:
            self.project.remove_point(self.pid)
        elif self.old is None:
            self.project.remove_measurement(self.pid, self.view)
        else:
            self.project.set_measurement(self.old)


class AddPoint(QUndoCommand):
    """Add a point (a new tie point when ``point`` is None); :attr:`pid` is its id."""

    def __init__(self, project, point: GroundPoint | None = None):
        super().__init__()
        self.project = project
        self.point = point or GroundPoint(project.new_point_id("T"), math.nan, math.nan, math.nan, kind="TIE")
        self.pid = self.point.id
        self.setText(f"New point {self.pid}")

    def redo(self) -> None:
        self.project.add_point(self.point)

    def undo(self) -> None:
        self.project.remove_point(self.pid)


class DeletePoint(QUndoCommand):
    """Delete a point with all its measurements."""

    def __init__(self, project, pid: str):
        super().__init__(f"Delete point {pid}")
        self.project, self.pid = project, pid
        self.point, self.ms = None, []

    def redo(self) -> None:
        self.point, self.ms = self.project.remove_point(self.pid)

    def undo(self) -> None:
        self.project.load([self.point], self.ms)


class DeleteMeasurement(QUndoCommand):
    """Delete the measurement of ``pid`` in ``view`` (the point stays)."""

    def __init__(self, project, pid: str, view: str):
        super().__init__(f"Delete {pid} in {view}")
        self.project, self.pid, self.view = project, pid, view
        self.old = None

    def redo(self) -> None:
        self.old = self.project.remove_measurement(self.pid, self.view)

    def undo(self) -> None:
        if self.old is not None:
            self.project.set_measurement(self.old)


class SetKind(QUndoCommand):
    """Switch a point between GCP, ICP and TIE (raises InputError at construction if it can't)."""

    def __init__(self, project, pid: str, kind: str):
        super().__init__(f"{pid} → {kind}")
        self.project, self.pid, self.kind = project, pid, kind
        self.old = project.points[pid].kind
        if kind != "TIE" and not has_ground(project.points[pid]):
            raise InputError(f"point {pid} has no ground coordinates: it can only be a tie point")

    def redo(self) -> None:
        self.project.set_kind(self.pid, self.kind)

    def undo(self) -> None:
        self.project.set_kind(self.pid, self.old)


class ChangeSettings(QUndoCommand):
    """Replace the model settings (bias model, parallax model, σ, threshold, mean height)."""

    def __init__(self, project, settings):
        super().__init__("Change model settings")
        self.project, self.new, self.old = project, settings, project.settings

    def redo(self) -> None:
        self.project.set_settings(self.new)

    def undo(self) -> None:
        self.project.set_settings(self.old)


class Import(QUndoCommand):
    """Add or replace many points and measurements as one step (one refit)."""

    def __init__(self, project, points, measurements, text: str = "Import"):
        super().__init__(text)
        self.project = project
        self.points, self.ms = list(points), list(measurements)
        ids = {p.id for p in self.points} | {m.id for m in self.ms}
        self.old_points = {pid: project.points.get(pid) for pid in ids}
        self.old_ms = {(m.id, m.view): project.measurements.get((m.id, m.view)) for m in self.ms}

    def redo(self) -> None:
        p = self.project
        with p.batch():  # one change event for the whole import
            for pt in self.points:  # replaced points first: load refuses to overwrite ground points
                if self.old_points.get(pt.id) is not None:
                    p.replace_point(pt)
            p.load([pt for pt in self.points if self.old_points.get(pt.id) is None], self.ms)

    def undo(self) -> None:
        p = self.project
        with p.batch():
            for (pid, view), old in self.old_ms.items():
                if old is None:
                    if (pid, view) in p.measurements:
                        p.remove_measurement(pid, view)
                else:
                    p.set_measurement(old)
            for pid, old in self.old_points.items():
                if old is None:
                    if pid in p.points:
                        p.remove_point(pid)
                else:
                    p.replace_point(old)


class EditPoint(QUndoCommand):
    """Replace point ``pid`` by ``point``: its ground data (E, N, H in metres, height kind,
    σ plan and height in metres), its kind, and — when ``point.id`` differs — its id, which its
    measurements follow. Raises InputError at construction when the result is not valid (a
    taken or empty id, a GCP or ICP without all three coordinates)."""

    def __init__(self, project, pid: str, point: GroundPoint, text: str | None = None):
        super().__init__(text or f"Edit {pid}")
        if not point.id.strip():
            raise InputError("a point id cannot be empty")
        if point.id != pid and point.id in project.points:
            raise InputError(f"point {point.id!r} already exists")
        if point.kind != "TIE" and not has_ground(point):
            raise InputError(f"{point.kind} {pid} needs E, N and H: make it a tie point first")
        self.project, self.pid, self.new = project, pid, point
        self.old = project.points[pid]

    def _swap(self, old_id: str, point: GroundPoint) -> None:
        p = self.project
        if point.id == old_id:
            p.replace_point(point)
            return
        with p.batch():  # a rename: the point and its measurements under the new id, one change
            _, ms = p.remove_point(old_id)
            p.load([point], [Measurement(point.id, m.view, m.x, m.y, m.sigma_px) for m in ms])

    def redo(self) -> None:
        self._swap(self.pid, self.new)

    def undo(self) -> None:
        self._swap(self.new.id, self.old)
