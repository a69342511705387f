"""Tools ▸ Space resection… starts from PRISM's camera (focal length 1939 mm, 7 µm detectors)
when the project is a PRISM scene, and from a generic camera otherwise."""
from __future__ import annotations

import json

import numpy as np
import pytest

from prismstation.gui.tools.resection_tool import GENERIC_CAMERA, PRISM_CAMERA, is_prism
from tests.qt_windows import close_windows, open_window


def test_a_prism_scene_gets_prism_camera_and_a_plausible_orbit(window, sim):
    """The simulated PRISM 1B2R triplet: the dialog opens with 1939 mm and 7 µm, and the
    resection of N with them puts the camera at PRISM's altitude (a frame camera only
    approximates a pushbroom: within 0.2 %)."""
    d = window.tools["resection"].open()
    assert (d.focal.value(), d.pitch.value()) == PRISM_CAMERA == (1939.0, 7.0)
    d.view.setCurrentText("N")
    res = d.run()
    assert res is not None and res.converged
    scene = json.loads((sim / "scene.json").read_text())
    h_mean = np.mean([p.H for p in window.project.points.values() if p.kind == "GCP"])
    above = res.position[2] - h_mean
    assert above == pytest.approx(scene["satellite_altitude_m"], rel=2e-3)  # measured: 691 807 m
    # a resection with the generic start lands the camera far from the orbit
    d.focal.setValue(GENERIC_CAMERA[0])
    generic = d.run()
    assert abs(generic.position[2] - h_mean - scene["satellite_altitude_m"]) > 0.1 * scene["satellite_altitude_m"]


@pytest.fixture()
def frame_window(qtbot, tmp_path):
    """The real window on a single frame-camera view (no PRISM scene)."""
    from tests.gui.tools.single_view import make_frame_view
    path, _ = make_frame_view(tmp_path / "frame")
    win = open_window(qtbot, path)
    yield win
    close_windows(qtbot, win)


def test_other_projects_keep_the_generic_camera(frame_window):
    assert not is_prism(frame_window.project)
    d = frame_window.tools["resection"].open()
    assert (d.focal.value(), d.pitch.value()) == GENERIC_CAMERA


@pytest.mark.parametrize("extra,prism", [({"scene_id": "ALPSMN061122750"}, True),
                                         ({"product": {"kind": "JAXA GeoTIFF 1B2", "path": "/p"}}, True),
                                         ({"product_level": "1B2G"}, True),
                                         ({"generator": "a frame camera"}, False)])
def test_is_prism(tmp_path, extra, prism):
    from prismstation.io.scene import read_scene
    from prismstation.model.project import Project
    from tests.gui.tools.single_view import make_frame_view
    path, _ = make_frame_view(tmp_path / "frame")
    scene_path = path.parent / "scene.json"
    doc = json.loads(scene_path.read_text())
    doc.update(extra)
    scene_path.write_text(json.dumps(doc))
    assert is_prism(Project(read_scene(scene_path), str(scene_path))) is prism
    assert is_prism(Project(read_scene(scene_path), str(scene_path), product="/data/ALPSM")) is True
