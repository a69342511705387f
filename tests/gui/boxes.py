"""Message boxes as the operator sees them: wait for the next modal box, note its title and
text, press one of its buttons."""
from __future__ import annotations

from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication, QMessageBox


#: the stop flags of the pollers still polling (:func:`stop_pollers` ends them all)
_LIVE: list[list] = []


def stop_pollers() -> None:
    """Stop every poller still waiting for its box: called after each test (tests/gui's
    conftest), so that the poller of a test that failed before its box came cannot answer the
    next test's box."""
    for stopped in _LIVE:
        stopped.append(True)
    _LIVE.clear()


def answer_next_box(seen: list, button=QMessageBox.StandardButton.Ok, tries: int = 200):
    """When a modal QMessageBox shows (polled every 50 ms, ``tries`` times), append
    ``(title, text)`` to ``seen`` and click ``button`` (a StandardButton). Returns a function
    that stops the polling: a poller whose box never came must not answer a later one."""
    stopped = []
    _LIVE.append(stopped)

    def poll(left=tries):
        if stopped:
            return
        w = QApplication.activeModalWidget()
        if isinstance(w, QMessageBox) and w.isVisible():
            seen.append((w.windowTitle(), w.text()))
            b = w.button(button)
            (b or w.buttons()[0]).click()
        elif left > 0:
            QTimer.singleShot(50, lambda: poll(left - 1))
    QTimer.singleShot(50, poll)
    return lambda: stopped.append(True)
