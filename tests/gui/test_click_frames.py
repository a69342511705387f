"""A click is answered in the next frame: the marker, its label, the loupe and the table's row
are on screen when the click's own handling ends, before the refit; a click made while a refit
runs is taken at once, and the refits coalesce."""
from __future__ import annotations

import threading
import time

import numpy as np

from tests.gui.test_editing import assert_no_ghost
from tests.gui.test_operator import click_image, settle


def _on_screen_now(win, view, xy):
    """The window's backing store shows image ``xy`` of ``view`` as a fresh render would."""
    assert_no_ghost(win, view, *xy)


def test_the_click_is_painted_before_the_refit(qtbot, window):
    win = window
    m = win.project.measurement("G2", "N")
    win.set_current("G2", drive=True)
    settle(qtbot, win)
    qtbot.wait(50)
    rev = win.solver.solution.revision
    new = click_image(qtbot, win, "N", m.x + 9.0, m.y - 7.0)  # no event-loop pass after it
    assert win.project.measurement("G2", "N").x == new[0]
    assert win.solver.solution.revision == rev  # the refit has not run yet ...
    _on_screen_now(win, "N", new)               # ... and the marker (label, square) is painted
    _on_screen_now(win, "N", (m.x, m.y))        # where it was: gone
    assert win.loupes["N"].position == tuple(new)
    settle(qtbot, win)
    assert win.solver.solution.revision == win.project.revision

    # a point measured for the first time in a view: its row says so in that first frame
    g9 = "G9"
    win.set_current(g9, drive=False)
    settle(qtbot, win)
    qtbot.wait(50)
    assert win.table_model.cell(g9, "Views") == "· · ·"
    xy = win.views.point_position(g9, "N")
    win.views.views["N"].center_on(*xy)
    qtbot.wait(50)
    click_image(qtbot, win, "N", *xy)
    assert win.table_model.cell(g9, "Views") == "N · ·"
    t = win.table
    idx = win.table_model.index(win.table_model.row_of(g9), 2)
    t.scrollTo(idx)  # (scrolls: painted by the event loop; then compare what the screen shows)
    qtbot.wait(30)
    from PySide6.QtGui import QGuiApplication
    r = t.visualRect(idx).translated(t.viewport().mapTo(win, t.visualRect(idx).topLeft()) - t.visualRect(idx).topLeft())
    screen = QGuiApplication.primaryScreen().grabWindow(win.winId()).toImage().copy(r)
    assert screen == win.grab().toImage().copy(r)


def test_clicks_during_a_refit_are_taken_and_the_refits_coalesce(qtbot, window, monkeypatch):
    """Fits made slow and sent to the worker: three clicks while one runs are each answered at
    once (their marker painted); one more fit follows the running one, for the last state."""
    from prismstation.gui import solver as solver_mod
    win = window
    real = solver_mod.solve_project
    fits, running, release = [], threading.Event(), threading.Event()

    def slow(snap, *a, **k):
        fits.append(snap.revision)
        running.set()
        # held until the three clicks are made (a fixed sleep let a loaded machine end the fit
        # before the third click); the interpreter is free meanwhile, as in the fit's numpy work
        release.wait(20)
        return real(snap, *a, **k)
    monkeypatch.setattr(solver_mod, "solve_project", slow)
    monkeypatch.setattr(win.solver, "inline_ms", 0.0)
    m = win.project.measurement("G2", "N")
    win.set_current("G2", drive=True)
    settle(qtbot, win)
    fits.clear()
    n0 = win.undo_stack.count()
    click_image(qtbot, win, "N", m.x + 5, m.y)
    qtbot.waitUntil(running.is_set, timeout=5000)  # the refit of the first click runs
    taken = []
    for k in (1, 2, 3):
        t0 = time.perf_counter()
        xy = click_image(qtbot, win, "N", m.x + 5 + 4 * k, m.y - 3 * k)
        taken.append(time.perf_counter() - t0)
        _on_screen_now(win, "N", xy)
        qtbot.wait(5)
    assert win.solver.busy() and len(fits) == 1  # all three made while the first fit ran
    assert max(taken) < 0.2, taken               # none waited for it
    release.set()
    settle(qtbot, win)
    assert win.undo_stack.count() == n0 + 4
    assert (win.project.measurement("G2", "N").x, win.project.measurement("G2", "N").y) == tuple(xy)
    assert len(fits) == 2 and fits[-1] == win.project.revision  # coalesced: one more, the last
    res = win.solver.solution.point("G2")
    assert np.allclose(res.measured["N"], xy)
