"""``kill -9`` a process whose journal writes in the background (the window's mode): the journal
left behind is exactly the project after the edit it names, never an older state than one the
writer thread had reported on disk, and the project file is untouched."""
import json
import os
import signal
import subprocess
import sys
import time

import pytest

from prismstation.io.project import load_project
from prismstation.io.recovery import recover, recovery_path
from tests.io.test_geoid_project import _project

EDITOR = r"""
import sys, random
from prismstation.io.project import load_project
from prismstation.io.recovery import Journal
from prismstation.model.points import Measurement
path, log = sys.argv[1], sys.argv[2]
proj = load_project(path)
journal = Journal(proj, path, background=True)
rng = random.Random(2)
with open(log, "a", buffering=1) as fh:
    for k in range(100000):
        if journal.written_revision is not None:
            fh.write(f"W {journal.written_revision}\n")  # on disk, as the writer thread reports
        pid = f"K{k}"
        proj.set_measurement(Measurement(pid, "N", rng.uniform(0, 14000), rng.uniform(0, 14000)))
        fh.write(f"C {pid} {proj.revision}\n")  # after the edit's call returned
"""


@pytest.mark.parametrize("delay", [0.6, 1.3])
def test_kill_minus_9_with_the_background_writer(tmp_path, delay):
    _project(tmp_path)
    path = tmp_path / "p.prismproj"
    before = path.read_bytes()
    saved = load_project(path)
    log = tmp_path / "done.log"
    proc = subprocess.Popen([sys.executable, "-c", EDITOR, str(path), str(log)])
    deadline = time.time() + 30
    while (not log.exists() or log.stat().st_size < 200) and time.time() < deadline:
        time.sleep(0.05)
    time.sleep(delay)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    done, on_disk = {}, None
    for line in log.read_text().splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[0] == "C":
            done[parts[1]] = int(parts[2])
        elif len(parts) == 2 and parts[0] == "W":
            on_disk = int(parts[1])
    assert len(done) > 20 and on_disk is not None, "the editor did not get going"
    journaled = json.loads(recovery_path(path).read_text())["recovery"]["revision"]
    assert journaled >= on_disk, "an edit the writer had put on disk was lost"
    got = recover(path)
    new = {pid for pid, _ in got.measurements if pid.startswith("K")}
    # exactly the edits up to the journaled revision: a consistent snapshot, no gap, no extra
    assert new == {pid for pid, rev in done.items() if rev <= journaled} | (
        {f"K{len(done)}"} if journaled > max(done.values()) else set())
    assert len(new) >= sum(rev <= on_disk for rev in done.values())
    assert path.read_bytes() == before and load_project(path).measurements == saved.measurements
    print(f"\n{len(done)} edits, journal at revision {journaled}, {len(done) - len(new)} in flight "
          f"at the kill (last reported on disk: {on_disk})")
