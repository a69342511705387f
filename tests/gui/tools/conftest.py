"""Fixtures for the tools' tests: a simulated triplet (with its truth) and an SRTM-like
reference, made once; the real window offscreen on a private copy; temporary settings."""
from __future__ import annotations

import json
import shutil

import pytest

from tests.qt_windows import close_windows, open_window


@pytest.fixture(scope="session")
def sim_master(tmp_path_factory):
    from prismstation.ops.project import create
    from prismstation.sim import simulate
    from prismstation.sim.reference import make_reference_dem
    d = tmp_path_factory.mktemp("sim")
    simulate(d, size=1200, seed=7)   # the simulator's default: each view off by up to ±50 m
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
    win = open_window(qtbot, sim / "p.prismproj")
    yield win
    close_windows(qtbot, win)  # cancels and awaits a running tool job


@pytest.fixture()
def job_outcome(qtbot):
    """``job_outcome(job)`` waits for a tool :class:`Job` to end and returns ``(kind, value)``:
    ``("result", value)``, ``("failed", message)`` or ``("cancelled", None)``."""
    def wait(job, timeout=20000):
        got = []
        job.result.connect(lambda v: got.append(("result", v)))
        job.failed.connect(lambda m: got.append(("failed", m)))
        job.cancelled.connect(lambda: got.append(("cancelled", None)))
        qtbot.waitUntil(lambda: bool(got), timeout=timeout)
        return got[0]
    return wait


@pytest.fixture()
def job_done(qtbot):
    """``job_done(job, stall_s=60)`` waits until a tool :class:`Job` has ended and its outcome
    is delivered; it fails when the job reports no progress for ``stall_s`` seconds (a stall),
    not when a loaded machine makes it slow."""
    import time

    def wait(job, stall_s=60.0):
        ended, last = [], [time.monotonic()]
        job.result.connect(lambda v: ended.append(v))
        job.failed.connect(lambda m: ended.append(m))
        job.cancelled.connect(lambda: ended.append(None))
        job.progress.connect(lambda *_: last.__setitem__(0, time.monotonic()))
        while not ended:
            assert time.monotonic() - last[0] < stall_s, f"{job.title}: no progress for {stall_s:.0f} s"
            qtbot.wait(50)
        return ended[0]
    return wait
