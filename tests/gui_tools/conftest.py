"""Fixtures for the tools' tests: a simulated triplet (with its truth) and an SRTM-like
reference, made once; the real window offscreen on a private copy; temporary settings."""
from __future__ import annotations

import gc
import json
import shutil

import pytest


@pytest.fixture(scope="session")
def sim_master(tmp_path_factory):
    from prismstation.cli.new import create
    from prismstation.sim import simulate
    from prismstation.sim.reference import make_reference_dem
    d = tmp_path_factory.mktemp("sim")
    simulate(d, size=1200, seed=7)
    make_reference_dem(d / "truth_dem.tif", d / "srtm.tif", seed=1)
    create(d / "p.prismproj", d / "scene.json", d / "points.csv", d / "measurements.csv")
    return d


@pytest.fixture()
def sim(sim_master, tmp_path):
    d = tmp_path / "sim"
    shutil.copytree(sim_master, d)
    return d


@pytest.fixture()
def truth(sim):
    return {p["id"]: p for p in json.loads((sim / "truth.json").read_text())["points"]}


@pytest.fixture()
def window(qtbot, sim):
    """The real main window on the simulated project, images loaded and fitted."""
    from prismstation.gui.app import make_app, wait_settled
    from prismstation.gui.main_window import MainWindow

    make_app()
    gc.collect()
    qtbot.wait(1)
    win = MainWindow(interactive=False)
    win.files.interactive = False
    qtbot.addWidget(win)
    win.resize(1500, 950)
    win.show()
    qtbot.waitExposed(win)
    assert win.open_project(sim / "p.prismproj", recover=False)
    assert wait_settled(win)
    yield win
    for tool in ("dem_orientation", "transfer_tool", "dsm_tool"):
        job = getattr(getattr(win, tool, None), "job", None)
        if job is not None:
            job.cancel()
            job.wait(20000)
