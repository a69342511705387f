"""Soak: thousands of random operator actions through the real window (offscreen) —
place, move, delete, undo, redo, switch kind, save, reopen — with no exception anywhere (an
excepthook that fails the test) and resident memory growing less than 10 % between the first
and the last thousand actions.

``PRISMSTATION_SOAK_ACTIONS`` sets the number of actions (default 2000, the least that has a
first and a last thousand); ``PRISMSTATION_SOAK_SEED`` the seed.
"""
from __future__ import annotations

import os
import random
import sys

import pytest
from PySide6.QtCore import QCoreApplication, QEvent

ACTIONS = max(2000, int(os.environ.get("PRISMSTATION_SOAK_ACTIONS", "2000")))
SEED = int(os.environ.get("PRISMSTATION_SOAK_SEED", "20261122"))


def rss_kib() -> int:
    """Resident memory of this process (VmRSS, KiB)."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    raise RuntimeError("no VmRSS in /proc/self/status")


def content(project) -> tuple:
    return (dict(project.points), dict(project.measurements), project.settings, project.geoid)


class Operator:
    """A random operator at the real window: every action goes through the window's own
    slots and actions (the ones its menus, keys and mouse gestures call)."""

    def __init__(self, win, path, rng):
        self.win, self.path, self.rng = win, path, rng
        self.counts: dict[str, int] = {}

    def pick(self):
        ids = list(self.win.project.points)
        return self.rng.choice(ids) if ids else None

    def xy(self):
        return self.rng.uniform(2.0, 398.0), self.rng.uniform(2.0, 398.0)

    def act(self) -> str:
        w, r = self.win, self.rng.random()
        if r < 0.22:
            name = "place"
            if self.rng.random() < 0.5:
                w.set_current(None, drive=False)
            else:
                w.set_current(self.pick(), drive=False)
            w.place(self.rng.choice("NFB"), *self.xy())
        elif r < 0.42:
            name = "move"
            ms = list(w.project.measurements)
            if ms:
                pid, view = self.rng.choice(ms)
                x, y = self.xy()
                for k in range(self.rng.randint(1, 4)):  # a short drag: merged into one step
                    w.move(pid, view, x + k, y - k, k == 3)
        elif r < 0.50:
            name = "delete"
            w.set_current(self.pick(), drive=False)
            w.a_del_point.trigger()
        elif r < 0.65:
            name = "undo"
            w.a_undo.trigger()
        elif r < 0.77:
            name = "redo"
            w.a_redo.trigger()
        elif r < 0.90:
            name = "kind"
            w.set_current(self.pick(), drive=False)
            w.a_kind[self.rng.choice(("GCP", "ICP", "TIE"))].trigger()
        elif r < 0.975:
            name = "save"
            assert w.files.save_as(str(self.path)) if w.files.path is None else w.files.save()
            assert w.undo_stack.isClean()
        else:
            name = "reopen"
            if self.rng.random() < 0.5:
                assert w.files.save()
            saved = self.rng.random() < 0.5 or not w.undo_stack.isClean()
            before = content(w.project) if w.undo_stack.isClean() else None
            assert w.open_project(self.path, recover=False, check_unsaved=False)
            if before is not None and saved:
                assert content(w.project) == before  # a saved project reads back the same
        self.counts[name] = self.counts.get(name, 0) + 1
        return name


def settle(win) -> None:
    from prismstation.gui.app import wait_settled
    for _ in range(5):
        if wait_settled(win):
            QCoreApplication.sendPostedEvents(None, QEvent.Type.DeferredDelete)
            return
    v = win.views
    raise AssertionError(f"the window does not settle: loading {v.loading()}, fitting "
                         f"{win.solver.busy()}, tiles {[x.tiles_complete() for x in v.views.values()]}")


@pytest.mark.slow  # 79 s (measured, -n 0)
def test_thousands_of_random_actions_no_exception_bounded_memory(small, make_window, monkeypatch):
    from prismstation.gui.app import wait_settled
    errors = []

    def hook(kind, value, tb):
        import traceback
        errors.append("".join(traceback.format_exception(kind, value, tb)))
    monkeypatch.setattr(sys, "excepthook", hook)

    win = make_window()
    assert win.open_project(small.path, recover=False)
    assert wait_settled(win)
    op = Operator(win, small.path, random.Random(SEED))
    rss = []
    turn = 0  # actions left in this event-loop turn: a quick operator does several per turn
    for i in range(ACTIONS):
        name = op.act()
        turn -= 1
        if turn <= 0 or name == "reopen":
            turn = op.rng.randint(1, 12)
            QCoreApplication.processEvents()
            # what returning to the event loop does: objects given to deleteLater() go now
            QCoreApplication.sendPostedEvents(None, QEvent.Type.DeferredDelete)
        if name == "reopen" or i % 250 == 249:
            settle(win)
            sol = win.solver.solution
            assert sol is None or sol.revision <= win.project.revision
        rss.append(rss_kib())
        assert not errors, f"action {i} ({name}) raised:\n{errors[0]}"
    settle(win)
    assert not errors, errors[0]
    first, last = max(rss[:1000]), max(rss[-1000:])
    growth = last / first - 1.0
    trace = " ".join(f"{max(rss[k:k + 250]) / 1024:.0f}" for k in range(0, len(rss), 250))
    print(f"\nsoak: {ACTIONS} actions {op.counts}; VmRSS max first 1000 {first / 1024:.1f} MiB, "
          f"last 1000 {last / 1024:.1f} MiB, growth {100 * growth:+.1f} %; per 250 actions (MiB): {trace}")
    for name in ("place", "move", "delete", "undo", "redo", "kind", "save", "reopen"):
        assert op.counts.get(name, 0) > 0, f"no {name} action in the run"
    assert growth < 0.10, f"resident memory grew {100 * growth:.1f} % (≥ 10 %)"
    # the journal holds the last state after all that: recovery reads it back equal
    if not win.undo_stack.isClean():
        from prismstation.io.recovery import recover
        assert win.files.flush_journal(timeout=30)  # the journal writes on its own thread
        assert content(recover(small.path)) == content(win.project)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(pytest.main([__file__, "-q", "-s"]))
