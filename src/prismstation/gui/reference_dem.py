"""A reference DEM for the window: heights for the linked cursor and for points without parallax,
loaded in a worker (:class:`DemLoader`) by :func:`prismstation.ops.reference_heights.load_for_scene`.
"""
from __future__ import annotations

import math

from PySide6.QtCore import QObject, Signal

from prismstation.errors import PrismError
from prismstation.gui import workers
from prismstation.ops.reference_heights import load_for_scene


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

    def forget(self) -> None:
        """Drop the outcome of the load under way (another project is open)."""
        self._request += 1

    def wait(self, ms: int = 30000) -> None:
        """Wait for the load and deliver its outcome (scripts and tests)."""
        self._jobs.wait(ms / 1000.0)
        workers.deliver_now()

    def close(self) -> None:
        """Join the load (it reads the project's scene); its outcome is dropped."""
        self._request += 1
        self._jobs.close()


def describe(heights) -> str:
    """The status bar's words for a loaded reference DEM: its file, its own cells and its own
    noise (the point transfer weighs the relief it shows against that noise)."""
    grid = heights.grid
    words = []
    if grid.source_cell_m:
        words.append("cells {:.0f} × {:.0f} m".format(*grid.source_cell_m))
    if grid.source_noise_m is not None and math.isfinite(grid.source_noise_m):
        words.append(f"its own noise {grid.source_noise_m:.1f} m")
    return f"Reference DEM: {heights.path}" + (" — " + ", ".join(words) if words else "")
