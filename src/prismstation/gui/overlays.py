"""What is drawn over one image: measured markers, predicted positions with their 95 % error
ellipses, residual vectors, labels, the current point and the linked-cursor crosshair.

All items live in the view box of an :class:`~prismstation.gui.image_view.ImageView`, in image
pixels (x = column, y = row, origin at the top-left corner of the top-left pixel). Markers keep
their size on screen (:mod:`~prismstation.gui.markers`). Updates are incremental where it matters: labels are
created once per point and only moved, so a click repaints in a few milliseconds.
"""
from __future__ import annotations

import math
from operator import attrgetter

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QPointF, QRectF, Qt
from PySide6.QtGui import QColor, QFont, QFontMetricsF, QPainterPath, QPen, QStaticText, QTransform

from prismstation.core.models.results import rows_array
from prismstation.gui.markers import NO_SHAPE, Markers, on_screen
from prismstation.gui.palette import BLUNDER_RGB, CURRENT_RGB, CURSOR_RGB, KIND_RGB, qcolor
from prismstation.ops.predict import CHI2_95_2D

KIND_COLORS = {k: qcolor(k) for k in KIND_RGB}  # one colour per kind: gui/palette.py
BLUNDER_COLOR, CURRENT_COLOR, CURSOR_COLOR = (qcolor(c) for c in (BLUNDER_RGB, CURRENT_RGB, CURSOR_RGB))


def _cross(gap: float = 0.18) -> QPainterPath:
    """A cross with an open centre (unit symbol, -0.5..0.5) that leaves the point visible."""
    p = QPainterPath()
    for a, b in (((-0.5, 0), (-gap, 0)), ((gap, 0), (0.5, 0)), ((0, -0.5), (0, -gap)), ((0, gap), (0, 0.5))):
        p.moveTo(*a)
        p.lineTo(*b)
    return p


MEASURED_SYMBOL = _cross()
CROSSHAIR_SYMBOL = _cross(0.08)
_PENS: dict = {}


def _pen(color: QColor, width: float = 2.0, dashed: bool = False):
    """One shared pen per style: pyqtgraph's symbol atlas then renders each symbol once."""
    key = (color.rgba(), width, dashed)
    pen = _PENS.get(key)
    if pen is None:
        pen = _PENS[key] = pg.mkPen(color, width=width,
                                    style=Qt.PenStyle.DashLine if dashed else Qt.PenStyle.SolidLine)
    return pen


class Curve(pg.PlotCurveItem):
    """A line item that is not a mouse target: the views pick markers themselves, and Qt's
    search of the items under a click asked this curve for its outline, which pyqtgraph strokes
    anew whenever the data changed (the residual vectors: at every click)."""

    def shape(self) -> QPainterPath:
        return NO_SHAPE

    def mouseClickEvent(self, ev) -> None:
        ev.ignore()


class LabelLayer(pg.GraphicsObject):
    """All point labels of a view in one item, drawn in screen pixels beside their points.

    One item with one ``paint`` instead of a ``TextItem`` per point: those recompute their
    transforms at every view change, which costs far more than drawing a few hundred strings.
    Positions are mapped to the screen at once (numpy) and only the labels in the exposed
    rectangle are drawn, so repainting one marker does not redraw every label.
    """

    OFFSET = QPointF(9.0, -7.0)
    REACH = QRectF(-20.0, -20.0, 100.0, 40.0)  # where a label can reach from its point, screen px

    def __init__(self):
        super().__init__()
        self.labels: list = []  # (x, y, text, QColor)
        self._xy = np.zeros((0, 2))
        self.font = QFont()
        self.font.setPointSizeF(8.5)
        self.font.setBold(True)
        self._ascent = QFontMetricsF(self.font).ascent()
        self._static: dict = {}  # text -> QStaticText
        self.setFlag(self.GraphicsItemFlag.ItemUsesExtendedStyleOption)  # option.exposedRect

    def set_labels(self, labels) -> None:
        self.labels = list(labels)
        self._xy = rows_array([(x, y) for x, y, _, _ in self.labels], 2)
        self.update()

    def shape(self) -> QPainterPath:  # not a mouse target
        return NO_SHAPE

    def boundingRect(self) -> QRectF:
        """The visible area of the view (image pixels): labels extend in screen pixels from
        points anywhere, and whatever is seen lies in it. Not "everywhere": Qt maps the rect of
        an update to the screen in integers, and a rect of ±1e9 image pixels overflowed them
        when zoomed in past ~2×, so a label's own repaint was dropped (an undone label stayed
        on screen, a new one showed where other items happened to repaint)."""
        return QRectF(self._view_rect)

    _view_rect = QRectF()

    def viewRangeChanged(self) -> None:  # pyqtgraph: the view box moved or zoomed
        vb = self.getViewBox()
        rect = vb.viewRect() if vb is not None else QRectF()
        if rect != self._view_rect:
            self.prepareGeometryChange()
            self._view_rect = QRectF(rect)
        super().viewRangeChanged()

    def paint(self, p, option, *args) -> None:
        if not self.labels:
            return
        t = p.transform()
        area = t.mapRect(option.exposedRect).intersected(QRectF(p.viewport()))
        area = area.adjusted(-self.REACH.right(), -self.REACH.bottom(), -self.REACH.left(), -self.REACH.top())
        dx, dy, inside = on_screen(t, self._xy[:, 0], self._xy[:, 1], area)
        if not inside.size:
            return
        p.resetTransform()
        p.setFont(self.font)
        shadow = QPen(QColor(0, 0, 0, 200))
        ox, oy = self.OFFSET.x(), self.OFFSET.y() - self._ascent  # static text: top-left origin
        for i in inside:
            _, _, text, color = self.labels[i]
            st = self._static.get(text)
            if st is None:  # laid out once, drawn many times
                st = self._static[text] = QStaticText(text)
                st.setTextFormat(Qt.TextFormat.PlainText)  # an id is never markup
                st.prepare(QTransform(), self.font)
            px, py = dx[i] + ox, dy[i] + oy
            p.setPen(shadow)
            p.drawStaticText(QPointF(px + 1, py + 1), st)
            p.setPen(color)
            p.drawStaticText(QPointF(px, py), st)
        p.setTransform(t)


def by_view(project) -> dict:
    """``{view: (measurements, kinds)}`` (tuples, in the project's order) of ``project``."""
    ms: dict = {}
    for (_, v), m in project.measurements.items():
        ms.setdefault(v, []).append(m)
    kind_of = {pid: p.kind for pid, p in project.points.items()}
    return {v: (tuple(lst), tuple(map(kind_of.__getitem__, map(_ID, lst)))) for v, lst in ms.items()}


_ID = attrgetter("id")


def ellipse_polylines(preds, n: int = 40) -> np.ndarray:
    """``(len(preds) · (n + 2), 2)``: the closed 95 % ellipse of each prediction (image pixels),
    a NaN row after each (vectorised over predictions)."""
    xy = np.array([p.xy for p in preds], float)
    cov = np.array([p.cov for p in preds], float)
    w, v = np.linalg.eigh(cov)                                # (m, 2), (m, 2, 2)
    axes = v * np.sqrt(CHI2_95_2D * np.clip(w, 0.0, None))[:, None, :]
    t = np.linspace(0.0, 2 * np.pi, n + 1)
    unit = np.stack([np.cos(t), np.sin(t)])                   # (2, n + 1)
    pts = xy[:, :, None] + axes @ unit                        # (m, 2, n + 1)
    out = np.full((len(preds), n + 2, 2), np.nan)
    out[:, :n + 1] = pts.transpose(0, 2, 1)
    return out.reshape(-1, 2)


class ViewOverlay:
    """The overlay items of one view (``name``) in view box ``vb``."""

    def __init__(self, name: str, vb: pg.ViewBox):
        self.name = name
        self.vb = vb
        self.exaggeration = 40.0  # screen pixels per pixel of residual, at every zoom
        self.scale = 1.0          # image pixels per screen pixel of the view
        self._residuals = np.zeros((0, 4))  # x, y, vx, vy (image pixels)
        self.show_labels = True
        self.measured = Markers(MEASURED_SYMBOL, 19)
        # the current point's marker in an item of its own: a click moves that point, and
        # re-setting one spot costs nothing where re-setting hundreds (each with its pen) cost
        # milliseconds at every click
        self.measured_current = Markers(MEASURED_SYMBOL, 19)
        # blunders drawn over their markers by an item of their own: a point that becomes (or
        # stops being) a blunder repaints its marker, not the whole view
        self.blunders = Markers(MEASURED_SYMBOL, 19, _pen(BLUNDER_COLOR))
        self.predicted = Markers("o", 15)
        self.current = Markers("s", 27, pg.mkPen(CURRENT_COLOR, width=1.5))
        self.vectors = Curve(connect="pairs", pen=pg.mkPen(255, 120, 0, width=2))
        # one curve per kind: the ellipses of its predictions, separated by NaN
        self.ellipses = {k: Curve(connect="finite", pen=_pen(c, 1.2, True))
                         for k, c in KIND_COLORS.items()}
        for item in self.ellipses.values():
            item.setZValue(20.5)
            vb.addItem(item, ignoreBounds=True)
        self._ellipse_key = None
        self.crosshair = Markers(CROSSHAIR_SYMBOL, 46, pg.mkPen(CURSOR_COLOR, width=1.5))
        for z, item in ((20, self.vectors), (21, self.predicted), (22, self.measured),
                        (22.2, self.measured_current), (22.5, self.blunders), (23, self.current),
                        (30, self.crosshair)):
            item.setZValue(z)
            vb.addItem(item, ignoreBounds=True)  # overlays never move the view's range
        self.crosshair.setVisible(False)
        self.labels = LabelLayer()
        self.labels.setZValue(24)
        vb.addItem(self.labels, ignoreBounds=True)
        self._label_state = None
        self._predicted_labels: dict = {}  # id -> (x, y) of the predictions drawn (unmeasured here)
        self.ids = np.zeros(0, dtype=object)      # ids of measured markers, in order
        self.xy = np.zeros((0, 2))                 # their image positions
        self._measured_key = None
        self._others_key = None
        self._current_key = None
        self._split = None
        self._measured_state = None
        self._vectors_key = None
        self._current_xy = None
        self._blunder_xy = ()
        self._predicted_key = None

    # ------------------------------------------------------------------ measured (project)
    def update_measured(self, project, solution=None, current=None, mine=None) -> None:
        """Markers at the project's measurements in this view (immediately, without the fit);
        the ``current`` point's in an item of its own. ``mine``: ``(measurements, kinds)`` of
        this view, when the caller has them (:func:`by_view`)."""
        state = (id(project), project.revision, current)
        if state != self._measured_state:  # the project or the current point changed
            self._measured_state = state
            ms, kinds = mine if mine is not None else by_view(project).get(self.name, ((), ()))
            key = (ms, kinds)  # measurements are frozen: equal means unchanged
            if key != self._measured_key or current != self._split:  # (else: another view's edit)
                if key != self._measured_key:
                    self._measured_key = key
                    self.ids = np.array([m.id for m in ms], dtype=object)
                    self.xy = rows_array([(m.x, m.y) for m in ms], 2)
                self._split = current
                ids = list(map(_ID, ms))
                i = ids.index(current) if current in ids else None  # (one measurement per view)
                split = (((ms, kinds), ((), ())) if i is None else
                         ((ms[:i] + ms[i + 1:], kinds[:i] + kinds[i + 1:]), (ms[i:i + 1], kinds[i:i + 1])))
                for item, sel, attr in ((self.measured, split[0], "_others_key"),
                                        (self.measured_current, split[1], "_current_key")):
                    if sel != getattr(self, attr):  # (tuples of the same objects: quick)
                        setattr(self, attr, sel)
                        if sel[0]:
                            item.setData(pos=[(m.x, m.y) for m in sel[0]], data=[m.id for m in sel[0]],
                                         pen=[_pen(KIND_COLORS.get(k, CURRENT_COLOR)) for k in sel[1]])
                        else:
                            item.clear()
                self._update_labels(project)  # a new point's label comes with its marker
        flagged = set(solution.columns.blunder_ids()) if solution is not None else set()
        xy = ()
        if flagged and len(self.ids):
            xy = tuple(map(tuple, self.xy[np.isin(self.ids, list(flagged))].tolist()))
        if xy != self._blunder_xy:
            self._blunder_xy = xy
            self.blunders.setData(pos=list(xy)) if xy else self.blunders.clear()

    # ------------------------------------------------------------------ from the solution
    def update_solution(self, project, solution, predictions=None) -> None:
        """Predicted positions (hollow, unmeasured views) with their error ellipses, residual
        vectors, labels. ``predictions``: ``{id: {view: Prediction}}``
        (:mod:`prismstation.ops.predict`); None: the solution's own predicted positions."""
        v, points = self.name, project.points
        pred, pred_pens = [], []
        polys: dict = {k: [] for k in self.ellipses}
        label_pos = {}
        residuals = np.zeros((0, 4))
        if solution is not None:
            c = solution.columns
            n = len(c)
            nan2 = np.full((n, 2), np.nan)
            meas, res = c.measured.get(v, nan2), c.residual.get(v, nan2)
            known = np.fromiter((pid in points for pid in c.ids), bool, n)
            measured = np.isfinite(meas[:, 0]) & np.isfinite(meas[:, 1])
            drawn = known & measured & np.isfinite(res[:, 0]) & np.isfinite(res[:, 1])
            residuals = np.column_stack([meas[drawn], res[drawn]])
            own = c.predicted.get(v, nan2)
            for i in np.flatnonzero(known & ~measured).tolist():  # (a few: the unmeasured)
                pid = c.ids[i]
                p = None if predictions is None else predictions.get(pid, {}).get(v)
                xy = tuple(own[i].tolist()) if predictions is None else (None if p is None else p.xy)
                if xy is not None and math.isfinite(xy[0]) and math.isfinite(xy[1]) and \
                        project.measurement(pid, v) is None:
                    kind = points[pid].kind
                    pred.append(xy)
                    pred_pens.append(_pen(KIND_COLORS.get(kind, CURRENT_COLOR), 1.5, True))
                    label_pos[pid] = xy
                    if p is not None and kind in polys and np.all(np.isfinite(p.cov)):
                        polys[kind].append(p)
        key = (tuple(pred), tuple(id(p) for p in pred_pens))
        if key != self._predicted_key:
            self._predicted_key = key
            if pred:
                self.predicted.setData(pos=np.array(pred), pen=pred_pens)
            else:
                self.predicted.clear()
        self._draw_ellipses(polys)
        self._residuals = residuals
        self._draw_vectors()
        self._predicted_labels = label_pos
        self._update_labels(project)

    def _draw_ellipses(self, preds: dict) -> None:
        """The 95 % ellipses of ``preds`` (kind → [Prediction]), as closed polylines."""
        key = tuple((k, tuple((p.xy, p.cov.tobytes()) for p in v)) for k, v in preds.items())
        if key == self._ellipse_key:
            return
        self._ellipse_key = key
        for k, item in self.ellipses.items():
            if preds[k]:
                xy = ellipse_polylines(preds[k])
                item.setData(xy[:, 0], xy[:, 1], connect="finite")
            else:
                item.setData([], [])

    def ellipse_points(self) -> np.ndarray:
        """``(n, 2)`` image points of every ellipse drawn (NaN rows between them; tests)."""
        parts = []
        for item in self.ellipses.values():
            x, y = item.getData()
            if x is not None and len(x):
                parts.append(np.column_stack([x, y]))
        return np.vstack(parts) if parts else np.zeros((0, 2))

    def set_scale(self, scale: float) -> None:
        """The view's zoom changed (image px per screen px): vectors keep their screen length."""
        if scale > 0 and abs(scale - self.scale) > 1e-9 * scale:
            self.scale = float(scale)
            self._draw_vectors()

    def _draw_vectors(self) -> None:
        r = self._residuals
        k = self.exaggeration * self.scale  # image pixels drawn per pixel of residual
        seg = np.empty((2 * len(r), 2))
        seg[0::2] = r[:, :2]
        seg[1::2] = r[:, :2] + k * r[:, 2:]
        key = seg.tobytes()
        if key != self._vectors_key:  # unchanged (this view's fit did not move): no repaint
            self._vectors_key = key
            self.vectors.setData(seg[:, 0], seg[:, 1], connect="pairs")

    def vector_ends(self) -> np.ndarray:
        """``(n, 4)``: start and end of each residual vector drawn, image pixels (tests)."""
        x, y = self.vectors.getData()
        if x is None or len(x) == 0:
            return np.zeros((0, 4))
        return np.column_stack([x[0::2], y[0::2], x[1::2], y[1::2]])

    def _update_labels(self, project) -> None:
        """A label beside each measured marker (at once, from the project) and each prediction
        of the last solution."""
        state = None
        if self.show_labels:
            points = project.points
            label_pos = dict(zip(self.ids.tolist(), map(tuple, self.xy.tolist())))
            for pid, xy in self._predicted_labels.items():
                if pid in points:
                    label_pos.setdefault(pid, xy)
            state = [(x, y, pid, KIND_COLORS.get(points[pid].kind, CURRENT_COLOR))
                     for pid, (x, y) in label_pos.items()]
        if state == self._label_state:
            return
        self._label_state = state
        self.labels.set_labels(state or [])

    def label_texts(self) -> dict:
        """``{id: (x, y)}`` of the labels drawn (tests)."""
        return {t: (x, y) for x, y, t, _ in self.labels.labels}

    def set_current(self, xy) -> None:
        """Highlight the current point at image ``(x, y)`` (None: nothing)."""
        xy = None if xy is None else tuple(map(float, xy))
        if xy == self._current_xy:
            return
        self._current_xy = xy
        if xy is None:
            self.current.clear()
        else:
            self.current.setData(pos=[xy])

    def set_crosshair(self, xy) -> None:
        """The linked-cursor crosshair at image ``(x, y)`` (None hides it)."""
        if xy is None or not np.all(np.isfinite(xy)):
            self.crosshair.setVisible(False)
            return
        self.crosshair.setData(pos=[tuple(map(float, xy))])
        self.crosshair.setVisible(True)

    def nearest(self, x: float, y: float, tolerance: float):
        """Id of the measured marker nearest image ``(x, y)`` within ``tolerance`` pixels, or None."""
        if len(self.xy) == 0:
            return None
        d = np.hypot(self.xy[:, 0] - x, self.xy[:, 1] - y)
        i = int(np.argmin(d))
        return self.ids[i] if d[i] <= tolerance else None
