"""The measuring mode: what a left click on an image does.

* **Create point** (C): a click away from other markers creates a new tie point there and
  makes it current; the mode then turns to *Measure*, so the next clicks place that point in
  the other views.
* **Measure current point** (M, the default): a click places the current point (or moves it
  to the click); with no current point nothing happens and the status bar says why — a stray
  click never creates a point.
* **Navigate** (V): clicks and drags only pan and pick; no marker is placed or moved.

In every mode a click on another point's marker makes that point current (a point just made by
Insert and not placed yet is then dropped: the click meant to place it). The mode shows in
the cursor over the images (a cross with a plus, a cross, an open hand), in the status bar
and in the checked button of the toolbar.
"""
from __future__ import annotations

from PySide6.QtCore import QObject, QPointF, Qt, QTimer, Signal
from PySide6.QtGui import QAction, QActionGroup, QColor, QCursor, QKeySequence, QPainter, QPen, QPixmap
from PySide6.QtWidgets import QToolBar, QToolTip

from prismstation.gui.text_label import TextLabel

MODES = {"create": ("&Create point", "C", "Create a new tie point with a click in a view"),
         "measure": ("&Measure point", "M", "A click places the current point in that view"),
         "navigate": ("Na&vigate", "V", "Clicks and drags only pan, zoom and pick points")}


def _create_cursor() -> QCursor:
    """A cross with a small plus beside it: a click here makes a new point."""
    pm = QPixmap(32, 32)
    pm.fill(Qt.GlobalColor.transparent)
    p = QPainter(pm)
    for colour, width in ((QColor(0, 0, 0), 3.0), (QColor(255, 255, 255), 1.0)):
        p.setPen(QPen(colour, width))
        for a, b in (((1, 11), (8, 11)), ((14, 11), (21, 11)), ((11, 1), (11, 8)), ((11, 14), (11, 21)),
                     ((20, 26), (30, 26)), ((25, 21), (25, 31))):
            p.drawLine(QPointF(*a), QPointF(*b))
    p.end()
    return QCursor(pm, 11, 11)


class MeasureMode(QObject):
    """The mode of ``window`` (a main window): its actions, status label and view cursors.

    Signals
    -------
    changed(mode)
        One of :data:`MODES`' keys.
    """

    changed = Signal(str)

    def __init__(self, window):
        super().__init__(window)
        self.w = window
        self.mode = "measure"
        self.group = QActionGroup(window)
        self.actions: dict[str, QAction] = {}
        for key, (text, shortcut, tip) in MODES.items():
            a = QAction(text, window)
            a.setShortcut(QKeySequence(shortcut))
            a.setCheckable(True)
            a.setStatusTip(f"{tip} ({shortcut})")
            a.setToolTip(f"{tip} ({shortcut})")
            a.triggered.connect(lambda _=False, k=key: self.set_mode(k))
            self.group.addAction(a)
            window.addAction(a)
            self.actions[key] = a
        self.label = TextLabel("", "Mode: measure (no point)")  # longer ids are elided
        window.statusBar().insertPermanentWidget(0, self.label)
        self._cursors = {"create": _create_cursor(), "measure": QCursor(Qt.CursorShape.CrossCursor),
                         "navigate": QCursor(Qt.CursorShape.OpenHandCursor)}
        self._install_in_menus()
        window.workspace.current_changed.connect(lambda *_: self._show())
        window.workspace.project_changed.connect(lambda *_: self._show())  # (no current point)
        window.views.images_loaded.connect(self._apply_to_views)
        window.a_new_point.triggered.connect(lambda: self.set_mode("measure"))
        self.set_mode("measure")

    def _install_in_menus(self) -> None:
        w, acts = self.w, list(self.actions.values())
        w.edit_menu.insertActions(w.a_new_point, acts)
        w.edit_menu.insertSeparator(w.a_new_point)
        tb = w.findChild(QToolBar, "toolbar_main")
        if tb is not None:
            tb.insertActions(w.a_new_point, acts)
            tb.insertSeparator(w.a_new_point)

    def set_mode(self, mode: str) -> None:
        if mode not in MODES:
            raise ValueError(f"measuring mode {mode!r} is not one of {', '.join(MODES)}")
        self.actions[mode].setChecked(True)
        changed = mode != self.mode
        self.mode = mode
        self._apply_to_views()
        self._show()
        if changed:
            self.changed.emit(mode)

    def _apply_to_views(self) -> None:
        views = self.w.views
        views.editable = self.mode != "navigate"
        views.view_cursor = self._cursors[self.mode]
        for iv in views.views.values():
            iv.graphics.viewport().setCursor(views.view_cursor)

    def _show(self) -> None:
        cur = self.w.current
        text = {"create": "Mode: create point", "navigate": "Mode: navigate",
                "measure": f"Mode: measure {cur}" if cur else "Mode: measure (no point)"}[self.mode]
        self.label.setText(text)

    def cursor(self) -> QCursor:
        """The cursor shown over the images in this mode."""
        return self._cursors[self.mode]

    def target(self, view: str | None = None, x: float = 0.0, y: float = 0.0) -> str | None:
        """The point a click at image ``(x, y)`` of ``view`` places: a new tie point id (Create,
        which then turns to Measure), the current point (Measure), or None (Navigate, or no
        current point: the status bar and a tip at the click say what to do)."""
        p, cur = self.w.project, self.w.current
        if p is None or self.mode == "navigate":
            return None
        if self.mode == "create":
            return p.new_point_id("T")
        if cur is None or cur not in p.points:
            text = "No current point: pick one (a marker, the table, PgDown) or press C to create one"
            self.w.statusBar().showMessage(text, 8000)
            iv = self.w.views.views.get(view)
            if iv is not None:
                vp = iv.graphics.viewport()  # after the click's own events, which hide tips
                at = vp.mapToGlobal(iv.map_to_viewport(x, y).toPoint())
                QTimer.singleShot(0, vp, lambda: QToolTip.showText(at, text, vp))
            return None
        return cur

    def placed(self, pid: str) -> None:
        """A click placed ``pid``: after creating a point, measure it in the other views."""
        if self.mode == "create":
            self.set_mode("measure")
