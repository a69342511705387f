"""Crash recovery: kill -9 a real process in the middle of editing; nothing confirmed is lost."""
import os
import signal
import subprocess
import sys
import time

import pytest

from prismstation.io.project import load_project
from prismstation.io.recovery import recover, recovery_for
from tests.io.test_geoid_project import _project

EDITOR = r"""
import sys, random
from prismstation.io.project import load_project
from prismstation.io.recovery import Journal
from prismstation.model.points import Measurement
path, log = sys.argv[1], sys.argv[2]
proj = load_project(path)
journal = Journal(proj, path)
rng = random.Random(1)
with open(log, "a", buffering=1) as fh:
    for k in range(100000):
        pid = f"K{k}"
        proj.set_measurement(Measurement(pid, "N", rng.uniform(0, 14000), rng.uniform(0, 14000)))
        fh.write(pid + "\n")  # written only after the edit's journal write returned
"""


@pytest.mark.parametrize("delay", [0.8, 1.7])
def test_kill_minus_9_while_editing(tmp_path, delay):
    _project(tmp_path)
    path = tmp_path / "p.prismproj"
    saved = load_project(path)
    log = tmp_path / "done.log"
    proc = subprocess.Popen([sys.executable, "-c", EDITOR, str(path), str(log)])
    deadline = time.time() + 30
    while (not log.exists() or log.stat().st_size < 40) and time.time() < deadline:
        time.sleep(0.05)
    time.sleep(delay)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    done = log.read_text().split()
    assert len(done) > 5, "the editor did not get going"
    assert recovery_for(path) is not None
    got = recover(path)
    for pid in done:  # every edit confirmed before the kill is there
        assert (pid, "N") in got.measurements
    # the project file itself was never touched
    again = load_project(path)
    assert again.measurements == saved.measurements
    assert len(got.measurements) >= len(saved.measurements) + len(done)
