"""Render prismstation.svg to PNGs of 16–256 px with Qt's QSvgRenderer.

Run: ``QT_QPA_PLATFORM=offscreen .venv/bin/python resources/icons/render_icons.py``.
"""
from pathlib import Path

from PySide6.QtCore import Qt
from PySide6.QtGui import QGuiApplication, QImage, QPainter
from PySide6.QtSvg import QSvgRenderer

SIZES = (16, 24, 32, 48, 64, 128, 256)


def render(svg: Path, out_dir: Path, sizes=SIZES) -> list[Path]:
    """Write ``prismstation-<n>.png`` (n×n, ARGB, antialiased) for each size; returns the paths."""
    renderer = QSvgRenderer(str(svg))
    if not renderer.isValid():
        raise ValueError(f"{svg}: not a valid SVG")
    paths = []
    for n in sizes:
        img = QImage(n, n, QImage.Format_ARGB32)
        img.fill(Qt.transparent)
        p = QPainter(img)
        p.setRenderHint(QPainter.Antialiasing)
        p.setRenderHint(QPainter.SmoothPixmapTransform)
        renderer.render(p)
        p.end()
        path = out_dir / f"prismstation-{n}.png"
        if not img.save(str(path)):
            raise OSError(f"cannot write {path}")
        paths.append(path)
    return paths


if __name__ == "__main__":
    app = QGuiApplication.instance() or QGuiApplication([])
    here = Path(__file__).resolve().parent
    for p in render(here / "prismstation.svg", here):
        print(p)
