"""One orientation from a reference DEM for every sensor model (``ops/orientation.py``): every
registered model has its workflows and its window parts under its name; an orientation is
stored in one change event, one with nothing to apply is refused; its JSON keeps the model's
layout beside the fit report."""
from __future__ import annotations

import inspect

import pytest

from prismstation.core.models import sensors
from prismstation.core.orientation.conditioning import FAILED, OK, OrientVerdict
from prismstation.gui import sensors as gui_sensors
from prismstation.model.project import Project
from prismstation.ops import sensors as ops_sensors
from prismstation.ops.orientation import Orientation, apply_orientation
from prismstation.sim.model_triplet import make_scene


def test_every_model_has_workflows_and_window_parts_of_one_signature():
    assert set(ops_sensors.WORKFLOWS) == set(sensors.MODELS) == set(gui_sensors.PARTS)
    for name in sensors.MODELS:
        wf = ops_sensors.WORKFLOWS[name]
        assert list(inspect.signature(wf.orient).parameters) == ["project", "reference", "request", "solution",
                                                                 "progress"]
        assert list(inspect.signature(wf.export_dsm).parameters) == ["sol", "project", "request", "reference",
                                                                     "progress"]
        for fn in ("panel_sections", "fit_warning", "plot_line", "orientable", "orient_request",
                   "orientation_text", "verdict_text", "applied_text"):
            assert callable(getattr(gui_sensors.PARTS[name], fn)), (name, fn)


def _orientation(record, status=OK, report_key=None):
    return Orientation(OrientVerdict(status, "why", "", 5.0), record, ("a line",), {"dem_control": record},
                       "3 patches", report_key=report_key)


def test_apply_stores_the_record_in_one_change_and_refuses_nothing_to_apply():
    project = Project(make_scene(size=2000))
    seen = []
    project.changed.connect(seen.append)
    apply_orientation(project, _orientation({"field": {}}))
    assert project.dem_control == {"field": {}} and project.settings.orientation == "dem" and len(seen) == 1
    refused = _orientation(None, FAILED)
    assert refused.exit_status == 3 and not refused.ok
    with pytest.raises(ValueError, match="nothing to apply"):
        apply_orientation(project, refused)


def test_json_keeps_each_models_layout_beside_the_report():
    report = {"points": [], "messages": ["m"]}
    prism = _orientation({"patches": []})
    assert prism.json(report) == {"points": [], "messages": ["m"], "dem_control": {"patches": []}}
    rpc = _orientation({"biases": {}}, report_key="report")
    assert rpc.json(report) == {"dem_control": {"biases": {}}, "report": report}
    assert rpc.json(None) == {"dem_control": {"biases": {}}}


@pytest.mark.parametrize("size, pixel_m, expected_m", [(2000, 5.0, 2500.0), (1200, 20.0, 4000.0), (1000, 2.5, 1000.0)])
def test_orient_dem_cuts_patches_of_a_quarter_of_the_scene_by_default(tmp_path, monkeypatch, size, pixel_m, expected_m):
    """`orient-dem` without --patch-km: a quarter of the scene's shorter side, 1–4 km, as the
    window offers (a 10 km scene: 2.5 km, 16 patches; before, 4 km on every scene: 4 patches
    on a 10 km one, refused as too few); --patch-km still rules."""
    import prismstation.ops.prism_project as pp
    from prismstation.cli import main
    from prismstation.errors import InputError
    from prismstation.sim.small_project import make_project
    proj = make_project(tmp_path / "p", size=size, p=pixel_m).path
    (tmp_path / "ref.tif").write_bytes(b"")
    asked = []

    def engine(*args, **kw):
        asked.append(kw["patch_m"])
        raise InputError("stopped here")
    monkeypatch.setattr(pp, "orient_from_dem", engine)
    assert main(["orient-dem", str(proj), str(tmp_path / "ref.tif")]) == 2
    assert main(["orient-dem", str(proj), str(tmp_path / "ref.tif"), "--patch-km", "3"]) == 2
    assert asked == [expected_m, 3000.0]
