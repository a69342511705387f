"""Linked navigation: a zoom or pan made by hand in one view moves the others onto the same
ground area, through the current model (View ▸ Linked navigation, on by default).

The ground under the centre of the view is found at the height of the reference DEM there
(else the solution's mean height, :meth:`TripletViews.ground_height`) and projected into each
other view; their scale (image px per screen px) is that view's pixels per pixel of the moved
one along the image x axis, so the same ground width fills the same screen width. Only hand
gestures (wheel, drag: pyqtgraph's ``sigRangeChangedManually``) are followed; the moves made
here are programmatic, so they are not followed in turn (no feedback loop), and a guard
refuses re-entry all the same.
"""
from __future__ import annotations

import numpy as np
from PySide6.QtCore import QObject

from prismstation.errors import PrismError

STEP_PX = 100.0  # image pixels of the moved view over which the other views' scale is taken


class LinkedNavigation(QObject):
    """Follows :attr:`TripletViews.navigated` while :attr:`enabled`."""

    def __init__(self, views, parent=None):
        super().__init__(parent)
        self.views = views
        self.enabled = True
        self._busy = False
        views.navigated.connect(self.follow)

    def set_enabled(self, on: bool) -> None:
        self.enabled = bool(on)

    def targets(self, name: str) -> dict:
        """``{view: (x, y, scale)}``: where each other view goes for the view ``name`` as it is."""
        views, sol = self.views, self.views.solution
        iv = views.views.get(name)
        if sol is None or not sol.ok or iv is None or iv.source is None:
            return {}
        cx, cy = iv.center()
        s = iv.scale()
        xy = np.array([[cx, cy], [cx + STEP_PX, cy]], float)
        try:
            h = views.ground_height(name, xy[0])
            en = sol.image_to_ground(name, xy, h)
            out = {}
            for v, other in views.views.items():
                if v == name or other.source is None:
                    continue
                q = sol.ground_to_image(v, en, h)
                k = float(np.hypot(*(q[1] - q[0]))) / STEP_PX
                if np.all(np.isfinite(q)) and k > 0:
                    out[v] = (float(q[0, 0]), float(q[0, 1]), s * k)
            return out
        except (PrismError, ValueError, np.linalg.LinAlgError):
            return {}

    def follow(self, name: str) -> None:
        """View ``name`` was zoomed or panned by hand: move the others (when enabled)."""
        if not self.enabled or self._busy:
            return
        self._busy = True
        try:
            for v, (x, y, s) in self.targets(name).items():
                self.views.views[v].center_on(x, y, s)
        finally:
            self._busy = False
