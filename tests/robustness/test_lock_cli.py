"""The command line honours the window's lock (``<project>.lock``, :mod:`prismstation.io.lock`):
a command that writes a project another live process holds refuses in one line and changes
nothing; commands that only read it go on; a stale lock (its process gone) does not count."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from tests.robustness import faults as ft

HOLD = """
import sys, time
from prismstation.io.lock import ProjectLock
ProjectLock(sys.argv[1]).acquire()
print("held", flush=True)
time.sleep(60)
"""


@pytest.fixture()
def held(sim):
    """The sim project, its lock held by another live process (as a window holds it)."""
    project = sim / "p.prismproj"
    other = subprocess.Popen([sys.executable, "-c", HOLD, str(project)], stdout=subprocess.PIPE, text=True,
                             env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    try:
        assert other.stdout.readline().strip() == "held"
        yield project, other
    finally:
        other.kill()
        other.wait()


def test_orient_dem_save_refuses_a_project_the_window_holds(held):
    project, other = held
    before = ft.digest(project)
    line = ft.assert_clean_failure(
        ft.run_cli(["orient-dem", project, project.parent / "srtm.tif", "--save"]),
        "orient-dem", "p.prismproj")
    assert f"process {other.pid}" in line and "close it there" in line
    assert ft.digest(project) == before


def test_transfer_save_refuses_a_project_the_window_holds(held):
    project, other = held
    before = ft.digest(project)
    line = ft.assert_clean_failure(ft.run_cli(["transfer", project, "--save"]), "transfer", "p.prismproj")
    assert f"process {other.pid}" in line and "close it there" in line
    assert ft.digest(project) == before


def test_new_force_refuses_a_project_the_window_holds(held):
    project, _ = held
    before = ft.digest(project)
    ft.assert_clean_failure(ft.run_cli(["new", project, "--scene", project.parent / "scene.json",
                                        "--force"]), "new", "open in prismstation")
    assert ft.digest(project) == before


def test_reading_commands_go_on(held):
    project, _ = held
    rc, out, err = ft.run_cli(["fit", project])
    assert rc == 0 and not err.strip(), err


def test_a_stale_lock_does_not_count(held):
    project, other = held
    other.kill()
    other.wait()
    rc, out, err = ft.run_cli(["new", project, "--scene", project.parent / "scene.json", "--force"])
    assert rc == 0, err
