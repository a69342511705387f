"""The status bar through a tool job's life, driven by the progress dialog's Cancel button:
no percentage is left on it after a cancel."""
from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtTest import QTest
from PySide6.QtWidgets import QProgressDialog, QPushButton

from tests.gui.tools.test_dsm_tool import _answer, _menu_action


def test_no_percentage_stays_on_the_status_bar_after_cancel(qtbot, window, tmp_path, job_outcome, monkeypatch):
    """"DSM: 7 %" stayed after Cancel: the engine notices a cancel between batches of tiles
    (a minute on a large scene), and its reports until then kept writing percentages."""
    out = tmp_path / "dsm.tif"
    _answer(monkeypatch, [], path=out, posting=5.0, whole=True)
    _menu_action(window).trigger()
    job = window.tools["dsm"].job
    progressed = []
    job.progress.connect(lambda f, m: progressed.append(f))
    qtbot.waitUntil(lambda: any(f > 0.0 for f in progressed), timeout=60000)
    shown = []
    window.statusBar().messageChanged.connect(shown.append)
    dlg = next(d for d in window.findChildren(QProgressDialog) if d.isVisible())
    QTest.mouseClick(next(b for b in dlg.findChildren(QPushButton) if b.text() == "Cancel"),
                     Qt.MouseButton.LeftButton)
    assert "cancelling" in window.statusBar().currentMessage()
    kind, _ = job_outcome(job, timeout=60000)
    assert kind == "cancelled"
    qtbot.wait(50)
    assert window.statusBar().currentMessage() == "DSM: cancelled"
    assert not [m for m in shown if "%" in m], shown
