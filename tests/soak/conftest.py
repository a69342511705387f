"""Fixtures for the window's soak and kill tests: a small rendered triplet project (made once,
copied per test) and a temporary settings location (the user's own are never touched)."""
from __future__ import annotations

import shutil

import pytest

from tests.qt_windows import close_windows, new_window

from prismstation.sim.small_project import make_project


@pytest.fixture(scope="session")
def small_master(tmp_path_factory):
    """9 GCPs, 6 ICPs, 400 px images."""
    return make_project(tmp_path_factory.mktemp("soak"), n_gcp=9, n_icp=6, size=400, p=25.0, seed=11)


@pytest.fixture()
def small(small_master, tmp_path):
    d = tmp_path / "proj"
    shutil.copytree(small_master.path.parent, d)
    return type(small_master)(d / small_master.path.name, d / "scene.json", small_master.truth,
                              small_master.ground)


@pytest.fixture()
def make_window(qtbot):
    """Build real main windows (offscreen); all closed and freed at the end."""
    made = []

    def make():
        made.append(new_window(qtbot, (2400, 1600)))  # above the minimum size (offscreen resize loop)
        return made[-1]

    yield make
    close_windows(qtbot, *made)
