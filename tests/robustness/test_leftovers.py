"""What a killed run leaves is cleaned by the next one: the temporaries beside a target and
the scratch copies in the temporary folder carry their process's host and pid, and those of a
process that no longer runs are removed (never a live one's); ``gui --screenshot`` leaves no
settings folder; a full disk's message gives the free space seen when the write failed."""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from prismstation.io import atomic
from tests.robustness import faults as ft


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


@pytest.fixture()
def own_tmp(tmp_path, monkeypatch):
    """A temporary folder of the test's own (the scratch copies go there)."""
    d = tmp_path / "tmp"
    d.mkdir()
    monkeypatch.setenv("TMPDIR", str(d))
    monkeypatch.setattr(tempfile, "tempdir", None)
    return d


def test_a_killed_runs_temporaries_are_removed_by_the_next_run(sim, tmp_path, own_tmp):
    out = tmp_path / "out"
    out.mkdir()
    host = atomic.OWNER_TAG.split("-")[0]
    dead, live = f"{host}-{_dead_pid()}", f"{host}-{os.getppid()}"
    stale = [out / f".d.tif.{dead}.k3j_x.part.tif", out / f".d.tif.{dead}.k3j_x.part.tif.ovr.tmp",
             own_tmp / f"prismstation-dsm-{dead}_ab_c.tif"]
    kept = [out / f".d.tif.{live}.zz.part.tif", out / f".d.tif.0badc0de-{_dead_pid()}.zz.part.tif",
            own_tmp / f"prismstation-dsm-{live}_zz.tif", out / "notes.txt"]
    for f in stale + kept:
        f.write_bytes(b"x" * 1000)
    rc, _, err = ft.run_cli(["dsm", sim / "p.prismproj", "-o", out / "d.tif", "--window", "300", "300", "200",
                             "200", "--posting", "10", "--min-fill", "0"])
    assert rc == 0, err
    assert not [f for f in stale if f.exists()]
    assert all(f.exists() for f in kept)
    assert sorted(p.name for p in out.iterdir()) == sorted([f.name for f in kept if f.parent == out] + ["d.tif"])
    assert [p.name for p in own_tmp.iterdir()] == [kept[2].name]


def test_temporaries_are_named_with_their_owner(tmp_path):
    seen = []
    with atomic.atomic_path(tmp_path / "x.json") as tmp:
        seen.append(tmp.name)
        tmp.write_text("{}")
    assert seen[0].startswith(f".x.json.{atomic.OWNER_TAG}.") and seen[0].endswith(".part.json")
    s = atomic.scratch_file("dsm", ".tif")
    try:
        assert s.name.startswith(f"prismstation-dsm-{atomic.OWNER_TAG}_")
    finally:
        s.unlink()


def test_gui_screenshot_leaves_no_settings_folder(sim, tmp_path, own_tmp):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path), "TMPDIR": str(own_tmp),
           "QT_QPA_PLATFORM": "offscreen"}
    env.pop("PRISMSTATION_SETTINGS_DIR", None)
    host = atomic.OWNER_TAG.split("-")[0]
    stale = own_tmp / f"prismstation-settings-{host}-{_dead_pid()}_abc"
    stale.mkdir()
    (stale / "settings.ini").write_text("[x]\n")
    r = subprocess.run([sys.executable, "-c", "import sys; from prismstation.cli import main; sys.exit(main())",
                        "gui", str(sim / "p.prismproj"), "--screenshot", str(tmp_path / "s.png")],
                       capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert (tmp_path / "s.png").is_file()
    assert not [p for p in own_tmp.iterdir() if p.name.startswith("prismstation-settings-")]


@pytest.mark.skipif(not ft.can_mount(), reason="no tmpfs can be mounted here (a shared file system's "
                    "free space moves with other processes' files)")
def test_the_free_space_is_the_least_seen_while_writing(tmp_path):
    """A writer that used the space and freed it before it failed (as GDAL removes its
    temporary overview file): the watch saw the space it had used."""
    import time
    d = tmp_path / "fs"
    with ft.tmpfs(d, 8192):
        with atomic.FreeSpaceWatch(d, interval=0.01) as watch:
            with open(d / "big", "wb") as fh:
                fh.write(b"\0" * (6 << 20))
            time.sleep(0.1)
            (d / "big").unlink()
        after = atomic.free_bytes(d)
    assert watch.least is not None and watch.least <= after - (5 << 20)
