"""A one-line label for text that changes all the time (status figures, view headers).

``QLabel.setText`` always asks its layout to recompute, and the request climbs to the main
window, which then relayouts and repaints everything: several milliseconds on every click or
cursor move. :class:`TextLabel` has a size hint fixed at construction (from its widest
expected text) and ``setText`` only repaints the label itself; too long a text is elided.
"""
from __future__ import annotations

import math

from PySide6.QtCore import QSize, Qt
from PySide6.QtGui import QColor, QFont, QFontMetricsF, QPainter
from PySide6.QtWidgets import QSizePolicy, QWidget


class TextLabel(QWidget):
    """One line of text, elided on the right, never resizing its layout.

    Parameters
    ----------
    text : str
        The initial text.
    widest : str, optional
        A sample of the widest text expected: the width hint (default: ``text``).
    background, color : QColor, optional
        Fill and text colour (default: the palette's).
    bold : bool
    stretch : bool
        Take whatever width the layout offers (the hint is then only a minimum to ask for).
    align : Qt.AlignmentFlag
        Horizontal alignment of the text.
    """

    PAD_X, PAD_Y = 6, 3

    def __init__(self, text: str = "", widest: str | None = None, *, background=None, color=None,
                 bold: bool = False, stretch: bool = False, align=Qt.AlignmentFlag.AlignLeft,
                 parent=None):
        super().__init__(parent)
        self._text, self._shorter = text, ()
        if bold:
            f = QFont(self.font())
            f.setBold(True)
            self.setFont(f)
        self._background = QColor(background) if background is not None else None
        self._color = QColor(color) if color is not None else None
        self._align = align | Qt.AlignmentFlag.AlignVCenter
        fm = self.fontMetrics()
        # the advance rounded up: elision measures in fractions of a pixel, and the sample
        # text itself must fit
        width = math.ceil(QFontMetricsF(self.font()).horizontalAdvance(widest if widest is not None else text))
        self._hint = QSize(width + 1 + 2 * self.PAD_X,
                           fm.height() + 2 * self.PAD_Y)
        # paints its whole rectangle: a new text repaints this label only, not its parents
        self.setAttribute(Qt.WidgetAttribute.WA_OpaquePaintEvent)
        horizontal = QSizePolicy.Policy.Ignored if stretch else QSizePolicy.Policy.Fixed
        self.setSizePolicy(horizontal, QSizePolicy.Policy.Fixed)
        self.setFixedHeight(self._hint.height())
        if not stretch:
            self.setFixedWidth(self._hint.width())

    def text(self) -> str:
        return self._text

    def setText(self, text: str, *shorter: str) -> None:
        """Show ``text``; where the label is narrower than it, the first of the ``shorter``
        wordings that fits (else the last, elided)."""
        if text != self._text or shorter != self._shorter:
            self._text, self._shorter = text, shorter
            self.update()

    def set_color(self, color) -> None:
        """The text colour (None: the palette's)."""
        color = QColor(color) if color is not None else None
        if color != self._color:
            self._color = color
            self.update()

    def sizeHint(self) -> QSize:
        return self._hint

    def minimumSizeHint(self) -> QSize:
        return QSize(0, self._hint.height())

    def shown_text(self) -> str:
        """The text as painted: the longest wording that fits, else the shortest elided ("…")."""
        width = self.rect().adjusted(self.PAD_X, 0, -self.PAD_X, 0).width()
        fm = self.fontMetrics()
        for text in (self._text, *self._shorter):
            if fm.horizontalAdvance(text) <= width:
                return text
        return fm.elidedText((self._text, *self._shorter)[-1], Qt.TextElideMode.ElideRight, width)

    def paintEvent(self, event) -> None:
        p = QPainter(self)
        p.fillRect(self.rect(), self._background if self._background is not None
                   else self.palette().color(self.backgroundRole()))
        if self._color is not None:
            p.setPen(self._color)
        r = self.rect().adjusted(self.PAD_X, 0, -self.PAD_X, 0)
        p.drawText(r, int(self._align), self.shown_text())
        p.end()
