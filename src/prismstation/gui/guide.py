"""Help ▸ User guide: ``docs/guide.md`` in a viewer window.

The guide is looked for beside the package (a source checkout or an editable install:
``<repo>/docs/guide.md``) and in a one-folder build (``<bundle>/docs/guide.md``).
"""
from __future__ import annotations

import sys
from pathlib import Path

from PySide6.QtCore import QUrl
from PySide6.QtGui import QTextCursor, QTextLength, QTextTable
from PySide6.QtWidgets import QDialog, QTextBrowser, QVBoxLayout


def guide_path() -> Path | None:
    """The user guide's path, or None when it is not installed."""
    roots = [Path(__file__).resolve().parents[3] / "docs"]
    if getattr(sys, "_MEIPASS", None):
        roots.insert(0, Path(sys._MEIPASS) / "docs")
    return next((r / "guide.md" for r in roots if (r / "guide.md").is_file()), None)


class GuideViewer(QDialog):
    """The guide rendered from its Markdown, pictures included; links to the other documents
    open in the same viewer."""

    def __init__(self, path: Path, parent=None):
        super().__init__(parent)
        self.setObjectName("guide_viewer")
        self.setWindowTitle("prismstation — user guide")
        self.browser = QTextBrowser()
        self.browser.setOpenLinks(True)
        self.browser.setOpenExternalLinks(False)
        self.browser.setSearchPaths([str(path.parent)])
        self.browser.sourceChanged.connect(lambda *_: self.fit_page())
        self.browser.setSource(QUrl.fromLocalFile(str(path)))
        QVBoxLayout(self).addWidget(self.browser)
        self.resize(900, 700)

    def fit_page(self) -> None:
        """Pictures and tables at most as wide as the page, whatever its width (a list's indent
        and the scroll bar included): as a share of it, which Qt applies at every layout.
        Screenshots are wider than the viewer; Markdown tables came out a few pixels wider."""
        doc = self.browser.document()
        for frame in doc.rootFrame().childFrames():
            if isinstance(frame, QTextTable):
                fmt = frame.format()
                fmt.setWidth(QTextLength(QTextLength.Type.PercentageLength, 98))
                frame.setFormat(fmt)
        block = doc.begin()
        while block.isValid():
            it = block.begin()
            while not it.atEnd():
                frag = it.fragment()
                fmt = frag.charFormat()
                if fmt.isImageFormat():
                    img = fmt.toImageFormat()
                    # (of the page, not of the block: a picture in a list item leaves the indent)
                    share = 100 if block.textList() is None and not block.blockFormat().indent() else 90
                    img.setMaximumWidth(QTextLength(QTextLength.Type.PercentageLength, share))
                    cur = QTextCursor(doc)
                    cur.setPosition(frag.position())
                    cur.setPosition(frag.position() + frag.length(), QTextCursor.MoveMode.KeepAnchor)
                    cur.setCharFormat(img)
                it += 1
            block = block.next()


def show_guide(parent) -> QDialog | None:
    """Show the guide in a viewer over ``parent`` (kept as ``parent.guide_viewer``); None with a
    status message when the guide is not installed."""
    path = guide_path()
    if path is None:
        parent.statusBar().showMessage("The user guide (docs/guide.md) is not installed", 10000)
        return None
    viewer = getattr(parent, "guide_viewer", None)
    if viewer is None:
        viewer = parent.guide_viewer = GuideViewer(path, parent)
    viewer.show()
    viewer.raise_()
    return viewer
