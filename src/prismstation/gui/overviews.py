"""Offer to build overviews for a large raster that has none, with a cancellable progress dialog.

The build runs in a worker thread (``RasterSource.build_overviews``); the dialog's Cancel makes the
progress callback return False, which stops the build between levels.
"""
from __future__ import annotations

from PySide6.QtCore import QObject, Signal, Slot
from PySide6.QtWidgets import QMessageBox, QProgressDialog

from prismstation.errors import RasterReadError
from prismstation.gui import workers


class OverviewBuilder(QObject):
    """Runs ``source.build_overviews`` in a worker thread (:mod:`.workers`).

    Signals
    -------
    progressed(percent)
    finished(completed, error_message)
        ``completed`` is False when cancelled or failed; ``error_message`` is '' unless failed.
    """

    progressed = Signal(int)
    finished = Signal(bool, str)

    def __init__(self, source, external: bool = True):
        super().__init__()
        self.source = source
        self.external = external
        self.jobs = workers.Jobs("overviews")
        self.cancelled = self.jobs.cancelled
        self.result: tuple[bool, str] | None = None

    def start(self) -> None:
        self.jobs.start(self._run)

    def cancel(self) -> None:
        self.cancelled.set()

    def wait(self) -> None:
        self.jobs.wait()

    def _run(self) -> None:  # worker thread
        def progress(fraction: float) -> bool:
            workers.post(self._progressed, int(round(100 * fraction)))
            return not self.cancelled.is_set()

        try:
            self.result = (bool(self.source.build_overviews(progress, external=self.external)), "")
        except RasterReadError as exc:
            self.result = (False, str(exc))
        finally:
            self.source.release_thread()
        workers.post(self._finished, *self.result)

    def _progressed(self, percent: int) -> None:
        self.progressed.emit(percent)

    def _finished(self, completed: bool, message: str) -> None:
        self.finished.emit(completed, message)


class _Waiter(QObject):
    """Lives in the GUI thread: receives the builder's signals there and closes the dialog."""

    def __init__(self, dialog, builder):
        super().__init__()
        self.dialog, self.builder = dialog, builder
        self.ok, self.message = None, ""

    @Slot()
    def cancel(self) -> None:
        self.builder.cancel()  # a threading.Event: safe from this thread

    @Slot(bool, str)
    def finish(self, completed: bool, message: str) -> None:
        self.ok, self.message = completed, message
        self.dialog.done(0)


def build_overviews_with_progress(parent, source, external: bool = True) -> bool:
    """Build overviews of ``source`` behind a modal QProgressDialog with Cancel.

    Returns
    -------
    bool
        True when the overviews were built, False when cancelled or failed (a failure is shown
        in a message box).
    """
    dialog = QProgressDialog(f"Building overviews of {source.path.name}…", "Cancel", 0, 100,
                             parent)
    dialog.setWindowTitle("Overviews")
    dialog.setMinimumDuration(0)
    dialog.setAutoClose(False)
    dialog.setAutoReset(False)
    builder = OverviewBuilder(source, external)
    waiter = _Waiter(dialog, builder)
    builder.progressed.connect(dialog.setValue)
    builder.finished.connect(waiter.finish)
    dialog.canceled.connect(waiter.cancel)
    builder.start()
    dialog.exec()  # the queued `finished` can only arrive inside this event loop
    if waiter.ok is None:  # the dialog went away before the end (Cancel, Esc, close)
        builder.cancel()
    builder.wait()
    ok, message = builder.result or (False, "")
    if message:
        QMessageBox.warning(parent, "Overviews", message)
    return ok


def offer_overviews(parent, source, min_size: int = 4096) -> bool:
    """Ask whether to build overviews when ``source`` is large and has none; build if accepted.

    Returns True when the source has overviews afterwards (or does not need them).
    """
    if not source.needs_overviews(min_size):
        return True
    answer = QMessageBox.question(
        parent, "Overviews",
        f"{source.path.name} ({source.width} × {source.height} px) has no overviews: display "
        "will be slow when zoomed out. Build them now (an .ovr file beside the image)?")
    if answer != QMessageBox.StandardButton.Yes:
        return False
    return build_overviews_with_progress(parent, source)
