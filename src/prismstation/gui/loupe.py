"""Loupe: a magnified window of the full-resolution pixels under the cursor.

The loupe shows ``n × n`` full-resolution pixels around the image point ``(x, y)`` (docs/model.md §1:
x = column, y = row, origin top-left corner of the top-left pixel), each drawn as a
``zoom × zoom`` block without interpolation, and a crosshair at the exact subpixel position.
Pixels come from the view's :class:`~prismstation.io.raster.RasterSource` (cached full-resolution
tiles when present, else one small read).
"""
from __future__ import annotations

import math

import numpy as np
from PySide6.QtCore import QPointF, QRectF, QSize, Qt
from PySide6.QtGui import QColor, QImage, QPainter, QPen
from PySide6.QtWidgets import QWidget

from prismstation.errors import RasterReadError


class Loupe(QWidget):
    """Magnified full-resolution window under a cursor, with a subpixel crosshair.

    Parameters
    ----------
    zoom : int
        Screen pixels per image pixel, at most: a smaller widget shows whole screen pixels per
        image pixel as many as fit (at least ``MIN_ZOOM``), centred.
    pixels : int
        Side of the window shown, in image pixels (odd values centre the cursor's pixel).
    label : str
        The view's name, painted in the top-left corner (N, F, B).
    """

    MIN_ZOOM = 3

    def __init__(self, parent=None, zoom: int = 8, pixels: int = 25, label: str = ""):
        super().__init__(parent)
        self.max_zoom = self.zoom = int(zoom)
        self.pixels = int(pixels)
        self.label = label
        self.source = None
        self.levels = (0.0, 255.0)
        self.position: tuple[float, float] | None = None
        self.origin = (0, 0)  # image (column, row) of the window's top-left pixel
        self.window: np.ndarray | None = None  # (pixels, pixels) raw values
        self._qimage: QImage | None = None
        self.setMinimumSize(self.minimumSizeHint())

    def sizeHint(self) -> QSize:
        side = self.max_zoom * self.pixels
        return QSize(side, side)

    def minimumSizeHint(self) -> QSize:
        side = self.MIN_ZOOM * self.pixels
        return QSize(side, side)

    def resizeEvent(self, ev) -> None:
        """Whole screen pixels per image pixel, as many as the widget holds (no interpolation)."""
        self.zoom = max(self.MIN_ZOOM, min(self.max_zoom, min(self.width(), self.height()) // self.pixels))
        super().resizeEvent(ev)

    def attach(self, view) -> None:
        """Follow an ImageView: its source, its levels and the cursor over it."""
        self.source = view.source
        self.levels = view.levels()
        view.cursor_moved.connect(self.set_position)
        view.levels_changed.connect(self.set_levels)
        view.source_changed.connect(lambda: self.set_source(view.source))
        self._view = view

    def set_source(self, source) -> None:
        self.source = source
        self.window = None
        self.position = None
        self.update()

    def set_levels(self, lo: float, hi: float) -> None:
        self.levels = (float(lo), float(hi))
        self._render()

    def set_position(self, x: float, y: float) -> None:
        """Show the pixels around image point ``(x, y)``."""
        if self.source is None:
            return
        self.position = (float(x), float(y))
        half = self.pixels // 2
        x0, y0 = math.floor(x) - half, math.floor(y) - half
        if self.window is None or (x0, y0) != self.origin:
            try:
                self.window = self.source.read_pixels(x0, y0, self.pixels, self.pixels)
            except RasterReadError:
                self.window = np.zeros((self.pixels, self.pixels), self.source.dtype)
            self.origin = (x0, y0)
            self._render()
        else:
            self.update()

    def _render(self) -> None:
        if self.window is None:
            return
        lo, hi = self.levels
        g = np.clip((self.window.astype(np.float32) - lo) * (255.0 / max(hi - lo, 1e-12)), 0, 255)
        g = np.ascontiguousarray(g.astype(np.uint8))
        h, w = g.shape
        self._qimage = QImage(g.data, w, h, w, QImage.Format.Format_Grayscale8).copy()
        self.update()

    def screen_of(self, x: float, y: float) -> QPointF:
        """Widget position of image point ``(x, y)`` in the loupe's current window (the
        magnified pixels are centred in the widget)."""
        o = self._offset()
        return QPointF(o.x() + (x - self.origin[0]) * self.zoom, o.y() + (y - self.origin[1]) * self.zoom)

    def _offset(self) -> QPointF:
        side = self.pixels * self.zoom
        return QPointF(max(0, (self.width() - side) // 2), max(0, (self.height() - side) // 2))

    def paintEvent(self, ev) -> None:
        p = QPainter(self)
        p.fillRect(self.rect(), QColor(0, 0, 0))
        if self._qimage is not None:
            side = self.pixels * self.zoom
            p.setRenderHint(QPainter.RenderHint.SmoothPixmapTransform, False)
            o = self._offset()
            p.drawImage(QRectF(o.x(), o.y(), side, side), self._qimage)
        if self.position is not None:
            c = self.screen_of(*self.position)
            p.setRenderHint(QPainter.RenderHint.Antialiasing, True)
            for color, width in ((QColor(0, 0, 0, 160), 3.0), (QColor(255, 60, 0), 1.0)):
                p.setPen(QPen(color, width))
                gap = self.zoom * 0.6
                p.drawLine(QPointF(0, c.y()), QPointF(c.x() - gap, c.y()))
                p.drawLine(QPointF(c.x() + gap, c.y()), QPointF(self.width(), c.y()))
                p.drawLine(QPointF(c.x(), 0), QPointF(c.x(), c.y() - gap))
                p.drawLine(QPointF(c.x(), c.y() + gap), QPointF(c.x(), self.height()))
            p.setPen(QPen(QColor(255, 255, 0), 1))
            x, y = self.position
            text = f"x {x:.2f}  y {y:.2f}"
            if p.fontMetrics().horizontalAdvance(text) > self.width() - 8:  # a narrow loupe
                text = f"{x:.1f}, {y:.1f}"
            p.drawText(self.rect().adjusted(4, 2, -4, -2),
                       Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignBottom, text)
        if self.label:
            f = p.font()
            f.setBold(True)
            p.setFont(f)
            p.fillRect(QRectF(0, 0, p.fontMetrics().horizontalAdvance(self.label) + 8,
                              p.fontMetrics().height() + 2), QColor(0, 0, 0, 170))
            p.setPen(QPen(QColor(255, 255, 255), 1))
            p.drawText(self.rect().adjusted(4, 1, -4, -2),
                       Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignTop, self.label)
        p.end()
