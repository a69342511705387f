"""Change events of the project: what each edit names, batches that emit once, and only the
project bumping its revision."""
import math
from dataclasses import replace

import pytest

from prismstation.core.models.solution import Settings
from prismstation.errors import InputError
from prismstation.model.points import GroundPoint, Measurement
from prismstation.model.project import Change, Project
from prismstation.sim.model_triplet import make_scene


@pytest.fixture
def project():
    p = Project(make_scene(size=2000))
    p.events = []
    p.changed.connect(p.events.append)
    return p


def test_each_edit_names_the_points_and_views_it_touched(project):
    project.add_point(GroundPoint("A", 1.0, 2.0, 3.0))
    project.set_measurement(Measurement("A", "N", 10.0, 20.0))
    project.set_measurement(Measurement("T1", "F", 5.0, 6.0))    # a new tie point
    project.set_kind("A", "ICP")
    project.remove_measurement("A", "N")
    project.set_settings(replace(project.settings, sigma_px=0.7))
    project.set_geoid({"kind": "constant", "value": 50.0})
    project.set_dem_control({"patches": []})
    project.set_relocations({"N": "/elsewhere/N.tif"})
    e = project.events
    assert [c.revision for c in e] == list(range(1, 10)) and project.revision == 9
    assert e[0] == Change(1, frozenset({"A"}))
    assert e[1] == Change(2, frozenset({"A"}), frozenset({"N"}))
    assert e[2].points == {"T1"} and e[2].views == {"F"} and project.points["T1"].kind == "TIE"
    assert e[3].points == {"A"} and not e[3].views
    assert e[4] == Change(5, frozenset({"A"}), frozenset({"N"}))
    assert e[5] == Change(6, settings=True)
    assert e[6] == Change(7, geoid=True)
    assert e[7] == Change(8, control=True) and project.dem_control == {"patches": []}
    assert e[8] == Change(9, files=True) and project.relocations == {"N": "/elsewhere/N.tif"}


def test_removing_a_point_names_the_views_it_was_measured_in(project):
    project.load([GroundPoint("A", 1.0, 2.0, 3.0)],
                 [Measurement("A", "N", 1.0, 1.0), Measurement("A", "B", 2.0, 2.0)])
    assert project.events[-1].points == {"A"} and project.events[-1].views == {"N", "B"}
    project.remove_point("A")
    assert project.events[-1].points == {"A"} and project.events[-1].views == {"N", "B"}


def test_a_batch_emits_one_merged_change_and_bumps_the_revision_once(project):
    with project.batch():
        project.add_point(GroundPoint("A", 1.0, 2.0, 3.0))
        with project.batch():                                   # nested: still one event
            project.set_measurement(Measurement("B", "F", 1.0, 1.0))
            project.set_settings(replace(project.settings, sigma_px=2.0))
        assert project.events == [] and project.revision == 0
    assert project.events == [Change(1, frozenset({"A", "B"}), frozenset({"F"}), settings=True)]
    assert project.revision == 1
    with project.batch():
        pass                                                    # nothing changed: no event
    assert len(project.events) == 1 and project.revision == 1


def test_a_batch_ended_by_an_error_still_reports_what_was_done(project):
    project.add_point(GroundPoint("A", 1.0, 2.0, 3.0))
    with pytest.raises(InputError):
        with project.batch():
            project.set_measurement(Measurement("A", "N", 1.0, 1.0))
            project.add_point(GroundPoint("A", 1.0, 2.0, 3.0))  # exists: refused
    assert project.events[-1] == Change(2, frozenset({"A"}), frozenset({"N"}))
    assert project.measurement("A", "N") is not None


def test_a_new_project_with_content_is_at_revision_zero_and_refuses_bad_measurements():
    sc = make_scene(size=2000)
    p = Project(sc, points=[GroundPoint("A", 1.0, 2.0, 3.0)],
                measurements=[Measurement("A", "N", 1.0, 2.0)], product="/data/prod")
    assert p.revision == 0 and p.measurement("A", "N").x == 1.0 and p.product == "/data/prod"
    with pytest.raises(InputError, match="view 'X'"):
        Project(sc, measurements=[Measurement("A", "X", 1.0, 2.0)])
    events = []
    p.changed.connect(events.append)
    p.mark_modified()
    assert p.revision == 1 and events == [Change(1)]
    assert not math.isnan(p.points["A"].E) and p.settings == Settings()


def _fresh_obs(project, heights):
    """point_obs of a new project with the same content (an empty cache)."""
    fresh = Project(project.scene, points=project.points.values(),
                    measurements=project.measurements.values())
    return fresh.point_obs(heights)


def test_point_obs_reused_between_fits_follow_every_edit(project):
    """point_obs keeps the PointObs of unchanged points between calls: after every kind of edit,
    in the project and in a snapshot fitted meanwhile, it equals a fresh project's."""
    project.load([GroundPoint("A", 1.0, 2.0, 3.0), GroundPoint("B", 4.0, 5.0, 6.0, kind="ICP")],
                 [Measurement("A", "N", 10.0, 20.0), Measurement("A", "F", 11.0, 21.0),
                  Measurement("B", "N", 30.0, 40.0, sigma_px=0.5), Measurement("T", "B", 1.0, 2.0)])
    heights = {"A": 40.0, "B": 41.0}
    edits = [
        lambda p: p.set_measurement(Measurement("A", "N", 10.5, 20.0)),
        lambda p: p.set_measurement(Measurement("B", "F", 31.0, 41.0, sigma_px=0.2)),
        lambda p: p.remove_measurement("A", "F"),
        lambda p: p.set_kind("A", "ICP"),
        lambda p: p.replace_point(replace(p.points["B"], E=4.5, sigma_xy_m=0.3)),
        lambda p: p.set_kind("A", "TIE"),
        lambda p: p.remove_point("T"),
        lambda p: p.set_measurement(Measurement("T", "N", 3.0, 4.0)),  # the same id again
    ]
    assert project.point_obs(heights) == _fresh_obs(project, heights)
    for i, edit in enumerate(edits):
        snap = project.snapshot()
        edit(project)
        assert project.point_obs(heights) == _fresh_obs(project, heights), i
        assert snap.point_obs(heights) == _fresh_obs(snap, heights), i  # the snapshot unchanged
    project.point_obs(heights)
    heights = {**heights, "B": 52.0}  # a new geoid: other ellipsoidal heights, nothing edited
    assert project.point_obs(heights) == _fresh_obs(project, heights)


def test_measurements_of_follows_every_edit_in_the_order_of_the_measurements(project):
    """The per-point index the solver reads equals a search of the measurements after every
    edit (order included: a moved measurement keeps its place), and a snapshot keeps its own."""
    def searched(p):
        out = {}
        for (pid, _), m in p.measurements.items():
            out.setdefault(pid, []).append(m)
        return {pid: tuple(ms) for pid, ms in out.items()}

    def indexed(p):
        return {pid: p.measurements_of(pid) for pid in p.points if p.measurements_of(pid)}

    project.load([GroundPoint("A", 1.0, 2.0, 3.0)],
                 [Measurement("A", "N", 1.0, 1.0), Measurement("A", "F", 2.0, 2.0), Measurement("T", "B", 3.0, 3.0)])
    edits = [
        lambda p: p.set_measurement(Measurement("A", "N", 1.5, 1.0)),   # moved: keeps its place
        lambda p: p.set_measurement(Measurement("A", "B", 4.0, 4.0)),   # a new view: last
        lambda p: p.remove_measurement("A", "N"),
        lambda p: p.set_measurement(Measurement("A", "N", 5.0, 5.0)),   # back: now last
        lambda p: p.remove_point("T"),
        lambda p: p.set_measurement(Measurement("U", "F", 6.0, 6.0)),   # a new tie point
        lambda p: p.remove_measurement("U", "F"),
    ]
    assert indexed(project) == searched(project)
    for i, edit in enumerate(edits):
        snap = project.snapshot()
        before = indexed(snap)
        edit(project)
        assert indexed(project) == searched(project), i
        assert indexed(snap) == before == searched(snap), i
    assert [m.view for m in project.measurements_of("A")] == ["F", "B", "N"]
    assert project.measurements_of("U") == () and project.measurements_of("T") == ()
