"""Short texts laid out once and drawn many times: the table's and the model panel's cells,
which a refit repaints at every click with mostly the same strings ("0.03", "GCP")."""
from __future__ import annotations

from PySide6.QtCore import QPointF, Qt
from PySide6.QtGui import QFont, QPainter, QStaticText

ALIGN_LEFT = int(Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignVCenter)
ALIGN_RIGHT = int(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)


class StaticTexts:
    """``draw(p, x, y, w, h, right, text)``: ``text`` in the box ``x, y, w × h`` (px) with the
    font given to :meth:`set_font` and the painter's pen, left- or right-aligned and centred
    vertically — the pixels of ``QPainter.drawText`` with those flags, at half its cost once
    a text was seen. A text wider than its box is drawn by ``drawText`` (clipped to the box,
    as Qt's cells are)."""

    def __init__(self, size: int = 4000):
        self.size = size
        self._laid_out: dict = {}  # (text, font key) -> (QStaticText, width, height)
        self._font, self._font_key = None, ""

    def __len__(self) -> int:
        return len(self._laid_out)

    def set_font(self, p: QPainter, font: QFont) -> None:
        """Paint with ``font`` from now on (``p.setFont``; its key read once, not per text)."""
        p.setFont(font)
        self._font, self._font_key = font, font.key()

    def draw(self, p: QPainter, x: int, y: int, w: int, h: int, right: bool, text: str) -> None:
        if not text:
            return
        key = (text, self._font_key)
        hit = self._laid_out.get(key)
        if hit is None:
            if len(self._laid_out) >= self.size:
                self._laid_out.clear()
            st = QStaticText(text)
            st.setTextFormat(Qt.TextFormat.PlainText)
            st.prepare(p.transform(), self._font)
            size = st.size()
            hit = self._laid_out[key] = (st, size.width(), size.height())
        st, tw, th = hit
        if tw > w:
            p.drawText(x, y, w, h, ALIGN_RIGHT if right else ALIGN_LEFT, text)
            return
        p.drawStaticText(QPointF(x + w - tw if right else x, y + (h - th) / 2), st)
