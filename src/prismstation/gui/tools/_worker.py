"""Long tool operations off the GUI thread: progress, cancel, result or a one-line error.

``Job(fn, title, window)`` runs ``fn(progress)`` in a worker thread (:mod:`prismstation.gui.workers`).
``progress(fraction, message="")`` (fraction 0–1) emits :attr:`Job.progress` and returns False
once :meth:`Job.cancel` was called, which is how the engine's long loops learn to stop. The
outcome is exactly one of :attr:`Job.result` (the return value), :attr:`Job.failed` (a message
for the operator, never a traceback) or :attr:`Job.cancelled`, emitted on the GUI thread.

A running job has no Qt parent and keeps itself alive, so it is never destroyed while it runs;
it is cancelled and awaited when ``window`` closes or the application quits.
"""
from __future__ import annotations

import shiboken6

from PySide6.QtCore import QCoreApplication, QEvent, QObject, Qt, Signal
from PySide6.QtWidgets import QMessageBox, QProgressDialog

from prismstation.errors import PrismError
from prismstation.gui import workers

_LIVE: set = set()  # running jobs are kept alive here until they end
STOP_WAIT_MS = 60000  # how long a closing window or quitting application waits for a job


class Job(QObject):
    """Run ``fn(progress)`` in a worker thread (see module doc)."""

    progress = Signal(float, str)
    result = Signal(object)
    failed = Signal(str)
    cancelled = Signal()

    def __init__(self, fn, title: str = "", window=None):
        super().__init__()
        self.fn, self.title, self._window = fn, title, _widget(window)
        self._jobs = workers.Jobs("tool")
        self._cancel = self._jobs.cancelled

    def cancel(self) -> None:
        self._cancel.set()

    def is_cancelled(self) -> bool:
        return self._cancel.is_set()

    def isRunning(self) -> bool:
        return self._jobs.busy()

    def wait(self, ms: int | None = None) -> bool:
        """Join the thread (``ms`` milliseconds at most); True when it has ended."""
        return self._jobs.wait(None if ms is None else ms / 1000.0)

    def report(self, fraction: float, message: str = "") -> bool:  # worker thread
        workers.post(self._progressed, float(fraction), str(message))
        return not self._cancel.is_set()

    def _progressed(self, fraction: float, message: str) -> None:
        self.progress.emit(fraction, message)

    def _run(self) -> None:  # worker thread
        try:
            out = self.fn(self.report)
            outcome = ("cancelled", None) if self._cancel.is_set() else ("result", out)
        except PrismError as exc:
            outcome = ("cancelled", None) if self._cancel.is_set() else ("failed", str(exc))
        except Exception as exc:  # an engine bug must not take the window down: say what it was
            outcome = ("failed", f"{self.title or 'the operation'} failed: {type(exc).__name__}: {exc}")
        workers.post(self._deliver, *outcome)

    def start(self) -> None:
        _LIVE.add(self)
        app = QCoreApplication.instance()
        if app is not None:
            app.aboutToQuit.connect(self._stop)
        if self._window is not None:
            self._window.installEventFilter(self)
        self._jobs.start(self._run)

    def eventFilter(self, obj, ev) -> bool:  # the window is closing: stop first
        if ev.type() == QEvent.Type.Close and self.isRunning():
            self._stop()
        return False

    def _stop(self) -> None:
        self.cancel()
        self.wait(STOP_WAIT_MS)

    def _deliver(self, kind, value) -> None:
        _LIVE.discard(self)
        if self._window is not None and shiboken6.isValid(self._window):
            self._window.removeEventFilter(self)
        app = QCoreApplication.instance()
        if app is not None:
            try:
                app.aboutToQuit.disconnect(self._stop)
            except (RuntimeError, TypeError):
                pass
        if kind == "result":
            self.result.emit(value)
        elif kind == "failed":
            self.failed.emit(value)
        else:
            self.cancelled.emit()


def _widget(window):
    """The widget of a tool context (or the widget itself)."""
    from prismstation.gui.tools import ToolContext
    return window.widget if isinstance(window, ToolContext) else window


def stop_jobs_of(window) -> None:
    """Cancel and join the running jobs started over ``window`` (it is closing)."""
    for job in list(_LIVE):
        if job._window is window and job.isRunning():
            job._stop()


def run_with_progress(window, title: str, fn, on_result, *, on_failed=None, dialog: bool = True) -> Job:
    """Start ``fn(progress)`` in a :class:`Job` with a cancellable progress dialog over
    ``window`` (a widget or a tool context; busy until the first progress report); ``on_result(value)`` and
    ``on_failed(message)`` run on the GUI thread while the window exists. Errors also go to a
    message box (when the window is interactive) and the status bar."""
    window = _widget(window)
    job = Job(fn, title, window)
    dlg = None
    if dialog:
        dlg = QProgressDialog(title, "Cancel", 0, 0, window)
        dlg.setWindowTitle(title)
        dlg.setWindowModality(Qt.WindowModality.WindowModal)
        dlg.setMinimumDuration(0)
        dlg.setAutoClose(False)
        dlg.setAutoReset(False)
        dlg.canceled.connect(job.cancel)
        dlg.canceled.connect(lambda: window.statusBar().showMessage(
            f"{title}: cancelling (the step running now ends first)"))
        dlg.show()

    def progressed(f, m):  # a report sent before the window closed may arrive after
        if not shiboken6.isValid(window) or job.is_cancelled():
            return  # after Cancel: no percentage that then stays on the status bar
        if dlg is not None and shiboken6.isValid(dlg):
            dlg.setMaximum(1000)
            dlg.setValue(int(round(1000 * min(max(f, 0.0), 1.0))))
            dlg.setLabelText(f"{title}\n{m}" if m else title)
        window.statusBar().showMessage(f"{title}: {f:.0%} {m}")
    job.progress.connect(progressed)

    def close():
        if dlg is not None:
            dlg.canceled.disconnect(job.cancel)
            dlg.close()
            dlg.deleteLater()

    def done(value):
        if not shiboken6.isValid(window):
            return  # the window was closed while the job ran
        close()
        window.statusBar().showMessage(f"{title}: done", 8000)
        on_result(value)

    def failed(msg):
        if not shiboken6.isValid(window):
            return
        close()
        window.statusBar().showMessage(f"{title}: {msg}", 15000)
        if on_failed is not None:
            on_failed(msg)
        if getattr(window, "interactive", False):
            QMessageBox.warning(window, title, msg)

    def cancelled():
        if not shiboken6.isValid(window):
            return
        close()
        window.statusBar().showMessage(f"{title}: cancelled", 8000)

    job.result.connect(done)
    job.failed.connect(failed)
    job.cancelled.connect(cancelled)
    job.start()
    return job
