"""Fixtures for the window's tests: a small rendered triplet project and a temporary settings
location (the user's own settings are never touched)."""
from __future__ import annotations

import shutil

import pytest

from tests.qt_windows import close_windows, open_window

from tests.gui.project_factory import make_project

UNMEASURED = ("G9",)


@pytest.fixture(scope="session")
def demo_master(tmp_path_factory):
    """The master copy (made once): 9 GCPs, 12 ICPs, 800 px images; G9 not measured."""
    return make_project(tmp_path_factory.mktemp("demo"), n_gcp=9, n_icp=12, size=800, p=25.0,
                        unmeasured=UNMEASURED, seed=5)


@pytest.fixture()
def demo(demo_master, tmp_path):
    """A private copy of the demo project for one test (same truth)."""
    d = tmp_path / "demo"
    shutil.copytree(demo_master.path.parent, d)
    demo_master_copy = type(demo_master)(d / demo_master.path.name, d / "scene.json",
                                         demo_master.truth, demo_master.ground)
    return demo_master_copy


@pytest.fixture()
def window(qtbot, demo):
    """The real main window on a copy of the demo project, images loaded and fitted."""
    win = open_window(qtbot, demo.path)
    win.demo = demo
    yield win
    close_windows(qtbot, win)
