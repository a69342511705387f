"""Dialog titles shown whole: a window manager cuts a title to the window's width, and a small
form (a few fields) is narrower than its title. :func:`fit_title` makes the dialog at least as
wide as its title needs, title-bar buttons included."""
from __future__ import annotations

from PySide6.QtGui import QFont, QFontMetrics

TITLE_BAR_EXTRA_PX = 150  # the window manager's icon and buttons (openbox, GNOME, KDE: 90–140 px)


def title_width(title: str) -> int:
    """Pixels a window title needs in a title bar (bold system font, buttons included)."""
    font = QFont()
    font.setBold(True)
    return QFontMetrics(font).horizontalAdvance(title) + TITLE_BAR_EXTRA_PX


def fit_title(dialog, title: str | None = None) -> None:
    """Give ``dialog`` (its window title, or ``title``) a minimum width that shows the title whole."""
    if title is not None:
        dialog.setWindowTitle(title)
    dialog.setMinimumWidth(max(dialog.minimumWidth(), title_width(dialog.windowTitle())))
