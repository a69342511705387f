"""Markers: symbols of a constant size on screen at points of a view box (image pixels), and
Scatter, the plots' scatter item with the same lean repaint.

pyqtgraph's ``ScatterPlotItem`` does the same job for plots; in an image view it cost ~0.25 ms
of Python per item at every repaint, however small the repainted area (it maps and masks
every spot each time), and a view repaints a few markers' areas at every click. This item
maps the spots with one numpy product, draws only those in the exposed area from one cached
pixmap per style in one Qt call, and knows its bounding rectangle without asking the view for
every call.
"""
from __future__ import annotations

import math

import numpy as np
import pyqtgraph as pg
from pyqtgraph.graphicsItems.ScatterPlotItem import renderSymbol
from pyqtgraph.Qt import internals
from PySide6.QtCore import QRectF
from PySide6.QtGui import QBrush, QPainter, QPainterPath, QPen, QPixmap

NO_SHAPE = QPainterPath()  # the outline of an item that is no mouse target
_NO_BRUSH = QBrush()
_PIXMAPS: dict = {}  # (symbol, size, pen, brush, device pixel ratio) -> QPixmap


def _pen_key(pen: QPen) -> tuple:
    return pen.color().rgba(), pen.widthF(), int(pen.style().value)


def _pixmap(symbol, size: float, pen: QPen, dpr: float, brush: QBrush | None = None) -> QPixmap:
    """The symbol drawn once with ``pen`` and ``brush`` (None: no fill), centred in a square
    pixmap of ``dpr`` device pixels per pixel."""
    brush = brush if brush is not None else _NO_BRUSH
    key = (symbol if isinstance(symbol, str) else id(symbol), size, _pen_key(pen),
           brush.color().rgba(), int(brush.style().value), dpr)
    pm = _PIXMAPS.get(key)
    if pm is None:
        pm = _PIXMAPS[key] = QPixmap.fromImage(renderSymbol(symbol, size, pen, brush, dpr=dpr))
    return pm


def on_screen(t, x: np.ndarray, y: np.ndarray, area: QRectF):
    """``(dx, dy, inside)``: the positions ``x``, ``y`` (``(n,)``, item coordinates) mapped by
    the painter transform ``t`` to device pixels, and the indices of those in ``area`` (device
    pixels, edges included)."""
    dx = t.m11() * x + t.m21() * y + t.dx()
    dy = t.m12() * x + t.m22() * y + t.dy()
    inside = np.flatnonzero((dx >= area.left()) & (dx <= area.right()) &
                            (dy >= area.top()) & (dy <= area.bottom()))
    return dx, dy, inside


def _draw_centred(p: QPainter, pm: QPixmap, dpr: float, x: np.ndarray, y: np.ndarray,
                  frags=internals.PrimitiveArray(QPainter.PixmapFragment, 10)) -> None:
    """``pm`` centred at each device position ``(x[i], y[i])``, in one call (Qt's pixmap
    fragments, as pyqtgraph's scatter item draws; a call per spot costs ~1.5 µs of Python
    each). The painter's transform must be the identity."""
    frags.resize(len(x))
    a = frags.ndarray()
    a[:, 0], a[:, 1] = x, y
    a[:, 2:6] = (0.0, 0.0, pm.width(), pm.height())       # the whole pixmap (device pixels)
    a[:, 6:10] = (1.0 / dpr, 1.0 / dpr, 0.0, 1.0)          # scale, rotation, opacity
    p.drawPixmapFragments(*frags.drawargs(), pm)


def _paint_spots(p: QPainter, option, x: np.ndarray, y: np.ndarray, pms: list, dpr: float,
                 half: float, which: np.ndarray | None = None) -> None:
    """Spots at item positions ``x``, ``y`` (``(n,)``) in the exposed area of ``option``, each
    the pixmap ``pms[which[i]]`` (``which`` None: ``pms[0]``) centred on it; ``half``: half the
    largest pixmap's side (device-independent px), how far a spot reaches into the area."""
    t = p.transform()
    area = t.mapRect(option.exposedRect).adjusted(-half, -half, half, half)
    dx, dy, inside = on_screen(t, x, y, area)
    if not inside.size:
        return
    p.resetTransform()
    if len(pms) == 1 or which is None:
        _draw_centred(p, pms[0], dpr, dx[inside], dy[inside])
    else:
        chosen = which[inside]
        for k, pm in enumerate(pms):
            sel = inside[chosen == k]
            if sel.size:
                _draw_centred(p, pm, dpr, dx[sel], dy[sel])
    p.setTransform(t)


class Markers(pg.GraphicsObject):
    """Symbols ``symbol`` (a pyqtgraph symbol name or a unit ``QPainterPath``, −0.5..0.5) of
    ``size`` screen pixels at image positions, each drawn with its own pen or ``pen``.

    Not a mouse target (the views pick markers themselves from their positions). Hidden while
    empty, so that a view's repaint skips it.
    """

    def __init__(self, symbol, size: float, pen: QPen | None = None):
        super().__init__()
        self.symbol, self.size = symbol, float(size)
        self.pen = pen if pen is not None else pg.mkPen(200, 200, 200)
        self._xy = np.zeros((0, 2))
        self._pens: list[QPen] = [self.pen]
        self._which = np.zeros(0, int)       # index into _pens per spot
        self._data_rect = QRectF()
        self._pad: tuple | None = None       # half a symbol, image pixels (x, y); None: unknown
        self._drawn: tuple = (None, [], 0.0)  # dpr, pixmap per pen, half the largest side (px)
        self.setFlag(self.GraphicsItemFlag.ItemUsesExtendedStyleOption)  # option.exposedRect
        self.setVisible(False)

    # ------------------------------------------------------------------ data
    def setData(self, pos, pen=None, data=None) -> None:
        """Spots at ``pos`` (``(n, 2)`` image x, y); ``pen``: one pen, a pen per spot or None
        (the item's pen). ``data`` is accepted for pyqtgraph's signature and not kept."""
        xy = np.asarray(pos, float).reshape(-1, 2)
        if pen is None or isinstance(pen, QPen):
            pens, which = [pen or self.pen], np.zeros(len(xy), int)
        else:
            index: dict = {}
            which = np.array([index.setdefault(id(p), len(index)) for p in pen], int)
            pens = [None] * len(index)
            for p in pen:
                pens[index[id(p)]] = p
        self.prepareGeometryChange()
        self._xy, self._pens, self._which = xy, pens, which
        self._drawn = (None, [], 0.0)
        if len(xy):
            lo, hi = np.nanmin(xy, axis=0), np.nanmax(xy, axis=0)
            self._data_rect = QRectF(lo[0], lo[1], hi[0] - lo[0], hi[1] - lo[1])
        else:
            self._data_rect = QRectF()
        self.setVisible(len(xy) > 0)
        self.update()

    def clear(self) -> None:
        """No spot (the item hides; where the spots were is repainted)."""
        self.setData(np.zeros((0, 2)))

    def getData(self) -> tuple[np.ndarray, np.ndarray]:
        """``(x, y)`` of the spots, image pixels."""
        return self._xy[:, 0].copy(), self._xy[:, 1].copy()

    # ------------------------------------------------------------------ geometry
    def viewTransformChanged(self) -> None:  # pyqtgraph: the view moved, zoomed or resized
        self.prepareGeometryChange()
        self._pad = None
        super().viewTransformChanged()

    def boundingRect(self) -> QRectF:
        if not len(self._xy):
            return QRectF()
        if self._pad is None:
            t = self.deviceTransform_()  # (pyqtgraph: None while not in a view)
            half = 0.5 * (self.size + max(math.ceil(max(p.widthF() for p in self._pens)), 1)) + 1.0
            if t is None:
                return QRectF(self._data_rect)
            sx, sy = math.hypot(t.m11(), t.m12()), math.hypot(t.m21(), t.m22())  # screen px per image px
            if sx <= 0 or sy <= 0:
                return QRectF(self._data_rect)
            self._pad = (half / sx, half / sy)
        px, py = self._pad
        return self._data_rect.adjusted(-px, -py, px, py)

    def shape(self) -> QPainterPath:  # not a mouse target
        return NO_SHAPE

    def mouseClickEvent(self, ev) -> None:
        ev.ignore()

    # ------------------------------------------------------------------ drawing
    def paint(self, p, option, *args) -> None:
        if not len(self._xy):
            return
        dpr = p.device().devicePixelRatioF() if p.device() is not None else 1.0
        if self._drawn[0] != dpr:
            pms = [_pixmap(self.symbol, self.size, pen, dpr) for pen in self._pens]
            self._drawn = (dpr, pms, max(pm.width() for pm in pms) / dpr * 0.5)
        _, pms, half = self._drawn
        _paint_spots(p, option, self._xy[:, 0], self._xy[:, 1], pms, dpr, half, self._which)


class Scatter(pg.ScatterPlotItem):
    """pyqtgraph's scatter item for the plots (hover tips, clicks, legend samples kept), with
    one style for all its spots (``symbol``, ``size``, ``pen``, ``brush`` of the item; the
    plots never style a spot of their own) and a cheaper repaint: the spots in the exposed
    area mapped by one product and drawn from one cached pixmap, the bounding rectangle
    remembered while the data and the view are unchanged (pyqtgraph recomputes both on every
    call, ~0.2 ms per repaint and ~45 µs per rectangle)."""

    _br_key = None

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.setFlag(self.GraphicsItemFlag.ItemUsesExtendedStyleOption)  # option.exposedRect

    def boundingRect(self) -> QRectF:
        # pyqtgraph replaces ``self.bounds`` when the data or the view transform change
        key = self._br_key
        if key is None or key[0] is not self.bounds or key[1] != self._maxSpotPxWidth:
            rect = super().boundingRect()
            self._br_key = (self.bounds, self._maxSpotPxWidth, rect)
            return QRectF(rect)
        return QRectF(key[2])

    def paint(self, p, option, widget=None) -> None:
        n = len(self.data)
        if not n:
            return
        o = self.opts
        if self._exportOpts is not False or not o["pxMode"]:
            return super().paint(p, option, widget)
        dpr = widget.devicePixelRatioF() if widget is not None else 1.0
        pm = _pixmap(o["symbol"], o["size"], o["pen"], dpr, o["brush"])  # (QPen, QBrush: pyqtgraph's)
        _paint_spots(p, option, self.data["x"], self.data["y"], [pm], dpr, pm.width() / dpr * 0.5)
