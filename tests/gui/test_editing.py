"""Editing through the real window: stale markers, the status bar, stray clicks, measuring modes
and the point editor — driven by mouse, keys and the table's editors."""
from __future__ import annotations

import math

import numpy as np
from PySide6.QtCore import QPoint, QPointF, Qt
from PySide6.QtGui import QGuiApplication

from tests.gui.test_operator import click_image, key, settle


def screen_pixels(win, view, x, y, half=16, fresh=False):
    """RGB pixels the window shows on screen (its backing store, not a fresh render) in a
    box of ±``half`` screen px around image ``(x, y)`` of ``view``: what the operator sees.
    ``fresh``: the same box of the window rendered anew (what it should show)."""
    iv = win.views.views[view]
    vp = iv.graphics.viewport()
    c = vp.mapTo(win, iv.map_to_viewport(x, y).toPoint())
    img = (win.grab() if fresh else QGuiApplication.primaryScreen().grabWindow(win.winId())).toImage()
    out = np.array([[img.pixelColor(c.x() + i, c.y() + j).getRgb()[:3]
                     for i in range(-half, half + 1)] for j in range(-half, half + 1)])
    return out


def assert_no_ghost(win, view, x, y):
    """The screen around image ``(x, y)`` of ``view`` is what a fresh render shows."""
    assert np.array_equal(screen_pixels(win, view, x, y), screen_pixels(win, view, x, y, fresh=True)), view


def count_colour(px, rgb, tol=40):
    return int(np.sum(np.all(np.abs(px - np.array(rgb)) <= tol, axis=-1)))


MAGENTA = (255, 0, 255)


def drag_marker(qtbot, win, view, x, y, dx, dy):
    """Press on the marker at image ``(x, y)`` of ``view`` and drag it ``(dx, dy)`` screen px."""
    iv = win.views.views[view]
    vp = iv.graphics.viewport()
    start = iv.map_to_viewport(x, y).toPoint() + QPoint(3, 2)
    n = 10
    qtbot.wait(600)
    qtbot.mousePress(vp, Qt.MouseButton.LeftButton, pos=start)
    for i in range(1, n + 1):
        qtbot.wait(25)
        qtbot.mouseMove(vp, start + QPoint(round(dx * i / n), round(dy * i / n)))
    qtbot.mouseRelease(vp, Qt.MouseButton.LeftButton, pos=start + QPoint(dx, dy))


def test_undoing_a_blunder_drag_clears_magenta_in_the_other_views(qtbot, window):
    """Issue 13 bug 2: a marker dragged in F becomes a blunder (magenta in N, F, B); after
    Ctrl+Z the screen of N and B no longer shows it magenta (it did until a pan)."""
    win = window
    assert not any(r.blunder for r in win.solver.solution.points)
    m = win.project.measurement("G3", "F")
    win.views.views["F"].center_on(m.x, m.y, 1.0)
    drag_marker(qtbot, win, "F", m.x, m.y, 40, -30)
    settle(qtbot, win)
    assert {r.id for r in win.solver.solution.points if r.blunder} == {"G3"}
    qtbot.wait(50)
    for v in ("N", "B"):
        xy = win.project.measurement("G3", v)
        assert count_colour(screen_pixels(win, v, xy.x, xy.y), MAGENTA) > 10, v
    key(qtbot, win, "Ctrl+Z")
    settle(qtbot, win)
    qtbot.wait(50)
    assert not any(r.blunder for r in win.solver.solution.points)
    for v in ("N", "B"):
        xy = win.project.measurement("G3", v)
        assert count_colour(screen_pixels(win, v, xy.x, xy.y), MAGENTA) == 0, v
        assert_no_ghost(win, v, xy.x, xy.y)


YELLOW = (255, 210, 60)  # tie points (markers, predictions, labels); the images are grey


def free_spot(win, view="N"):
    """Image (x, y) in ``view`` at least 60 px from every measured marker."""
    ov = win.views.overlays[view]
    return next((x, y) for x in range(150, 650, 37) for y in range(150, 650, 41)
                if ov.nearest(x, y, 60) is None)


def measure_new_tie_in_n(qtbot, win):
    """Insert a tie point and click it in N; returns its id and its predicted positions in F
    and B (at the mean height), each view centred on it and showing it in yellow."""
    for iv in win.views.views.values():
        iv.set_scale(1.0)
    x, y = free_spot(win)
    win.views.views["N"].center_on(x, y)
    key(qtbot, win, "Insert")
    pid = win.current
    click_image(qtbot, win, "N", x, y)
    settle(qtbot, win)
    pred = {v: win.views.point_position(pid, v) for v in ("F", "B")}
    for v, xy in pred.items():
        assert win.project.measurement(pid, v) is None and xy is not None
        win.views.views[v].center_on(*xy)
    qtbot.wait(50)
    for v, xy in pred.items():
        assert count_colour(screen_pixels(win, v, *xy), YELLOW) > 10
    return pid, pred


def test_undoing_a_points_creation_leaves_no_ghost_in_the_other_views(qtbot, window):
    """Issue 13 bug 2: the predicted markers of an undone point stayed on screen in F and B."""
    win = window
    pid, pred = measure_new_tie_in_n(qtbot, win)
    for _ in range(2):                   # the click, then the creation
        key(qtbot, win, "Ctrl+Z")
    settle(qtbot, win)
    qtbot.wait(50)
    assert pid not in win.project.points
    assert win.current is None           # no current point that no longer exists
    for v, xy in pred.items():
        assert count_colour(screen_pixels(win, v, *xy), YELLOW) == 0, v
        assert_no_ghost(win, v, *xy)


def test_deleting_a_points_only_measurement_leaves_no_ghost(qtbot, window):
    """Issue 13 bug 2: Del on a point's only measurement left its predictions on screen."""
    win = window
    pid, pred = measure_new_tie_in_n(qtbot, win)
    n = win.project.measurement(pid, "N")
    iv = win.views.views["N"]
    qtbot.mouseMove(iv.graphics.viewport(), iv.map_to_viewport(n.x + 30, n.y).toPoint())
    key(qtbot, win, "Del")               # in the view under the cursor
    settle(qtbot, win)
    qtbot.wait(50)
    assert win.project.measurement(pid, "N") is None and pid in win.project.points
    assert count_colour(screen_pixels(win, "N", n.x, n.y), YELLOW) == 0
    assert_no_ghost(win, "N", n.x, n.y)
    for v, xy in pred.items():
        assert count_colour(screen_pixels(win, v, *xy), YELLOW) == 0, v
        assert_no_ghost(win, v, *xy)
