"""Replacing a project file never leaves a moment without a valid project at its path.

Every ``os.replace`` a save makes is, in turn, made to fail (an I/O error) or to kill the
process (SIGKILL, in a subprocess): after each, the project's path holds the previous version
or the new one, whole, and loads. The backup is made by a hard link, or by a copy where links
cannot be made (also tested)."""
from __future__ import annotations

import errno
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from prismstation.errors import WriteError
from prismstation.io.project import load_project, save_project



def _two_versions(sim):
    """The project at ``sim/p.prismproj`` (old) and a changed copy to save over it (new)."""
    path = sim / "p.prismproj"
    project = load_project(path)
    old = path.read_bytes()
    pid = next(iter(project.points))
    project.set_kind(pid, "ICP" if project.points[pid].kind == "GCP" else "GCP")
    return path, project, old


def _replace_calls(path, project) -> int:
    """How many ``os.replace`` calls one save makes (counted on a scratch copy)."""
    scratch = path.with_name("count.prismproj")
    scratch.write_bytes(path.read_bytes())
    calls = []
    real = os.replace

    def counting(*a, **k):
        calls.append(a)
        return real(*a, **k)
    os.replace = counting
    try:
        save_project(project, scratch)
    finally:
        os.replace = real
    for f in scratch.parent.glob("count.prismproj*"):
        f.unlink()
    return len(calls)


def _assert_whole(path, old: bytes, new: bytes) -> None:
    assert path.is_file(), "no project at its path"
    assert path.read_bytes() in (old, new)
    load_project(path)


def test_a_failing_replace_at_each_call_leaves_a_project(sim, monkeypatch):
    path, project, old = _two_versions(sim)
    n = _replace_calls(path, project)
    assert n == 2  # the backup's rename, then the project's
    save_project(project, path)  # the new version's bytes, to compare against
    new = path.read_bytes()
    for k in range(1, n + 1):
        path.write_bytes(old)
        real, calls = os.replace, []

        def failing(*a, _k=k, **kw):
            calls.append(a)
            if len(calls) == _k:
                raise OSError(errno.EIO, "Input/output error")
            return real(*a, **kw)
        monkeypatch.setattr(os, "replace", failing)
        with pytest.raises(WriteError):
            save_project(project, path)
        monkeypatch.setattr(os, "replace", real)
        _assert_whole(path, old, new)
        assert path.read_bytes() == old  # a failed save changes nothing
        assert not [f for f in sim.iterdir() if ".part" in f.name]


_KILLER = textwrap.dedent("""
    import os, signal, sys
    from prismstation.io.project import load_project, save_project
    path, k = sys.argv[1], int(sys.argv[2])
    project = load_project(path)
    pid = next(iter(project.points))
    project.set_kind(pid, "ICP" if project.points[pid].kind == "GCP" else "GCP")
    real, calls = os.replace, []
    def killing(*a, **kw):
        calls.append(a)
        if len(calls) == k:
            os.kill(os.getpid(), signal.SIGKILL)
        return real(*a, **kw)
    os.replace = killing
    save_project(project, path)
""")


@pytest.mark.parametrize("k", [1, 2])
def test_a_kill_at_each_replace_leaves_a_project(sim, k):
    path, project, old = _two_versions(sim)
    save_project(project, path)
    new = path.read_bytes()
    path.write_bytes(old)
    r = subprocess.run([sys.executable, "-c", _KILLER, str(path), str(k)], capture_output=True)
    assert r.returncode == -9, r.stderr.decode()
    _assert_whole(path, old, new)
    assert path.read_bytes() == old  # killed before (k = 1) or at (k = 2) the one rename


def test_the_backup_is_a_copy_where_links_cannot_be_made(sim, monkeypatch):
    path, project, old = _two_versions(sim)

    def no_link(*a, **k):
        raise OSError(errno.EPERM, "Operation not permitted")
    monkeypatch.setattr(os, "link", no_link)
    save_project(project, path)
    assert Path(str(path) + ".bak").read_bytes() == old
    assert path.read_bytes() != old
    load_project(path)
    assert not [f for f in sim.iterdir() if ".part" in f.name]
