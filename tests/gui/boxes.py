"""Message boxes as the operator sees them: wait for the next modal box, note its title and
text, press one of its buttons."""
from __future__ import annotations

from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication, QMessageBox


def answer_next_box(seen: list, button=QMessageBox.StandardButton.Ok, tries: int = 200) -> None:
    """When a modal QMessageBox shows (polled every 50 ms, ``tries`` times), append
    ``(title, text)`` to ``seen`` and click ``button`` (a StandardButton)."""
    def poll(left=tries):
        w = QApplication.activeModalWidget()
        if isinstance(w, QMessageBox) and w.isVisible():
            seen.append((w.windowTitle(), w.text()))
            b = w.button(button)
            (b or w.buttons()[0]).click()
        elif left > 0:
            QTimer.singleShot(50, lambda: poll(left - 1))
    QTimer.singleShot(50, poll)
