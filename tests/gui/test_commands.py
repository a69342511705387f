"""Undo commands on a bare Project (no window): each redo/undo pair restores the state exactly."""
from __future__ import annotations

import math

import pytest
from PySide6.QtGui import QUndoStack

from prismstation.core.models.solution import Settings
from prismstation.errors import InputError
from prismstation.gui import commands as cmd
from prismstation.model.points import GroundPoint, Measurement
from prismstation.model.project import Project
from prismstation.sim.model_triplet import make_scene


def state(p: Project):
    return (dict(p.points), dict(p.measurements), p.settings)


@pytest.fixture()
def project(qapp):
    p = Project(make_scene(size=1000))
    p.load([GroundPoint("G1", 540000.0, 4560000.0, 500.0), GroundPoint("I1", 540100.0, 4560100.0, 600.0, kind="ICP")],
           [Measurement("G1", "N", 10.0, 20.0), Measurement("G1", "F", 11.0, 21.0)])
    return p


def test_place_new_id_creates_a_tie_point_and_undo_removes_it(project):
    stack = QUndoStack()
    before = state(project)
    c = cmd.PlaceMeasurement(project, project.new_point_id("T"), "B", 5.0, 6.0)
    stack.push(c)
    assert project.points[c.pid].kind == "TIE" and math.isnan(project.points[c.pid].E)
    assert project.measurement(c.pid, "B") == Measurement(c.pid, "B", 5.0, 6.0)
    stack.undo()
    assert state(project) == before
    stack.redo()
    assert project.measurement(c.pid, "B").x == 5.0


def test_consecutive_moves_of_one_point_merge(project):
    stack = QUndoStack()
    before = state(project)
    for i in range(5):
        stack.push(cmd.PlaceMeasurement(project, "G1", "N", 10.0 + i, 20.0 - i, merge=True))
    assert stack.count() == 1
    assert (project.measurement("G1", "N").x, project.measurement("G1", "N").y) == (14.0, 16.0)
    stack.push(cmd.PlaceMeasurement(project, "G1", "F", 1.0, 2.0, merge=True))  # other view: new step
    stack.push(cmd.PlaceMeasurement(project, "I1", "N", 3.0, 4.0, merge=True))  # new measurement
    stack.push(cmd.PlaceMeasurement(project, "I1", "N", 3.5, 4.5, merge=True))  # merges with it
    assert stack.count() == 3
    stack.undo()
    assert project.measurement("I1", "N") is None
    stack.undo()
    stack.undo()
    assert state(project) == before


def test_delete_kind_settings_import_round_trip(project):
    stack = QUndoStack()
    before = state(project)
    stack.push(cmd.DeleteMeasurement(project, "G1", "F"))
    assert project.measurement("G1", "F") is None
    stack.push(cmd.SetKind(project, "I1", "GCP"))
    assert project.points["I1"].kind == "GCP"
    stack.push(cmd.ChangeSettings(project, Settings(bias_model="shift")))
    stack.push(cmd.DeletePoint(project, "G1"))
    assert "G1" not in project.points and not any(k[0] == "G1" for k in project.measurements)
    new_pts = [GroundPoint("G2", 540200.0, 4560200.0, 700.0), GroundPoint("I1", 540111.0, 4560111.0, 610.0, kind="ICP")]
    new_ms = [Measurement("G2", "N", 1.0, 1.0), Measurement("T9", "B", 2.0, 2.0)]
    stack.push(cmd.Import(project, new_pts, new_ms))
    assert project.points["I1"].E == 540111.0 and project.points["T9"].kind == "TIE"
    assert project.measurement("G2", "N") is not None
    while stack.canUndo():
        stack.undo()
    assert state(project) == before
    while stack.canRedo():
        stack.redo()
    assert project.points["I1"].E == 540111.0 and "G1" not in project.points


def test_an_import_and_its_undo_each_emit_one_change_naming_every_point(project):
    stack, events = QUndoStack(), []
    project.changed.connect(events.append)
    new_pts = [GroundPoint("G2", 540200.0, 4560200.0, 700.0), GroundPoint("I1", 540111.0, 4560111.0, 610.0, kind="ICP")]
    new_ms = [Measurement("G2", "N", 1.0, 1.0), Measurement("T9", "B", 2.0, 2.0)]
    stack.push(cmd.Import(project, new_pts, new_ms))
    stack.undo()
    assert [(e.points, e.views) for e in events] == [({"G2", "I1", "T9"}, {"N", "B"})] * 2
    assert [e.revision for e in events] == [project.revision - 1, project.revision]


def test_a_tie_point_cannot_become_a_gcp(project):
    t = project.add_tie()
    with pytest.raises(InputError, match="tie point"):
        cmd.SetKind(project, t, "GCP")
