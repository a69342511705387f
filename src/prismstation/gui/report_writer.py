"""The report as HTML or PDF through Qt's own writers.

:func:`write_document` writes, by extension, a self-contained ``.html`` (the document of
:func:`prismstation.io.report_html.report_html`, figures as PNG data URIs) or a ``.pdf`` (A4;
the ``QTextDocument`` painted page by page on a ``QPdfWriter`` with a footer naming the report
and "Page i of n"; table headings repeat on every page). The figures are the four plots of
:class:`prismstation.gui.plots.PlotsWidget`, drawn from the report's dict unless given.
"""
from __future__ import annotations

import base64
import os
import sys
from pathlib import Path

from prismstation.errors import InputError, WriteError
from prismstation.gui.plot_figures import render_images
from prismstation.gui.plots import PlotsWidget
from prismstation.io.atomic import write_atomic
from prismstation.io.report_html import MAX_DOCUMENT_POINTS, format_when, report_html

_app = None  # a QApplication made here for the command line, kept alive


def _ensure_app():
    """The running QApplication, or a new one (offscreen when there is no display)."""
    global _app
    from PySide6.QtWidgets import QApplication
    app = QApplication.instance()
    if app is None:
        if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                     or os.environ.get("WAYLAND_DISPLAY")):
            os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
        app = _app = QApplication([])
    return app


def render_figures(report: dict, size=(840, 540)) -> dict:
    """The four plots of ``report`` as QImages ``{name: QImage}`` (offscreen pyqtgraph)."""
    _ensure_app()
    w = PlotsWidget()
    try:
        w.set_report(report)
        return render_images(w, size)
    finally:
        import shiboken6
        shiboken6.delete(w)  # now, not from an event loop a script may not run


def _png_bytes(image) -> bytes:
    from PySide6.QtCore import QBuffer, QByteArray, QIODevice
    data = QByteArray()
    buf = QBuffer(data)
    buf.open(QIODevice.OpenModeFlag.WriteOnly)
    image.save(buf, "PNG")
    buf.close()
    return bytes(data.data())


def write_document(report: dict, path, figures: dict | None = None) -> None:
    """Write the residual report to ``path``: ``.html`` or ``.pdf`` (by extension).

    The document is made in memory, checked (a PDF begins with ``%PDF-`` and ends with
    ``%%EOF``, Qt's painter reported no failure) and written atomically
    (:func:`prismstation.io.atomic.write_atomic`: size checked, renamed into place): a
    failure is a :class:`~prismstation.errors.WriteError` and leaves no file.

    Parameters
    ----------
    report : dict
        As returned by :func:`prismstation.io.report.report_dict`.
    path : path-like
    figures : dict of str -> QImage, optional
        Plots to embed (keys as ``prismstation.gui.plots.PLOT_NAMES``); drawn from
        ``report`` when omitted.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in (".html", ".htm", ".pdf"):
        raise InputError(f"unknown document format {ext!r}: use .html or .pdf", path)
    _ensure_app()
    if figures is None:
        figures = render_figures(report)
    if ext in (".html", ".htm"):
        srcs = {n: "data:image/png;base64," + base64.b64encode(_png_bytes(im)).decode("ascii")
                for n, im in figures.items()}
        data = report_html(report, srcs).encode("utf-8")
    else:
        try:
            data = pdf_bytes(report, figures)
        except WriteError as exc:
            raise WriteError(exc.problem, path) from None
        problem = check_pdf(data)
        if problem:
            raise WriteError(f"cannot write: Qt's PDF writer {problem}", path)
    write_atomic(path, data, keep_backup=False)


def check_pdf(data: bytes) -> str:
    """What is wrong with the PDF ``data`` ("" when nothing): a PDF begins with ``%PDF-`` and
    its last line is ``%%EOF`` (a cut file has no end)."""
    if not data:
        return "wrote nothing"
    if not data.startswith(b"%PDF-"):
        return "wrote something that is not a PDF"
    if not data.rstrip().endswith(b"%%EOF"):
        return f"wrote an incomplete PDF ({len(data)} bytes, no %%EOF at the end)"
    return ""


def _footer_text(report: dict) -> str:
    h = report.get("header") or {}
    bits = [h.get("title") or "ALOS-PRISM orientation report"]
    if h.get("scene_id"):
        bits.append(f"scene {h['scene_id']}")
    bits.append(format_when(h.get("created")))
    return " · ".join(bits)


def pdf_bytes(report: dict, figures: dict) -> bytes:
    """The report as a PDF in memory: its QTextDocument painted page by page on an A4
    ``QPdfWriter``, with a footer on every page (the report's title, scene and date, and
    "Page i of n"). A painter that could not begin or end, or a page not added, is a
    :class:`~prismstation.errors.WriteError`."""
    from PySide6.QtCore import QBuffer, QByteArray, QIODevice
    data = QByteArray()
    buf = QBuffer(data)
    if not buf.open(QIODevice.OpenModeFlag.WriteOnly):
        raise WriteError("cannot write: Qt could not open a memory buffer for the PDF")
    try:
        _paint_pdf(report, buf, figures)
    finally:
        buf.close()
    return bytes(data.data())


def _paint_pdf(report: dict, device, figures: dict) -> None:
    from PySide6.QtCore import QMarginsF, QRectF, QSizeF, Qt, QUrl
    from PySide6.QtGui import (QColor, QFont, QPageLayout, QPageSize, QPainter, QPdfWriter,
                               QTextDocument)
    writer = QPdfWriter(device)
    h = report.get("header") or {}
    writer.setTitle(h.get("title") or "ALOS-PRISM orientation report")
    writer.setCreator(str(h.get("software") or report.get("program") or "prismstation"))
    writer.setPageLayout(QPageLayout(QPageSize(QPageSize.PageSizeId.A4),
                                     QPageLayout.Orientation.Portrait,
                                     QMarginsF(15, 15, 15, 12), QPageLayout.Unit.Millimeter))
    writer.setResolution(96)  # lay out in CSS pixels; images keep their own pixels
    doc = QTextDocument()
    doc.documentLayout().setPaintDevice(writer)
    for name, im in figures.items():
        doc.addResource(QTextDocument.ResourceType.ImageResource, QUrl(f"figure-{name}.png"), im)
    doc.setHtml(report_html(report, {name: f"figure-{name}.png" for name in figures},
                            max_points=MAX_DOCUMENT_POINTS))  # pages bounded, Ctrl+C between them
    page = writer.pageLayout().paintRectPixels(writer.resolution())
    footer = 26.0
    width, body = float(page.width()), float(page.height()) - footer
    doc.setPageSize(QSizeF(width, body))
    n = doc.pageCount()
    font = QFont("sans-serif")
    font.setPointSizeF(7.5)
    left = _footer_text(report)
    painter = QPainter()
    if not painter.begin(writer):
        raise WriteError("cannot write: Qt's PDF painter could not begin")
    ended = False
    try:
        for i in range(n):
            if i and not writer.newPage():
                raise WriteError(f"cannot write: Qt's PDF writer could not add page {i + 1}")
            painter.save()
            painter.translate(0, -i * body)
            doc.drawContents(painter, QRectF(0, i * body, width, body))
            painter.restore()
            painter.setPen(QColor(110, 110, 110))
            painter.setFont(font)
            painter.drawLine(0, int(body + 6), int(width), int(body + 6))
            box = QRectF(0, body + 8, width, footer - 8)
            painter.drawText(box, Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignVCenter, left)
            painter.drawText(box, Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter,
                             f"Page {i + 1} of {n}")
        ended = painter.end()  # writes the PDF's end (trailer, %%EOF) into the device
    finally:
        if painter.isActive():
            painter.end()
    del painter, doc
    del writer
    if not ended:
        raise WriteError("cannot write: Qt's PDF painter could not end the document")
