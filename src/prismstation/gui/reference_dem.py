"""A reference DEM for the window: heights for the linked cursor and for points without parallax,
loaded in a worker (:class:`DemLoader`) by :func:`prismstation.ops.reference_heights.load_for_scene`.
"""
from __future__ import annotations

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
