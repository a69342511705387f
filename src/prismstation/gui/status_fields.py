"""The status bar's fields: each view's cursor position, the ground under the cursor, the last
fit — and room for the messages.

The fields are :class:`~.text_label.TextLabel` s of a fixed width (a new figure never relayouts
the window). A message is painted in what the permanent fields leave: with three views named
``img_01``… on a 1600 px screen that was too little, and a message was cut where the measuring
mode's label begins. While a message needs more room, the views' cursor positions (also shown
under the loupes) step aside — the last view's first —, then the ground's; they come back with
the message's end.
"""
from __future__ import annotations

from PySide6.QtCore import QObject, Qt
from PySide6.QtWidgets import QWidget

from prismstation.gui.text_label import TextLabel

MESSAGE_PAD_PX = 24  # the status bar's margins around a message


class StatusFields(QObject):
    """The permanent fields of ``window``'s status bar (after those already there: the
    measuring mode's label). ``xy``: view → its cursor-position label; ``ground``, ``fit``."""

    def __init__(self, window):
        super().__init__(window)
        self.sb = window.statusBar()
        self.xy: dict[str, TextLabel] = {}
        self.ground = self.fit = None
        self.set_views(("N", "F", "B"))
        self.ground = self._label("E —  N —  h —", "E 0000000.0  N 00000000.0  h -0000.0 m")
        self.fit = self._label("", "fit 0000 ms · σ0 000.000")
        self._stepped_aside: list = []
        self.sb.messageChanged.connect(self._make_room)

    def _label(self, text: str, widest: str) -> TextLabel:
        lab = TextLabel(text, widest)  # a new value must not relayout the window
        self.sb.addPermanentWidget(lab)
        return lab

    def set_views(self, views) -> None:
        """One cursor-position label per view of the scene, before the ground's and the fit's."""
        if list(self.xy) == list(views):
            return
        after = [lab for lab in (self.ground, self.fit) if lab is not None]
        for lab in (*self.xy.values(), *after):
            self.sb.removeWidget(lab)
        for lab in self.xy.values():
            lab.setParent(None)
            lab.deleteLater()
        self.xy = {v: self._label(f"{v}  —", f"{v}  x -00000.0  y -00000.0")  # to 99,999 px, and < 0
                   for v in views}
        for lab in after:
            self.sb.addPermanentWidget(lab)
            lab.show()

    def clear(self) -> None:
        """No figure of the previous project: cursor positions, ground, fit time, message."""
        for v, lab in self.xy.items():
            lab.setText(f"{v}  —")
        self.ground.setText("E —  N —  h —")
        self.fit.setText("")
        self.sb.clearMessage()

    def show_cursor(self, positions: dict, ground) -> None:
        """``positions``: view → image ``(x, y)`` (views without one show "—"); ``ground``
        ``(E, N, h)`` or None (the last one stays)."""
        for v, lab in self.xy.items():
            xy = positions.get(v)
            lab.setText(f"{v}  x {xy[0]:.1f}  y {xy[1]:.1f}" if xy is not None else f"{v}  —")
        if ground is not None:
            self.ground.setText(f"E {ground[0]:.1f}  N {ground[1]:.1f}  h {ground[2]:.1f} m")

    def message_room(self) -> int:
        """Pixels a message has now: the status bar's width less its visible widgets (the
        permanent fields, the measuring mode's label, the size grip)."""
        spacing = max(self.sb.layout().spacing(), 0)
        used = sum(w.width() + spacing for w in self.sb.findChildren(
            QWidget, options=Qt.FindChildOption.FindDirectChildrenOnly) if w.isVisible())
        return self.sb.width() - used - MESSAGE_PAD_PX

    def _make_room(self, text: str) -> None:
        for lab in self._stepped_aside:
            lab.show()
        self._stepped_aside = []
        if not text:
            return
        need = self.sb.fontMetrics().horizontalAdvance(text)
        for lab in (*reversed(self.xy.values()), self.ground):  # the first view's goes last
            if need <= self.message_room():
                break
            lab.hide()
            self._stepped_aside.append(lab)
