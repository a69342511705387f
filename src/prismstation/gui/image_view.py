"""ImageView: a pyqtgraph view of a whole (large) image, panned and zoomed without full reads.

What is drawn: an always-present coarse overview of the whole image (one read of about 1000 px),
and on top of it the tiles of the overview level matching the current zoom for the visible area.
Tiles are read by a :class:`~prismstation.gui.tiles.TileLoader` in worker threads and delivered to
the GUI thread (:func:`~prismstation.gui.workers.post`); requests are dropped when the view has moved on; tiles come from the
source's LRU cache when they are there.

Coordinates (docs/model.md §1): scene coordinates of the view box are image pixels, x = column to the
right, y = row down (the y axis is inverted), origin at the top-left corner of the top-left pixel;
the centre of pixel (i, j) is (i + 0.5, j + 0.5).
"""
from __future__ import annotations

import time

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QEvent, QPointF, QRectF, Qt, QTimer, Signal
from PySide6.QtWidgets import QGraphicsItem, QVBoxLayout, QWidget

from prismstation.gui.tiles import COARSE_KEY, TileLoader, tiles_for_rect
from prismstation.io.raster import RasterSource

_COARSE_Z = -100
TILE_BUDGET_S = 0.004
"""GUI-thread time per event-loop turn spent turning delivered tiles into images (seconds)."""


def _image_item(arr: np.ndarray, rect_xywh, levels, z: float) -> pg.ImageItem:
    item = pg.ImageItem(axisOrder="row-major")
    item.setImage(arr, autoLevels=False, levels=levels)
    item.setRect(QRectF(*rect_xywh))
    item.setZValue(z)
    # kept as a pixmap at screen resolution: a marker or a vector redrawn over the image (every
    # click) blits it instead of resampling the tile (a view repaint 1.6 → 0.9 ms)
    item.setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)
    return item


class ImageViewBox(pg.ViewBox):
    """The view box of an :class:`ImageView`: image pixels, y down, fixed aspect, no menu.

    ``drag_handler(ev) -> bool``, when set, sees every mouse drag first; True means it took the
    drag (a marker being moved), otherwise the box pans.
    """

    def __init__(self):
        super().__init__(lockAspect=True, invertY=True, enableMenu=False, defaultPadding=0.0)
        self.drag_handler = None

    def mouseDragEvent(self, ev, axis=None):
        if self.drag_handler is not None and self.drag_handler(ev):
            return
        super().mouseDragEvent(ev, axis=axis)


class ImageView(QWidget):
    """A view of one :class:`RasterSource` (band 1, grey).

    The widget holds a ``pg.GraphicsView`` (``self.graphics``) whose central item is a
    ``pg.ViewBox`` (``self.vb``) in image coordinates: overlays (markers, vectors) are added to
    ``self.vb`` in image pixels. Left-drag pans, the wheel zooms.

    Signals
    -------
    cursor_moved(x, y)
        Image coordinates (pixels, continuous) under the mouse; may lie outside the image.
    cursor_left()
        The mouse has left the view.
    clicked(x, y, modifiers)
        Left click (not a drag) at image coordinates; ``modifiers`` is a Qt.KeyboardModifier.
    view_changed()
        The visible rectangle changed (pan, zoom, resize).
    levels_changed(lo, hi)
        The display levels changed (data units).
    tiles_settled()
        Every tile wanted for the current view is displayed.
    source_changed()
        A new source (or None) was set; geometry is known, levels may follow.
    source_ready()
        The coarse overview of the new source is shown; levels and statistics are known.
    read_failed(message)
        A tile (or the coarse overview) could not be read; the message names the file. The
        view keeps showing what it has.
    """

    sync_coarse_pixels = 40_000_000
    """Files without overviews larger than this (pixels) get their coarse read in a worker."""

    prefetch_margin = 0.5
    """Tiles within this fraction of the view size around it are read ahead into the cache."""

    cursor_moved = Signal(float, float)
    cursor_left = Signal()
    clicked = Signal(float, float, object)
    view_changed = Signal()
    levels_changed = Signal(float, float)
    tiles_settled = Signal()
    source_changed = Signal()
    source_ready = Signal()
    read_failed = Signal(str)

    def __init__(self, parent=None, threads: int = 2):
        super().__init__(parent)
        self.graphics = pg.GraphicsView(self, background="k")
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.graphics)
        self.vb = ImageViewBox()
        self.graphics.setCentralItem(self.vb)
        self.source: RasterSource | None = None
        self.loader: TileLoader | None = None
        self._threads = threads
        self._coarse_item: pg.ImageItem | None = None
        self._tiles: dict = {}  # key -> ImageItem
        self._wanted: list = []
        self._level = 0
        self._levels = (0.0, 255.0)
        self.display_filter = None  # optional callable(array) -> array for overview and tiles
        self._update_timer = QTimer(self)
        self._update_timer.setSingleShot(True)
        self._update_timer.setInterval(0)
        self._update_timer.timeout.connect(self._update_tiles)
        self._arrived: list = []  # (key, array) delivered, not yet shown
        self._unsettled = False  # a tile was shown since the last settle
        self._drain_timer = QTimer(self)
        self._drain_timer.setSingleShot(True)
        self._drain_timer.setInterval(0)
        self._drain_timer.timeout.connect(self._drain_arrived)
        self.vb.sigRangeChanged.connect(self._on_range_changed)
        scene = self.graphics.scene()
        scene.sigMouseMoved.connect(self._on_mouse_moved)
        scene.sigMouseClicked.connect(self._on_mouse_clicked)
        # no item of a view takes clicks or hovers (markers are picked by the views, the box
        # pans on drags): pyqtgraph's two searches of the items near the cursor at every click
        # (~1 ms with a few hundred markers) are skipped
        scene.sendClickEvent = lambda ev: (scene.sigMouseClicked.emit(ev), ev.isAccepted())[1]
        scene.sendHoverEvents = lambda ev, exitOnly=False: None
        self.graphics.viewport().installEventFilter(self)  # (its Leave: cursor_left)

    # ------------------------------------------------------------------ source
    def set_source(self, source: RasterSource | None, levels=None) -> None:
        """Show ``source`` whole (fit), with ``levels`` or the 0.5–99.5 percentile stretch.

        Reads only the coarse overview (about 1000 px) on the GUI thread, and only when the file
        has overviews or is small (:attr:`sync_coarse_pixels`); otherwise that read, which GDAL
        must make from the full-resolution data, runs in a worker and the image appears when it
        is done (``source_ready``). Tiles always follow in worker threads.
        """
        self._clear()
        self.source = source
        self._pending_levels = levels
        if source is None:
            self.source_changed.emit()
            return
        self.loader = TileLoader(source, self._threads, self._on_tile_loaded, self._on_tile_failed)
        self.destroyed.connect(self.loader.stop)  # deleted without a close: the workers end
        w, h = source.width, source.height
        self.vb.setLimits(xMin=-w, xMax=2 * w, yMin=-h, yMax=2 * h, minXRange=4, minYRange=4)
        self.fit()
        self.source_changed.emit()
        if source.has_overviews() or w * h <= self.sync_coarse_pixels:
            self._install_coarse(source.coarse()[0])
        else:
            self.loader.request([COARSE_KEY])

    def is_ready(self) -> bool:
        """True once the coarse overview is shown (levels and statistics are known)."""
        return self._coarse_item is not None

    def _install_coarse(self, arr) -> None:
        source, levels = self.source, self._pending_levels
        if levels is None:
            st = source.statistics((0.5, 99.5))
            levels = (st.percentiles[0.5], st.percentiles[99.5])
        self._levels = (float(levels[0]), float(levels[1]))
        self._coarse_item = _image_item(self._filtered(arr), (0, 0, source.width, source.height),
                                        self._levels, _COARSE_Z)
        self.vb.addItem(self._coarse_item)
        self._update_timer.start()
        self.levels_changed.emit(*self._levels)
        self.source_ready.emit()

    def _clear(self) -> None:
        self.shutdown()
        for item in self._tiles.values():
            self.vb.removeItem(item)
        self._tiles.clear()
        if self._coarse_item is not None:
            self.vb.removeItem(self._coarse_item)
            self._coarse_item = None
        self._wanted = []
        self._arrived = []

    def shutdown(self) -> None:
        """End the tile reads (joined: the caller may close the source afterwards)."""
        if self.loader is not None:
            self.destroyed.disconnect(self.loader.stop)
            self.loader.shutdown(wait=True)
            self.loader = None

    def closeEvent(self, ev):
        self.shutdown()
        super().closeEvent(ev)

    # ------------------------------------------------------------------ geometry
    def _screen_size(self) -> tuple[float, float]:
        """Size of the image area in screen pixels (a default before the first layout)."""
        w, h = self.vb.width(), self.vb.height()
        return (float(w), float(h)) if w > 0 and h > 0 else (640.0, 480.0)

    def scale(self) -> float:
        """Image pixels per screen pixel (>1 zoomed out, <1 zoomed in)."""
        return float(self.vb.viewRect().width() / self._screen_size()[0])

    def visible_rect(self) -> tuple[float, float, float, float]:
        """Visible area ``(x, y, w, h)`` in image pixels (may extend beyond the image)."""
        r = self.vb.viewRect()
        return float(r.x()), float(r.y()), float(r.width()), float(r.height())

    def center(self) -> tuple[float, float]:
        """Image coordinates at the centre of the view."""
        x, y, w, h = self.visible_rect()
        return x + w / 2, y + h / 2

    def center_on(self, x: float, y: float, scale: float | None = None) -> None:
        """Centre the view on image point ``(x, y)``, optionally at ``scale`` (image px/screen px)."""
        s = self.scale() if scale is None else float(scale)
        sw, sh = self._screen_size()
        hw, hh = sw * s / 2, sh * s / 2
        self.vb.setRange(xRange=(x - hw, x + hw), yRange=(y - hh, y + hh), padding=0)

    def set_scale(self, pixels_per_screen_pixel: float) -> None:
        """Zoom about the view centre to ``pixels_per_screen_pixel`` image pixels per screen pixel."""
        self.center_on(*self.center(), scale=pixels_per_screen_pixel)

    def zoom(self, factor: float) -> None:
        """Magnify by ``factor`` about the view centre (2 = twice as large on screen)."""
        self.set_scale(self.scale() / float(factor))

    def fit(self) -> None:
        """Show the whole image."""
        if self.source is not None:
            self.vb.setRange(QRectF(0, 0, self.source.width, self.source.height), padding=0)

    def map_from_viewport(self, pos: QPointF) -> tuple[float, float]:
        """Image coordinates of a position in ``self.graphics.viewport()`` (pixels, float)."""
        p = self.vb.mapSceneToView(self.graphics.mapToScene(0, 0) + QPointF(pos))
        return float(p.x()), float(p.y())

    def map_to_viewport(self, x: float, y: float) -> QPointF:
        """Position in ``self.graphics.viewport()`` of image coordinates ``(x, y)``."""
        return self.vb.mapViewToScene(QPointF(x, y)) - self.graphics.mapToScene(0, 0)

    # ------------------------------------------------------------------ display filter
    def _filtered(self, arr):
        return arr if self.display_filter is None else self.display_filter(arr)

    def set_display_filter(self, fn) -> None:
        """Show the overview and tiles through ``fn(array) -> array`` (None: as read)."""
        self.display_filter = fn
        self._drop_tiles(lambda k: True)
        if self.source is not None and self._coarse_item is not None:
            self._coarse_item.setImage(self._filtered(self.source.coarse()[0]), autoLevels=False,
                                       levels=self._levels)
            self._coarse_item.setVisible(True)
            self._update_tiles()

    # ------------------------------------------------------------------ levels
    def levels(self) -> tuple[float, float]:
        return self._levels

    def set_levels(self, lo: float, hi: float) -> None:
        """Display levels in data units: ``lo`` shows black, ``hi`` white (overview and tiles)."""
        lo, hi = float(lo), float(hi)
        if hi <= lo:
            hi = lo + 1e-6
        if self._coarse_item is None:  # not ready yet: these levels win over the statistics
            self._pending_levels = (lo, hi)
        if (lo, hi) == self._levels:
            return
        self._levels = (lo, hi)
        for item in ([self._coarse_item] if self._coarse_item else []) + list(self._tiles.values()):
            item.setLevels(self._levels)
        self.levels_changed.emit(lo, hi)

    # ------------------------------------------------------------------ tiles
    def current_level(self) -> int:
        """Decimation level of the tiles wanted for the current view (0: the overview suffices)."""
        return self._level

    def displayed_tiles(self) -> list:
        """Keys ``(level, col, row)`` of the tiles shown."""
        return list(self._tiles)

    def tiles_complete(self) -> bool:
        """True when every wanted tile of the current view is displayed (and no update waits)."""
        if self._update_timer.isActive() or (self.source is not None and not self.is_ready()):
            return False
        return all(k in self._tiles for k in self._wanted)

    def _on_range_changed(self, *args) -> None:
        self._update_timer.start()
        self.view_changed.emit()

    def resizeEvent(self, ev):
        super().resizeEvent(ev)
        self._update_timer.start()

    def _update_tiles(self) -> None:
        src = self.source
        if src is None or self._coarse_item is None or self.vb.width() <= 0:
            return
        # image pixels per physical screen pixel (HiDPI screens have several per logical pixel)
        level = src.level_for(self.scale() / self.graphics.viewport().devicePixelRatioF())
        _, coarse_f = src.coarse()
        if level >= coarse_f:  # the overview is as fine as the screen: no tiles
            self._level, self._wanted = 0, []
            self._coarse_item.setVisible(True)
            self._drop_tiles(lambda k: True)
            self.loader.request([])
            self.tiles_settled.emit()
            return
        self._level = level
        x, y, w, h = self.visible_rect()
        self._wanted = tiles_for_rect(src, level, (x, y, w, h))
        wanted = set(self._wanted)
        missing = []
        for key in self._wanted:
            if key in self._tiles:
                continue
            arr = src.cached_tile(*key)
            if arr is not None:
                self._show_tile(key, arr)
            else:
                missing.append(key)
        # tiles of this level off screen go; other levels stay as a backdrop until complete
        self._drop_tiles(lambda k: k[0] == level and k not in wanted)
        self._drop_tiles(lambda k: k[0] != level and not self._intersects(k))
        self._coarse_item.setVisible(bool(missing))
        if not missing:
            self._settled()
        m = self.prefetch_margin
        ring = [k for k in tiles_for_rect(src, level, (x - m * w, y - m * h, (1 + 2 * m) * w,
                                                       (1 + 2 * m) * h))
                if k not in wanted and k not in src.cache]
        self.loader.request(missing + ring)  # visible first; the ring only fills the cache

    def _intersects(self, key) -> bool:
        x, y, w, h = self.source.tile_rect(*key)
        vx, vy, vw, vh = self.visible_rect()
        return x < vx + vw and vx < x + w and y < vy + vh and vy < y + h

    def _drop_tiles(self, predicate) -> None:
        for key in [k for k in self._tiles if predicate(k)]:
            self.vb.removeItem(self._tiles.pop(key))

    def _show_tile(self, key, arr) -> pg.ImageItem:
        level = key[0]
        item = _image_item(self._filtered(arr), self.source.tile_rect(*key), self._levels,
                           -np.log2(level))
        self.vb.addItem(item)
        self._tiles[key] = item
        return item

    def _on_tile_loaded(self, source, key, arr) -> None:
        if source is self.source and key == COARSE_KEY:
            if self._coarse_item is None:
                self._install_coarse(arr)
        elif source is self.source:
            self._arrived.append((key, arr))
            self._drain_timer.start()

    def _on_tile_failed(self, source, key, message: str) -> None:
        if source is self.source:
            self.read_failed.emit(message)

    def _drain_arrived(self) -> None:
        """Show delivered tiles until TILE_BUDGET_S has passed (one at least), then yield to
        the event loop; tiles no longer wanted are dropped on the way."""
        t0 = time.perf_counter()
        while self._arrived:
            key, arr = self._arrived.pop(0)
            if key in self._tiles or key not in self._wanted:
                continue
            self._show_tile(key, arr).render()  # convert now, inside the budget
            self._unsettled = True
            if time.perf_counter() - t0 >= TILE_BUDGET_S:
                break
        if self._unsettled and self.tiles_complete():  # (stale tiles may still be queued)
            self._settled()
        if self._arrived:
            self._drain_timer.start()

    def _settled(self) -> None:
        """All wanted tiles shown: they cover the view, so backdrop tiles and overview go."""
        self._unsettled = False
        self._drop_tiles(lambda k: k[0] != self._level)
        self._coarse_item.setVisible(False)
        self.tiles_settled.emit()

    # ------------------------------------------------------------------ mouse
    def eventFilter(self, obj, ev) -> bool:
        if ev.type() == QEvent.Type.Leave and obj is self.graphics.viewport():
            self.cursor_left.emit()
        return False

    def _on_mouse_moved(self, scene_pos) -> None:
        if self.source is None:
            return
        p = self.vb.mapSceneToView(scene_pos)
        self.cursor_moved.emit(float(p.x()), float(p.y()))

    def _on_mouse_clicked(self, ev) -> None:
        if self.source is None or ev.button() != Qt.MouseButton.LeftButton:
            return
        p = self.vb.mapSceneToView(ev.scenePos())
        self.clicked.emit(float(p.x()), float(p.y()), ev.modifiers())
