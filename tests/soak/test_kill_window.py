"""Issue 7 item 1 through the real window: ``kill -9`` a window process in the middle of editing,
then the next window offers to recover and every edit that was on screen is there.

The editor is a separate Python process running the real :class:`MainWindow` offscreen; a timer
performs operator edits through the window's own undo commands (place a new point, move,
delete, switch kind) and logs each edit before (``I``) and after (``C``) it is made. After the
kill, the recovered project must equal the replay of the completed edits, or of those plus the
one that was under way.
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
    r = rng.random()
    if r < 0.4 or not alive:
        pid, view = p.new_point_id("T"), rng.choice("NFB")
        x, y = rng.uniform(5, 395), rng.uniform(5, 395)
        fh.write(f"I P {pid} {view} {x!r} {y!r}\n")
        win.set_current(None)
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
    fh.write("C\n")  # written only after the window's command returned

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
    done, pending = [], None
    for line in log.read_text().splitlines():
        parts = line.split()
        if parts[0] == "I":
            pending = parts[1:]
        elif parts[0] == "C" and pending is not None:
            done.append(pending)
            pending = None
    return done, pending


@pytest.mark.parametrize("mode,seed", [("saved", 3), ("untitled", 4)])
def test_kill_minus_9_in_the_middle_of_editing_loses_nothing(small, make_window, temp_settings,
                                                              tmp_path, mode, seed):
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
    done, pending = read_log(log)
    assert len(done) >= 40
    assert autosave_path(None if mode == "untitled" else small.path).is_file()
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
    a = replay(done)
    b = replay(done + ([pending] if pending else []))
    got = observed(win.project, b)
    initial = None if mode == "untitled" else load_project(small.path)
    assert got in (observed_expect(a, b, initial), observed_expect(b, b, initial)), \
        "an edit on screen was lost"
    # every completed edit is there (the explicit form of the check above)
    for pid, exp in a.items():
        if exp is None:
            assert pid not in win.project.points or (pending and pending[1] == pid)
        else:
            assert pid in win.project.points


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
