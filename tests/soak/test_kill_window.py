"""Crash recovery through the real window: ``kill -9`` a window process in the middle of editing,
then the next window offers to recover and every edit that was on screen is there.

The editor is a separate Python process running the real :class:`MainWindow` offscreen; a timer
performs operator edits through the window's own undo commands (place a new point, move,
delete, switch kind) and logs each edit before (``I``) and after (``C`` with the project
revision) it is made, and before each edit the revision the journal's writer thread has on disk
(``W``). The journal is written in the background, so the last edits may still be in flight
when the process dies: the recovered project must equal the replay of the edits up to the
revision found in the journal (a consistent state, never a mix), and that revision must be at
least the last one logged as on disk (an edit once written is never lost).
"""
from __future__ import annotations

import hashlib
import os
import random
import signal
import subprocess
import sys
import time

import pytest
from PySide6.QtWidgets import QMessageBox

EDITOR = r"""
import random, sys
from PySide6.QtCore import QTimer
from prismstation.gui.app import make_app, wait_settled
from prismstation.gui.main_window import MainWindow

path, scene, log, mode, seed = sys.argv[1:6]
app = make_app()
win = MainWindow(interactive=False)
win.files.interactive = False
win.show()
ok = win.files.new_project(scene) if mode == "untitled" else win.open_project(path, recover=False)
assert ok and wait_settled(win)
rng = random.Random(int(seed))
fh = open(log, "a", buffering=1)
alive = [p for p in win.project.points]

def step():
    p = win.project
    if win.files.journal.written_revision is not None:  # on disk (the writer thread's report)
        fh.write(f"W {win.files.journal.written_revision}\n")
    r = rng.random()
    if r < 0.4 or not alive:
        pid, view = p.new_point_id("T"), rng.choice("NFB")
        x, y = rng.uniform(5, 395), rng.uniform(5, 395)
        fh.write(f"I P {pid} {view} {x!r} {y!r}\n")
        win.set_current(None)
        win.measure_mode.set_mode("create")
        win.place(view, x, y)
        assert win.current == pid
        alive.append(pid)
    elif r < 0.8:
        pid, view = rng.choice(alive), rng.choice("NFB")
        x, y = rng.uniform(5, 395), rng.uniform(5, 395)
        fh.write(f"I M {pid} {view} {x!r} {y!r}\n")
        win.move(pid, view, x, y, True)
    elif r < 0.9:
        pid = rng.choice(alive)
        fh.write(f"I D {pid}\n")
        win.set_current(pid)
        win.delete_point()
        alive.remove(pid)
    else:
        gs = [q for q in alive if p.points[q].kind in ("GCP", "ICP")]
        if not gs:
            return
        pid = rng.choice(gs)
        kind = "ICP" if p.points[pid].kind == "GCP" else "GCP"
        fh.write(f"I K {pid} {kind}\n")
        win.set_current(pid)
        win.set_kind(kind)
    fh.write(f"C {p.revision}\n")  # written only after the window's command returned

timer = QTimer()
timer.timeout.connect(step)
timer.start(1)
app.exec()
"""


def replay(ops):
    """pid -> None (deleted) or {"kind": k?, view: (x, y), ...} for what the ops touched."""
    state: dict = {}
    for op in ops:
        kind, pid = op[0], op[1]
        if kind == "P":
            state[pid] = {op[2]: (float(op[3]), float(op[4])), "kind": "TIE"}
        elif kind == "M":
            state.setdefault(pid, {})[op[2]] = (float(op[3]), float(op[4]))
        elif kind == "D":
            state[pid] = None
        elif kind == "K":
            state.setdefault(pid, {})["kind"] = op[2]
    return state


def observed(project, expected):
    """The recovered project seen through the keys of ``expected``."""
    out = {}
    for pid, exp in expected.items():
        if pid not in project.points:
            out[pid] = None
            continue
        if exp is None:
            out[pid] = "present"
            continue
        seen = {}
        for key in exp:
            if key == "kind":
                seen[key] = project.points[pid].kind
            else:
                m = project.measurement(pid, key)
                seen[key] = None if m is None else (m.x, m.y)
        out[pid] = seen
    return out


def read_log(log):
    """``(done, revisions, pending, on_disk)``: the completed ops and the project revision after
    each, the op under way (or None), the newest revision logged as written by the journal."""
    done, revs, pending, on_disk = [], [], None, None
    for line in log.read_text().splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "I":
            pending = parts[1:]
        elif parts[0] == "C" and pending is not None and len(parts) == 2:
            done.append(pending)
            revs.append(int(parts[1]))
            pending = None
        elif parts[0] == "W" and len(parts) == 2:
            on_disk = int(parts[1])
    return done, revs, pending, on_disk


@pytest.mark.slow  # 10–15 s each (measured, -n 0)
@pytest.mark.parametrize("mode,seed", [("saved", 3), ("untitled", 4)])
def test_kill_minus_9_in_the_middle_of_editing_loses_nothing(small, make_window, temp_settings,
                                                              tmp_path, mode, seed):
    import json

    from prismstation.gui.project_io import autosave_path
    from prismstation.io.project import load_project
    log = tmp_path / "edits.log"
    before = hashlib.sha256(small.path.read_bytes()).hexdigest()
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen", PRISMSTATION_SETTINGS_DIR=str(temp_settings))
    env.pop("PYTEST_CURRENT_TEST", None)
    proc = subprocess.Popen([sys.executable, "-c", EDITOR, str(small.path), str(small.scene_path),
                             str(log), mode, str(seed)], env=env, cwd=str(tmp_path))
    try:
        want = random.Random(seed).randint(40, 120)
        deadline = time.time() + 90
        while time.time() < deadline and proc.poll() is None:
            if log.exists() and log.read_text().count("\nC") >= want:
                break
            time.sleep(0.02)
        assert proc.poll() is None, "the editor window stopped by itself"
        time.sleep(random.Random(seed).uniform(0.0, 0.2))
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
    assert proc.returncode == -signal.SIGKILL
    done, revs, pending, on_disk = read_log(log)
    assert len(done) >= 40
    side = autosave_path(None if mode == "untitled" else small.path)
    assert side.is_file()
    journaled = json.loads(side.read_text())["recovery"]["revision"]
    assert on_disk is not None and journaled >= on_disk, "an edit already on disk was lost"
    k = sum(r <= journaled for r in revs)  # the completed edits the journal holds
    assert k >= sum(r <= on_disk for r in revs)
    print(f"\n{mode}: {len(done)} edits, journal at revision {journaled} = edit {k} "
          f"({len(done) - k} completed edit(s) in flight at the kill, last logged on disk {on_disk})")
    assert hashlib.sha256(small.path.read_bytes()).hexdigest() == before  # the file untouched

    win = make_window()
    asked = []

    def ask(title, text, buttons=None, default=None):
        asked.append((title, text))
        return QMessageBox.StandardButton.Yes if title == "Recover" else QMessageBox.StandardButton.No
    win.files.ask = ask
    if mode == "untitled":
        assert win.files.recover_untitled()
    else:
        assert win.open_project(small.path)
    assert [t for t, _ in asked] == ["Recover"]
    assert not win.undo_stack.isClean()  # recovered edits still have to be saved
    ops = done + ([pending] if pending else [])
    b = replay(ops)
    got = observed(win.project, b)
    initial = None if mode == "untitled" else load_project(small.path)
    # exactly the state after edit k (or k + 1 when the journaled revision fell inside an edit)
    want = [observed_expect(replay(ops[:n]), b, initial) for n in (k, k + 1) if n <= len(ops)]
    assert got in want, "the journal is not the state after the edits it says it holds"


def observed_expect(state, keys, initial):
    """``state`` in the form :func:`observed` gives, over the pids and keys of ``keys``; what
    the edits did not touch is as in ``initial`` (the project before editing, or None)."""
    base = {} if initial is None else observed(initial, keys)
    out = {}
    for pid, k in keys.items():
        s = state.get(pid, "absent")
        if s == "absent":
            out[pid] = base.get(pid)
        elif s is None:
            out[pid] = None
        elif k is None:
            out[pid] = "present"
        else:
            b = base.get(pid) if isinstance(base.get(pid), dict) else {}
            out[pid] = {key: s[key] if key in s else b.get(key) for key in k}
    return out
