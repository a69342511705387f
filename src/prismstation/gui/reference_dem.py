"""A reference DEM for the window: heights for the linked cursor and for points without parallax.

:func:`load_for_scene` reads a DEM (SRTM ``.hgt`` or GeoTIFF, any CRS) through
:func:`prismstation.io.dem.read_dem` onto a grid in the scene CRS covering the scene (30 m), made
ellipsoidal through the project's geoid; :class:`DemHeights` samples it bilinearly. Loading runs
in a worker (:class:`DemLoader`).
"""
from __future__ import annotations

import math

import numpy as np
from PySide6.QtCore import QObject, Signal
from rasterio.transform import from_origin
from scipy import ndimage

from prismstation.errors import PrismError
from prismstation.gui import workers

SPACING_M = 30.0
MARGIN_M = 3000.0


class DemHeights:
    """Ellipsoidal heights of a :class:`~prismstation.io.dem.DemGrid` at map points.

    Call with ``en`` ``(n, 2)`` map metres of the grid's CRS; returns ``(n,)`` metres, NaN
    outside the grid or in voids (bilinear between pixel centres).
    """

    def __init__(self, grid, path=None):
        self.grid = grid
        self.path = path
        self._inv = ~grid.transform

    def __call__(self, en) -> np.ndarray:
        en = np.asarray(en, dtype=float).reshape(-1, 2)
        col, row = self._inv * (en[:, 0], en[:, 1])
        return ndimage.map_coordinates(self.grid.heights, [np.asarray(row) - 0.5, np.asarray(col) - 0.5],
                                       order=1, mode="constant", cval=np.nan, prefilter=False)


def scene_grid(scene, spacing: float = SPACING_M, margin: float = MARGIN_M):
    """``(transform, shape)`` of a north-up grid in the scene CRS covering every view's image."""
    corners = []
    for v in scene.views.values():
        rows, cols = v.shape if v.shape else (20000, 20000)
        px = np.array([[0, 0], [cols, 0], [0, rows], [cols, rows]], float)
        corners.append(v.map_to_image.inverse()(px))
    c = np.vstack(corners)
    x0, y0 = c.min(axis=0) - margin
    x1, y1 = c.max(axis=0) + margin
    shape = (int(math.ceil((y1 - y0) / spacing)), int(math.ceil((x1 - x0) / spacing)))
    return from_origin(x0, y1, spacing, spacing), shape


def load_for_scene(path, project) -> DemHeights:
    """Read the DEM at ``path`` onto the scene's grid, ellipsoidal through the project's geoid."""
    from prismstation.io.dem import read_dem
    from prismstation.io.project import project_geoid
    transform, shape = scene_grid(project.scene)
    grid = read_dem(path, project.scene.crs, transform, shape, geoid=project_geoid(project))
    if not np.isfinite(grid.heights).any():
        from prismstation.errors import InputError
        raise InputError("the DEM does not cover the scene", file=path)
    return DemHeights(grid, path)


def _load(on_done, path, project, request: int) -> None:  # worker thread
    try:
        workers.post(on_done, load_for_scene(path, project), "", request)
    except (PrismError, OSError, ValueError) as exc:
        workers.post(on_done, None, str(exc), request)


class DemLoader(QObject):
    """Loads a reference DEM in a worker; ``loaded(DemHeights)`` or ``failed(message)`` for the
    latest :meth:`start` (earlier ones are dropped). :meth:`close` joins the worker."""

    loaded = Signal(object)
    failed = Signal(str)

    def __init__(self, parent=None):
        super().__init__(parent)
        self._jobs = workers.Jobs("reference-dem")
        self._request = 0

    def start(self, path, project) -> None:
        self._request += 1
        self._jobs.start(_load, self._done, path, project, self._request)

    def _done(self, heights, error, request) -> None:
        if request != self._request:
            return
        if heights is None:
            self.failed.emit(error)
        else:
            self.loaded.emit(heights)

    def wait(self, ms: int = 30000) -> None:
        """Wait for the load and deliver its outcome (scripts and tests)."""
        self._jobs.wait(ms / 1000.0)
        workers.deliver_now()

    def close(self) -> None:
        """Join the load (it reads the project's scene); its outcome is dropped."""
        self._request += 1
        self._jobs.close()
