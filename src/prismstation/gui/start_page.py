"""The start page: what the window shows while no project is open.

Instead of empty panels with controls that mean nothing yet, the central area offers the ways
in: open the demo project (when the program knows how to make it), open a project, open a
recent one, start a project from a JAXA PRISM product folder or from a scene file, and read the
user guide. The window hides its panels while this page is up and brings them back with the
first project.
"""
from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (QFrame, QHBoxLayout, QLabel, QListWidget, QListWidgetItem,
                               QPushButton, QVBoxLayout, QWidget)


class StartPage(QWidget):
    """Buttons for the ways into a project and the recent projects.

    Signals
    -------
    demo_requested(), open_requested(), product_requested(), scene_requested(), guide_requested()
    recent_requested(str)
        A recent project's path (double click or Enter).
    """

    demo_requested = Signal()
    open_requested = Signal()
    product_requested = Signal()
    scene_requested = Signal()
    guide_requested = Signal()
    recent_requested = Signal(str)

    def __init__(self, parent=None):
        super().__init__(parent)
        self.setObjectName("start_page")
        outer = QHBoxLayout(self)
        outer.addStretch(1)
        col = QVBoxLayout()
        outer.addLayout(col, 3)
        outer.addStretch(1)
        col.addStretch(1)
        title = QLabel("<h1>prismstation</h1><p>Orientation of ALOS-PRISM stereo triplets: "
                       "measure ground control and check points in the nadir, forward and "
                       "backward views, fit the bias and parallax models, check the accuracy on "
                       "independent points, report. Images with RPCs (Pléiades, SPOT, "
                       "WorldView…) too: a project made by <tt>prismstation new P --images …</tt> "
                       "opens here, with the RPC bias models.</p>")
        title.setWordWrap(True)
        col.addWidget(title)
        row = QHBoxLayout()
        buttons = QVBoxLayout()
        self.buttons = {}
        for key, text, tip, signal in (
                ("demo", "Open the demo project", "A simulated PRISM triplet with GCPs, ICPs, tie "
                 "points and a reference DEM (made on first use)", self.demo_requested),
                ("open", "Open a project…", "A .prismproj file", self.open_requested),
                ("product", "New project from a PRISM product…", "A JAXA product folder (CEOS "
                 "or GeoTIFF, level 1B1 or 1B2; a triplet or one view)", self.product_requested),
                ("scene", "New project on a scene file…", "A scene.json describing the images",
                 self.scene_requested),
                ("guide", "User guide", "A whole job, step by step", self.guide_requested)):
            b = QPushButton(text)
            b.setToolTip(tip)
            b.setMinimumHeight(34)
            b.clicked.connect(signal)
            buttons.addWidget(b)
            self.buttons[key] = b
        buttons.addStretch(1)
        row.addLayout(buttons, 2)
        line = QFrame()
        line.setFrameShape(QFrame.Shape.VLine)
        row.addWidget(line)
        recent = QVBoxLayout()
        recent.addWidget(QLabel("<b>Recent projects</b>"))
        self.recent = QListWidget()
        self.recent.setToolTip("Double click to open")
        self.recent.itemActivated.connect(lambda it: self.recent_requested.emit(it.data(Qt.ItemDataRole.UserRole)))
        recent.addWidget(self.recent, 1)
        row.addLayout(recent, 3)
        col.addLayout(row, 4)
        col.addStretch(1)
        self.set_demo_available(False)

    def set_demo_available(self, on: bool) -> None:
        self.buttons["demo"].setVisible(on)

    def set_recent(self, files) -> None:
        """Recent project paths, newest first; missing files are listed greyed out."""
        self.recent.clear()
        for f in files:
            p = Path(f)
            it = QListWidgetItem(f"{p.name}    {p.parent}")
            it.setData(Qt.ItemDataRole.UserRole, str(f))
            it.setToolTip(str(f))
            if not p.exists():
                it.setFlags(it.flags() & ~Qt.ItemFlag.ItemIsEnabled)
                it.setToolTip(f"{f} (not found)")
            self.recent.addItem(it)
        if not files:
            it = QListWidgetItem("none yet")
            it.setFlags(Qt.ItemFlag.NoItemFlags)
            self.recent.addItem(it)
