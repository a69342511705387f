"""Long tool operations off the GUI thread: progress, cancel, result or a one-line error.

``Job(fn, title, window)`` runs ``fn(progress)`` in a worker thread (:mod:`prismstation.gui.workers`).
``progress(fraction, message="")`` (fraction 0–1) emits :attr:`Job.progress` and returns False
once :meth:`Job.cancel` was called, which is how the engine's long loops learn to stop. The
outcome is exactly one of :attr:`Job.result` (the return value), :attr:`Job.failed` (a message
for the operator, never a traceback) or :attr:`Job.cancelled`, emitted on the GUI thread.

A running job has no Qt parent and keeps itself alive, so it is never destroyed while it runs;
it is cancelled and awaited when ``window`` closes or the application quits. The worker thread
holds no Qt object (a weak reference to its job): the last reference to a job is always dropped
on the GUI thread, never in a worker (which would delete the job there). The outcome is emitted
in an event-loop turn of its own, so receivers that open message boxes do not nest them in
another delivery.
"""
from __future__ import annotations

import weakref

import shiboken6
from PySide6.QtCore import QCoreApplication, QEvent, QObject, Qt, QTimer, Signal
from PySide6.QtWidgets import QMessageBox, QProgressDialog, QWidget

from prismstation.errors import PrismError
from prismstation.gui import workers
from prismstation.gui.titles import fit_title
from prismstation.gui.plain import plain

_LIVE: set = set()  # running jobs are kept alive here until they end
STOP_WAIT_MS = 60000  # how long a closing window or quitting application waits for a job


class Job(QObject):
    """Run ``fn(progress)`` in a worker thread (see module doc)."""

    progress = Signal(float, str)
    ended = Signal()  # the thread has ended (before the outcome is emitted)
    result = Signal(object)
    failed = Signal(str)
    cancelled = Signal()

    def __init__(self, fn, title: str = "", window=None):
        super().__init__()
        self.fn, self.title, self._window = fn, title, _widget(window)
        self._jobs = workers.Jobs("tool")
        self._cancel = self._jobs.cancelled
        self.last = (0.0, "")  # the last progress reported: fraction 0–1, message

    def cancel(self) -> None:
        self._cancel.set()

    def is_cancelled(self) -> bool:
        return self._cancel.is_set()

    def isRunning(self) -> bool:
        return self._jobs.busy()

    def describe(self) -> str:
        """``DSM: 45 % (matching F–B)`` for a question or a status line."""
        f, m = self.last
        return f"{self.title or 'a job'}: {f:.0%}" + (f" ({m})" if m else "")

    def wait(self, ms: int | None = None) -> bool:
        """Join the thread (``ms`` milliseconds at most); True when it has ended."""
        return self._jobs.wait(None if ms is None else ms / 1000.0)

    def report(self, fraction: float, message: str = "") -> bool:
        """The ``progress`` callable (any thread): True while the job is not cancelled."""
        return _report(weakref.ref(self), self._cancel, fraction, message)

    def _progressed(self, fraction: float, message: str) -> None:
        self.last = (fraction, message)
        self.progress.emit(fraction, message)

    def start(self) -> None:
        _LIVE.add(self)
        app = QCoreApplication.instance()
        if app is not None:
            app.aboutToQuit.connect(self._stop)
        if self._window is not None:
            self._window.installEventFilter(self)
        # the thread holds no Qt object: were it to drop the last reference to this job, the
        # job would be deleted in the worker thread while the GUI thread uses it
        self._jobs.start(_work, weakref.ref(self), self.fn, self.title, self._cancel)

    def eventFilter(self, obj, ev) -> bool:
        """The window is asked to close: it decides first (it may ask, or refuse); closing,
        its jobs are cancelled and awaited before it goes."""
        if ev.type() == QEvent.Type.Close and obj is self._window and self.isRunning():
            obj.event(ev)
            if ev.isAccepted():
                stop_jobs_of(obj)
            return True
        return False

    def _stop(self) -> None:
        self.cancel()
        self.wait(STOP_WAIT_MS)

    def _deliver(self, kind, value) -> None:
        """The outcome, on the GUI thread. The worker posted it as its last act: joined here,
        it has let go of everything it held before this job is released."""
        self.wait()
        _LIVE.discard(self)
        self.ended.emit()
        if self._window is not None and shiboken6.isValid(self._window):
            self._window.removeEventFilter(self)
        app = QCoreApplication.instance()
        if app is not None:
            try:
                app.aboutToQuit.disconnect(self._stop)
            except (RuntimeError, TypeError):
                pass
        # the receivers may open message boxes (nested event loops): not from inside the relay
        QTimer.singleShot(0, self, lambda: self._emit(kind, value))

    def _emit(self, kind, value) -> None:
        if kind == "result":
            self.result.emit(value)
        elif kind == "failed":
            self.failed.emit(value)
        else:
            self.cancelled.emit()


def _report(ref, cancel, fraction, message="") -> bool:  # worker thread
    workers.post(_to_job, ref, "_progressed", float(fraction), str(message))
    return not cancel.is_set()


def _to_job(ref, method: str, *args) -> None:  # GUI thread
    job = ref()
    if job is not None and shiboken6.isValid(job):
        getattr(job, method)(*args)


def _work(ref, fn, title, cancel) -> None:  # worker thread
    try:
        out = fn(lambda f, m="": _report(ref, cancel, f, m))
        outcome = ("cancelled", None) if cancel.is_set() else ("result", out)
    except PrismError as exc:
        outcome = ("cancelled", None) if cancel.is_set() else ("failed", str(exc))
    except Exception as exc:  # an engine bug must not take the window down: say what it was
        outcome = ("failed", f"{title or 'the operation'} failed: {type(exc).__name__}: {exc}")
    workers.post(_to_job, ref, "_deliver", *outcome)


def _widget(window):
    """The window of a tool context (its ``widget``), or ``window`` itself when it is one (or
    None)."""
    return window if window is None or isinstance(window, QWidget) else window.widget


def running_jobs_of(window) -> list:
    """The jobs started over ``window`` that are still running."""
    window = _widget(window)
    return [job for job in list(_LIVE) if job._window is window and job.isRunning()]


def stop_jobs_of(window) -> None:
    """Cancel and join the running jobs started over ``window`` (it is closing)."""
    for job in running_jobs_of(window):
        job._stop()


def run_with_progress(window, title: str, fn, on_result, *, on_failed=None, dialog: bool = True) -> Job:
    """Start ``fn(progress)`` in a :class:`Job` with a progress dialog over ``window`` (a widget
    or a tool context; busy until the first progress report); ``on_result(value)`` and
    ``on_failed(message)`` run on the GUI thread while the window exists. Errors also go to a
    message box (when the window is interactive) and the status bar.

    The dialog is not modal: the window stays usable, and its X and Ctrl+Q reach it (the
    window asks whether to cancel the job and quit). A window-modal progress dialog spun an
    event loop inside every progress report (``QProgressDialog.setValue``), so a quit, the
    job's end or the dialog's own deletion could run inside a report. Its Cancel or X cancels
    the job; the dialog then closes for good and is deleted once the job has ended."""
    window = _widget(window)
    job = Job(fn, title, window)
    dlg = None
    if dialog:
        dlg = QProgressDialog(title, "Cancel", 0, 0, window)
        dlg.setWindowTitle(title)
        fit_title(dlg)
        dlg.setWindowModality(Qt.WindowModality.NonModal)
        dlg.setMinimumDuration(0)
        dlg.setAutoClose(False)
        dlg.setAutoReset(False)
        dlg.canceled.connect(job.cancel)
        dlg.canceled.connect(lambda: shiboken6.isValid(window)
                             and window.statusBar().showMessage(f"{title}: cancelling…"))
        dlg.show()

    def live_dialog():
        return dlg is not None and shiboken6.isValid(dlg) and not dlg.wasCanceled()

    def progressed(f, m):  # a report sent before the window closed may arrive after
        if not shiboken6.isValid(window):
            return
        if live_dialog():
            dlg.setMaximum(1000)
            dlg.setValue(int(round(1000 * min(max(f, 0.0), 1.0))))
            dlg.setLabelText(f"{title}\n{m}" if m else title)
        if not job.is_cancelled():
            window.statusBar().showMessage(f"{title}: {f:.0%} {m}")
    job.progress.connect(progressed)

    def close():
        if dlg is not None and shiboken6.isValid(dlg):
            dlg.hide()
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
            box = QMessageBox(QMessageBox.Icon.Warning, title, plain(msg), QMessageBox.StandardButton.Ok, window)
            fit_title(box)
            box.exec()

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
