"""Shared pieces of the rectification / resection / DSM tools: the project's points of one view,
and a refresh coalescer. (Their worker thread is :mod:`._worker`.)"""
from __future__ import annotations

import numpy as np
from PySide6.QtCore import QObject, QTimer


def view_points(project, view: str):
    """GCPs and ICPs of ``project`` measured in ``view``.

    Returns ``(ids, xy, ground, is_check)``: ids (n,), image ``xy`` (n, 2) pixels, ``ground``
    (n, 3) ``E, N, H`` (metres, project CRS; H of the point's own height kind) and ``is_check``
    (n,) True for ICPs. Tie points are left out (no ground coordinates).
    """
    ids, xy, g, chk = [], [], [], []
    for pid, p in project.points.items():
        if p.kind not in ("GCP", "ICP"):
            continue
        m = project.measurement(pid, view)
        if m is None:
            continue
        ids.append(pid)
        xy.append((m.x, m.y))
        g.append((p.E, p.N, p.H))
        chk.append(p.kind == "ICP")
    return (tuple(ids), np.array(xy, float).reshape(-1, 2), np.array(g, float).reshape(-1, 3),
            np.array(chk, bool))


class Coalescer(QObject):
    """Call ``fn()`` once on the next event-loop turn however often :meth:`poke` was called."""

    def __init__(self, fn, parent=None):
        super().__init__(parent)
        self._t = QTimer(self)
        self._t.setSingleShot(True)
        self._t.setInterval(0)
        self._t.timeout.connect(fn)

    def poke(self, *_) -> None:
        self._t.start()


def watch_project(ctx, fn) -> Coalescer:
    """Call ``fn()`` after every edit, fit, and project (re)load of ``ctx``."""
    c = Coalescer(fn, ctx.widget)
    ctx.undo_stack.indexChanged.connect(c.poke)
    ctx.solver.solution_changed.connect(c.poke)
    ctx.views.images_loaded.connect(c.poke)
    return c
