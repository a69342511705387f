"""One colour per point kind, for every part of the window (markers on the images, the point
table, the plots, the accuracy strip, the report's figures).

Colours are ``(r, g, b)`` tuples, 0–255, chosen to read both on grey imagery and on a white
plot background; :func:`qcolor` gives a ``QColor``.
"""
from __future__ import annotations

from PySide6.QtGui import QColor

KIND_RGB = {"GCP": (235, 40, 40), "ICP": (20, 140, 255), "TIE": (240, 180, 0)}
BLUNDER_RGB = (255, 0, 255)
CURRENT_RGB = (255, 255, 255)
CURSOR_RGB = (80, 255, 80)
FIT_RGB = (20, 20, 20)
THEORY_RGB = (0, 150, 60)


def qcolor(kind_or_rgb, alpha: int = 255) -> QColor:
    """``QColor`` of a point kind (``"GCP"`` …) or of an ``(r, g, b)`` tuple."""
    r, g, b = KIND_RGB.get(kind_or_rgb, CURRENT_RGB) if isinstance(kind_or_rgb, str) else kind_or_rgb
    return QColor(r, g, b, alpha)


def kind_icon(kind: str, side: int = 16):
    """A ``QIcon``: a filled disc in the colour of ``kind`` (toolbar and menus)."""
    from PySide6.QtCore import Qt
    from PySide6.QtGui import QIcon, QPainter, QPixmap
    pm = QPixmap(side, side)
    pm.fill(Qt.GlobalColor.transparent)
    p = QPainter(pm)
    p.setRenderHint(QPainter.RenderHint.Antialiasing)
    p.setPen(qcolor(kind).darker(150))
    p.setBrush(qcolor(kind))
    p.drawEllipse(2, 2, side - 4, side - 4)
    p.end()
    return QIcon(pm)


def html(kind: str) -> str:
    """``#rrggbb`` of a point kind (rich text)."""
    return qcolor(kind).name()
