"""A reference DEM for the window: heights for the linked cursor and for points without parallax,
loaded in a worker (:class:`DemLoader`) by :func:`prismstation.ops.reference_heights.load_for_scene`.
"""
from __future__ import annotations

from PySide6.QtCore import QObject, QRunnable, QThreadPool, Signal

from prismstation.errors import PrismError
from prismstation.ops.reference_heights import load_for_scene


class _Relay(QObject):
    done = Signal(object, str)


_RELAY: _Relay | None = None


class _Job(QRunnable):
    def __init__(self, path, project, relay):
        super().__init__()
        self.path, self.project, self.relay = path, project, relay

    def run(self) -> None:  # worker thread
        try:
            self.relay.done.emit(load_for_scene(self.path, self.project), "")
        except (PrismError, OSError, ValueError) as exc:
            self.relay.done.emit(None, str(exc))


class DemLoader(QObject):
    """Loads a reference DEM in a worker; ``loaded(DemHeights)`` or ``failed(message)``."""

    loaded = Signal(object)
    failed = Signal(str)

    def __init__(self, parent=None):
        super().__init__(parent)
        global _RELAY
        if _RELAY is None:  # process-wide and never deleted: no emit on a dead object
            _RELAY = _Relay()
        self._pool = QThreadPool(self)
        self._pool.setMaxThreadCount(1)
        _RELAY.done.connect(self._done)
        self._waiting = False

    def start(self, path, project) -> None:
        self._waiting = True
        self._pool.start(_Job(path, project, _RELAY))

    def _done(self, heights, error) -> None:
        if not self._waiting:
            return
        self._waiting = False
        if heights is None:
            self.failed.emit(error)
        else:
            self.loaded.emit(heights)

    def wait(self, ms: int = 30000) -> None:
        self._pool.waitForDone(ms)
