"""Texts for the operator: user strings shown as they were typed, counts with their nouns.

User strings — point ids, file names, messages that quote them — must show as typed.

Qt renders a text as rich text wherever it "might be" (``Qt.mightBeRichText``: a tag on its first
line): tool tips, ``QLabel``, ``QMessageBox``, ``QStaticText``. An id ``<b>x</b>`` would show as a
bold "x" and ``<script>alert(1)</script>`` as nothing. :func:`plain` is a text those widgets
show literally; user strings put inside rich text of the window's own are ``html.escape``-d.
"""
from __future__ import annotations

import html

from PySide6.QtGui import Qt


def plain(text: str) -> str:
    """``text`` as Qt's auto-detecting widgets will show it literally: unchanged when Qt would
    take it for plain text anyway, else as escaped rich text (line breaks kept)."""
    text = str(text)
    return Qt.convertFromPlainText(text) if Qt.mightBeRichText(text) else text


def plain_block(text: str) -> str:
    """``text`` escaped in a block of rich text: for texts Qt joins before showing (pyqtgraph's
    tool tip of several points joins them with blank lines), which :func:`plain` cannot reach."""
    return f"<div>{html.escape(str(text))}</div>"


def counted(n: int, noun: str, plural: str | None = None) -> str:
    """``"1 patch"``, ``"3 patches"``: ``n`` with ``noun`` or its ``plural`` (default ``noun + "s"``)."""
    return f"{n} {noun if n == 1 else plural or noun + 's'}"
