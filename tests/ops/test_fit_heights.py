"""The ellipsoidal heights of a project's points, kept between fits by the caller's memo: the
same points, geoid and scene give the same heights again; a changed point, geoid or scene gives
new ones; another memo keeps its own."""
from dataclasses import replace

import pytest

from prismstation.model.points import GroundPoint, Measurement
from prismstation.model.project import Project
from prismstation.ops.fit import FitMemo, ellipsoidal_heights
from prismstation.sim.model_triplet import make_scene


@pytest.fixture
def project():
    p = Project(make_scene(size=2000), geoid={"kind": "constant", "value": 30.0})
    p.load([GroundPoint("A", 1.0, 2.0, 100.0, height_kind="orthometric"),
            GroundPoint("B", 4.0, 5.0, 200.0, height_kind="ellipsoidal", kind="ICP")],
           [Measurement("A", "N", 10.0, 20.0)])
    return p


def test_heights_follow_points_geoid_and_scene_not_measurements(project):
    memo = FitMemo()
    h = memo.heights(project)
    assert h == {"A": 130.0, "B": 200.0} == ellipsoidal_heights(project)
    project.set_measurement(Measurement("A", "N", 11.0, 20.0))   # a click: the same heights
    assert memo.heights(project) is h
    assert memo.heights(project.snapshot()) is h
    assert FitMemo().heights(project) is not h and ellipsoidal_heights(project) is not h  # not shared
    project.replace_point(replace(project.points["A"], H=101.0))
    assert memo.heights(project) == {"A": 131.0, "B": 200.0}
    project.set_geoid({"kind": "constant", "value": 10.0})
    assert memo.heights(project) == {"A": 111.0, "B": 200.0}
    other = Project(make_scene(size=3000), geoid=dict(project.geoid))
    other.load(list(project.points.values()), [])
    assert memo.heights(other) == {"A": 111.0, "B": 200.0}
    assert memo.heights(other) is not memo.heights(project)  # another scene
