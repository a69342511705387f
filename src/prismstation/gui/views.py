"""The N, F, B views side by side, with overlays, linked cursors and drive-to.

Predicted positions (where a point is not measured) come from
:mod:`prismstation.ops.predict` through :class:`~prismstation.gui.prediction.Predictions`,
each with its 95 % error ellipse; ``navigated`` tells
:class:`~prismstation.gui.linked_nav.LinkedNavigation` of a zoom or pan made by hand.

Views of different images are not linked by pyqtgraph's ``setXLink`` (their geometries differ):
the cursor in one view goes through the current :class:`~prismstation.core.models.solution.Solution`
(pixel → ground at a height → pixel) to the others (docs/architecture.md). The height is that of the
point under the cursor when there is one (its estimated or known height), else the mean scene
height of the solution.

Image coordinates: x = column, y = row, pixels, origin at the top-left corner of the top-left
pixel (docs/model.md §1).
"""
from __future__ import annotations

import weakref

import numpy as np
from PySide6.QtCore import QRect, Qt, Signal
from PySide6.QtGui import QRegion
from PySide6.QtWidgets import QSplitter, QVBoxLayout, QWidget

from prismstation.core.models.ray_dem import ray_meets_surface
from prismstation.core.models.scene import reference_view
from prismstation.errors import PrismError
from prismstation.gui import workers
from prismstation.gui.image_view import ImageView
from prismstation.gui.overlays import ViewOverlay, by_view
from prismstation.gui.prediction import Predictions
from prismstation.gui.text_label import TextLabel
from prismstation.io.raster import RasterSource

VIEW_TITLES = {"N": "N — nadir", "F": "F — forward", "B": "B — backward"}
PICK_TOLERANCE_SCREEN_PX = 8.0
EDIT_REACH = QRect(-40, -40, 160, 80)
"""What a marker drawn at a screen point covers, screen px: its symbol (27 px at most, the
current point's square) and its label (:attr:`.overlays.LabelLayer.REACH`)."""
DRIVE_TO_MAX_SCALE = 1.0  # image px per screen px at most after a drive-to (zooms in to detail)
TILE_CACHE_MB = 32  # read tiles kept per view: 128 tiles, a 5,800 px square at full resolution


def _load(on_loaded, view: str, path: str, generation: int) -> None:
    """Open a raster, read its coarse overview and statistics (worker thread); the handle this
    thread opened is closed here, the GUI thread opens its own."""
    try:
        src = RasterSource(path, cache_mb=TILE_CACHE_MB)
        try:
            src.coarse()
            st = src.statistics((0.5, 99.5))
        finally:
            src.release_thread()
        levels = (st.percentiles[0.5], st.percentiles[99.5])
        workers.post(on_loaded, view, generation, src, levels, "",
                     orphan=src.close)  # the views are gone: let the file go
    except (PrismError, OSError, ValueError) as exc:
        workers.post(on_loaded, view, generation, None, None, str(exc))


class TripletViews(QWidget):
    """Three (or one, two) :class:`ImageView` panes in a splitter with measurement overlays.

    Signals
    -------
    place_requested(view, x, y)
        A click on the image away from other points' markers (or with Shift): place the current
        point there.
    move_requested(pid, view, x, y, finished)
        A marker is being dragged (``finished`` on release).
    point_picked(pid)
        A click on a marker.
    cursor_info(view, x, y, linked, ground)
        The cursor is at ``(x, y)`` in ``view``; ``linked`` maps the other views to ``(x, y)``
        through the model; ``ground`` is ``(E, N, h)`` or None.
    images_loaded()
        Every image of the project is displayed (or failed with a message).
    navigated(view)
        The operator zoomed or panned ``view`` by hand (wheel, drag; not a programmatic move).
    """

    place_requested = Signal(str, float, float)
    move_requested = Signal(str, str, float, float, bool)
    point_picked = Signal(str)
    cursor_info = Signal(str, float, float, object, object)
    images_loaded = Signal()
    navigated = Signal(str)
    message = Signal(str)

    def __init__(self, parent=None):
        super().__init__(parent)
        self.splitter = QSplitter(Qt.Orientation.Horizontal, self)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.splitter)
        self.views: dict[str, ImageView] = {}
        self.overlays: dict[str, ViewOverlay] = {}
        self.headers: dict[str, TextLabel] = {}
        self.panes: dict[str, QWidget] = {}
        self.project = None
        self.solution = None
        self.current: str | None = None
        self.active_view: str | None = None
        self._pending: set[str] = set()
        self._generation = 0
        self._jobs = workers.Jobs("open-image")
        self._sources: list[RasterSource] = []  # opened here: closed here, after their readers
        self.offer_overviews = None  # callable(source) set by the window when interactive
        self.height_of = None  # reference DEM heights: (n, 2) map metres -> (n,) metres
        self.predictions = Predictions()  # of the points in the views they are not measured in
        self._by_view_key, self._by_view_cache = None, {}
        self._drawn: dict = {}  # view -> the inputs its overlay last drew (see _view_inputs)
        self.editable = True  # False (navigate mode): clicks and drags never place nor move
        self.view_cursor = Qt.CursorShape.CrossCursor  # over the images (the measuring mode's)

    # ------------------------------------------------------------------ project and images
    def set_project(self, project) -> None:
        """Build one pane per view of ``project.scene`` and load the images in workers."""
        self._release()
        for pane in self.panes.values():
            pane.setParent(None)
            pane.deleteLater()
        self.views, self.overlays, self.headers, self.panes = {}, {}, {}, {}
        self._drawn = {}
        self.project, self.solution, self.current = project, None, None
        self._generation += 1
        if project is None:
            return
        for name, view in project.scene.views.items():
            pane = QWidget()
            lay = QVBoxLayout(pane)
            lay.setContentsMargins(1, 1, 1, 1)
            lay.setSpacing(0)
            # its text (zoom) never sizes the pane: the views would change width on a zoom
            header = TextLabel(VIEW_TITLES.get(name, name), "N — nadir", background="#2b2f36",
                               color="#e8e8e8", bold=True, stretch=True)
            header.setObjectName("viewHeader")
            iv = ImageView(pane)
            iv.graphics.viewport().setCursor(self.view_cursor)
            lay.addWidget(header)
            lay.addWidget(iv, 1)
            self.splitter.addWidget(pane)
            self.views[name], self.headers[name], self.panes[name] = iv, header, pane
            self.overlays[name] = ViewOverlay(name, iv.vb)
            iv.vb.drag_handler = _MarkerDrag(self, name)
            iv.clicked.connect(lambda x, y, mods, n=name: self._on_clicked(n, x, y, mods))
            iv.cursor_moved.connect(lambda x, y, n=name: self.on_cursor(n, x, y))
            iv.cursor_left.connect(self.hide_crosshairs)
            iv.view_changed.connect(lambda n=name: self._on_view_changed(n))
            iv.read_failed.connect(lambda m, n=name: self.message.emit(f"view {n}: {m}"))
            iv.vb.sigRangeChangedManually.connect(lambda *_, n=name: self.navigated.emit(n))
        self.splitter.setSizes([1000] * len(self.views))
        self._pending = set()
        for name, view in project.scene.views.items():
            if view.image:
                self._pending.add(name)
                self._jobs.start(_load, self._on_loaded, name, view.image, self._generation)
            else:
                self.headers[name].setText(f"{VIEW_TITLES.get(name, name)} — no image")
        self.refresh_measured()
        if not self._pending:
            self.images_loaded.emit()

    def _release(self) -> None:
        """Join the tile readers of the images shown, then close the files. (A load still
        running reads a file of its own: its result is dropped by generation, and closed.)"""
        for v in self.views.values():
            v.shutdown()
            v.set_source(None)
        for src in self._sources:
            src.close()
        self._sources = []

    def _on_loaded(self, name, generation, src, levels, error) -> None:
        if generation != self._generation or name not in self.views:
            if src is not None:
                src.close()
            return
        self._pending.discard(name)
        if src is None:
            self.headers[name].setText(f"{VIEW_TITLES.get(name, name)} — image not readable")
            self.message.emit(f"view {name}: {error}")
        else:
            self._sources.append(src)
            if self.offer_overviews is not None:
                self.offer_overviews(src)
            self.views[name].set_source(src, levels)
            self._update_header(name)
        if not self._pending:
            self.images_loaded.emit()

    def loading(self) -> bool:
        return bool(self._pending)

    def wait_loaded(self, timeout_ms: int = 10000) -> bool:
        """Process events until every image is displayed (scripts and tests)."""
        from PySide6.QtCore import QCoreApplication, QElapsedTimer
        t = QElapsedTimer()
        t.start()
        while self._pending and t.elapsed() < timeout_ms:
            QCoreApplication.processEvents()
            self._jobs.wait(0.01)
        QCoreApplication.processEvents()
        return not self._pending

    def _on_view_changed(self, name: str) -> None:
        iv, ov = self.views.get(name), self.overlays.get(name)
        if iv is not None and ov is not None:
            ov.set_scale(iv.scale())
        self._update_header(name)

    def _update_header(self, name: str) -> None:
        iv = self.views.get(name)
        if iv is None or iv.source is None:
            return
        zoom = 1.0 / iv.scale() if iv.scale() > 0 else 0.0
        # the zoom first: a narrow pane elides the file name, not the figure that changes
        self.headers[name].setText(f"{VIEW_TITLES.get(name, name)}  ·  zoom {zoom:.3g}×  ·  "
                                   f"{iv.source.width} × {iv.source.height} px  ·  {iv.source.path.name}")

    # ------------------------------------------------------------------ overlays
    def refresh_measured(self) -> None:
        """Redraw the measured markers from the project (no fit needed)."""
        if self.project is None:
            return
        mine = self._by_view()
        for ov in self.overlays.values():
            ov.update_measured(self.project, self.solution, self.current, mine.get(ov.name, ((), ())))
        self._update_current()

    def paint_edit(self, view: str, positions) -> None:
        """The first frame of an edit made in ``view`` by a click or a drag: markers, labels and
        the current point redrawn from the project, and painted now around image ``positions``
        (where the marker was and is) — with whatever else of the window waits to be painted
        (the table's row, the loupe). The refit and what it changes follow in later frames."""
        self.refresh_measured()
        iv = self.views.get(view)
        if iv is None or not iv.isVisible():
            return
        region = QRegion()
        for x, y in positions:
            c = iv.map_to_viewport(x, y).toPoint()
            region += EDIT_REACH.translated(c)
        iv.graphics.viewport().repaint(region)

    def _by_view(self) -> dict:
        """The project's measurements and kinds per view (once per revision)."""
        key = (id(self.project), self.project.revision)
        if key != self._by_view_key:
            self._by_view_key, self._by_view_cache = key, by_view(self.project)
        return self._by_view_cache

    def set_solution(self, solution) -> None:
        self.solution = solution
        if self.project is None:
            return
        preds = self.predictions.update(self.project, solution, self.height_of)
        mine = self._by_view()
        for name, ov in self.overlays.items():
            ov.update_measured(self.project, solution, self.current, mine.get(name, ((), ())))
            key = self._view_inputs(name, solution, preds)
            if key is None or key != self._drawn.get(name):
                ov.update_solution(self.project, solution, preds)
                self._drawn[name] = key
        self._update_current()

    def _view_inputs(self, name, solution, preds):
        """What view ``name`` draws from the solution depends on, or None (always redraw):
        its measurements and their kinds, its bias (the residuals of its known points), the
        known ground, the predictions in it and the labels' switch. A click in N changes none
        of F's or B's when every point there is measured: their overlays are left alone."""
        fit = solution.bias.get(name) if solution is not None else None
        ov = self.overlays[name]
        if fit is None or ov._measured_key is None:
            return None
        predicted = tuple((pid, p.xy, p.cov.tobytes()) for pid, d in preds.items()
                          for v, p in d.items() if v == name)
        return (id(ov._measured_key), fit.model, np.asarray(fit.params).tobytes(),
                id(self.predictions._ground), predicted, ov.show_labels, id(self.project))

    def set_height_of(self, height_of) -> None:
        """The reference DEM's heights (None: none): predictions are made again with them."""
        self.height_of = height_of
        if self.solution is not None:
            self.set_solution(self.solution)

    def set_exaggeration(self, k: float) -> None:
        for ov in self.overlays.values():
            ov.exaggeration = float(k)
            ov._draw_vectors()

    def set_show_labels(self, on: bool) -> None:
        for ov in self.overlays.values():
            ov.show_labels = bool(on)
        self.set_solution(self.solution)

    def set_current(self, pid: str | None) -> None:
        self.current = pid
        if self.project is not None:
            mine = self._by_view()
            for ov in self.overlays.values():
                ov.update_measured(self.project, self.solution, pid, mine.get(ov.name, ((), ())))
        self._update_current()

    def _update_current(self) -> None:
        for name, ov in self.overlays.items():
            ov.set_current(None if self.current is None else self.point_position(self.current, name))

    def point_position(self, pid: str, view: str):
        """Image ``(x, y)`` of ``pid`` in ``view``: measured, else predicted (from the best
        ground available, :mod:`prismstation.ops.predict`), else the solution's, else None."""
        if self.project is None:
            return None
        m = self.project.measurement(pid, view)
        if m is not None:
            return (m.x, m.y)
        p = self.predictions.get(pid, view)
        if p is not None:
            return p.xy
        r = self.solution.point(pid) if self.solution is not None else None
        if r is not None and view in r.predicted and np.all(np.isfinite(r.predicted[view])):
            return tuple(r.predicted[view])
        return None

    # ------------------------------------------------------------------ navigation
    def drive_to(self, pid: str, scale: float | None = None) -> None:
        """Centre every view on ``pid`` (measured or predicted position) at one common scale."""
        if not self.views:
            return
        if scale is None:
            ref = self.views[reference_view(self.views)]
            scale = min(ref.scale(), DRIVE_TO_MAX_SCALE)
        for name, iv in self.views.items():
            xy = self.point_position(pid, name)
            if xy is not None:
                iv.center_on(xy[0], xy[1], scale)
            else:
                iv.set_scale(scale)

    def fit_all(self) -> None:
        for iv in self.views.values():
            iv.fit()

    def zoom_all(self, factor: float) -> None:
        for iv in self.views.values():
            iv.zoom(factor)

    # ------------------------------------------------------------------ mouse
    def _on_clicked(self, name, x, y, mods) -> None:
        self.active_view = name
        iv = self.views[name]
        if not (mods & Qt.KeyboardModifier.ShiftModifier):
            pid = self.overlays[name].nearest(x, y, PICK_TOLERANCE_SCREEN_PX * iv.scale())
            if pid is not None and pid != self.current:  # near the current point: re-place it
                self.point_picked.emit(str(pid))
                return
        if self.editable:
            self.place_requested.emit(name, x, y)

    def cursor_height(self, name: str, x: float, y: float) -> float | None:
        """Height for the linked cursor: that of the point under the cursor, else that of the
        current point (the one being measured), else None (the reference DEM or the mean)."""
        sol = self.solution
        if sol is None:
            return None
        iv = self.views[name]
        pid = self.overlays[name].nearest(x, y, PICK_TOLERANCE_SCREEN_PX * iv.scale())
        for p in (pid, self.current):
            r = sol.point(str(p)) if p is not None else None
            if r is not None and r.ground_est is not None and np.isfinite(r.ground_est[2]):
                return float(r.ground_est[2])
        return None

    def ground_height(self, name: str, xy) -> float:
        """Height (m) of the ground under image ``xy`` of ``name``: the reference DEM's where it
        has one (the ray meets it: fixed point), else the solution's mean height."""
        sol = self.solution
        h = float(sol.mean_height)
        if self.height_of is not None:
            xy = np.asarray(xy, float)
            hit = ray_meets_surface(lambda hh: sol.image_to_ground(name, xy, hh[0])[None],
                                    lambda en: np.asarray(self.height_of(en), float), h)
            h = float(hit.h[0]) if hit else h
        return h

    def linked(self, name: str, x: float, y: float, h: float | None = None):
        """``(positions, ground)``: where image ``(x, y)`` of ``name`` falls in the other views
        at height ``h`` (default: :meth:`cursor_height`, else the reference DEM under the cursor,
        else the mean scene height), and its ground ``(E, N, h)``."""
        sol = self.solution
        if sol is None:
            return {}, None
        h = self.cursor_height(name, x, y) if h is None else h
        xy = np.array([x, y], float)
        try:
            if h is None:
                h = self.ground_height(name, xy)
            en = sol.image_to_ground(name, xy, h)
            out = {v: tuple(map(float, sol.ground_to_image(v, en, h))) for v in self.views if v != name}
        except (PrismError, ValueError, np.linalg.LinAlgError):
            return {}, None
        return out, (float(en[0]), float(en[1]), float(h))

    def on_cursor(self, name: str, x: float, y: float) -> None:
        """The cursor moved to ``(x, y)`` in ``name``: crosshairs in the other views, info out."""
        self.active_view = name
        positions, ground = self.linked(name, x, y)
        for v, ov in self.overlays.items():
            ov.set_crosshair(positions.get(v) if v != name else None)
        self.cursor_info.emit(name, x, y, positions, ground)

    def hide_crosshairs(self) -> None:
        """The mouse left a view: no linked cursor in the others."""
        for ov in self.overlays.values():
            ov.set_crosshair(None)

    def shutdown(self) -> None:
        """End every job reading the images and close them (the window is closing)."""
        self._jobs.close()
        self._generation += 1  # loads delivered from now on are closed unseen
        self._release()


class _MarkerDrag:
    """The drag handler of one view's box: a left drag that starts on a measured marker moves
    it (keeping the grab offset); any other drag pans. Picking uses the marker positions, not
    the items' bounding boxes, so it is exact at every zoom. Holds the views weakly."""

    def __init__(self, views: TripletViews, name: str):
        self.views_ref, self.name = weakref.ref(views), name
        self.pid, self.offset = None, (0.0, 0.0)

    def __call__(self, ev) -> bool:
        views, name = self.views_ref(), self.name
        if (views is None or name not in views.views or ev.button() != Qt.MouseButton.LeftButton
                or not views.editable):
            return False
        vb = views.views[name].vb
        if ev.isStart():
            p = vb.mapSceneToView(ev.buttonDownScenePos())
            scale = views.views[name].scale()
            pid = views.overlays[name].nearest(p.x(), p.y(), PICK_TOLERANCE_SCREEN_PX * scale)
            self.pid = None if pid is None else str(pid)
            if pid is not None:
                m = views.project.measurement(str(pid), name)
                self.offset = (m.x - p.x(), m.y - p.y())
        if self.pid is None:
            return False
        ev.accept()
        p = vb.mapSceneToView(ev.scenePos())
        views.active_view = name
        views.move_requested.emit(self.pid, name, p.x() + self.offset[0], p.y() + self.offset[1],
                                  bool(ev.isFinish()))
        if ev.isFinish():
            self.pid = None
        return True
