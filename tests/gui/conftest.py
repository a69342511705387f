"""Fixtures for the window's tests: a small rendered triplet project and a temporary settings
location (the user's own settings are never touched)."""
from __future__ import annotations

import fcntl
import os
import shutil

import pytest

from tests.gui.boxes import stop_pollers
from tests.qt_windows import close_windows, open_window

from prismstation.sim.small_project import make_project

UNMEASURED = ("G9",)


@pytest.fixture(autouse=True)
def _no_box_answered_for_another_test():
    """A test that fails before its message box came leaves its poller polling: stopped here,
    so that it cannot answer the next test's box."""
    yield
    stop_pollers()


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


@pytest.fixture(scope="session")
def real_demo_master(tmp_path_factory):
    """The demo project as ``prismstation demo`` makes it (2000 px triplet, 9 GCPs, 41 ICPs,
    20 tie points, SRTM-like reference): made once per test session (a minute), shared by
    the xdist workers through a lock."""
    from prismstation.cli.demo import ensure_demo
    base = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):  # the workers' base folders share this session's
        base = base.parent
    base = base / "real_demo"
    base.mkdir(exist_ok=True)
    with open(base / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            if not (base / "done").exists():
                ensure_demo(base / "demo", rebuild=True)
                (base / "done").write_text("")
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
    return base / "demo" / "demo.prismproj"


@pytest.fixture()
def real_demo(real_demo_master, tmp_path):
    """A private copy of the real demo project."""
    shutil.copytree(real_demo_master.parent, tmp_path / "demo")
    return tmp_path / "demo" / "demo.prismproj"
