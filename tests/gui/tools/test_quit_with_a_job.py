"""X / Ctrl+Q while a tool's job runs: the window asks whether to cancel the job and quit (it
used to ignore them: the progress dialog was window-modal), from the window and from the
progress dialog itself."""
from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QApplication, QDialog, QMessageBox, QProgressDialog

from tests.gui.boxes import answer_next_box


def test_ctrl_q_during_a_job_asks_to_cancel_it_and_quit(qtbot, window, sim, monkeypatch):
    from prismstation.gui.tools import dem_orientation as mod

    def fake_exec(dlg):
        dlg.path.setText(str(sim / "srtm.tif"))
        return QDialog.DialogCode.Accepted
    monkeypatch.setattr(mod.OrientDialog, "exec", fake_exec)
    tool = window.tools["dem_orientation"]
    tool.a_orient.trigger()
    job = tool.job
    qtbot.waitUntil(lambda: job.last[0] > 0, timeout=30000)
    dlg = next(w for w in QApplication.topLevelWidgets() if isinstance(w, QProgressDialog) and w.isVisible())
    window.interactive = True
    try:
        asked = []
        answer_next_box(asked, QMessageBox.StandardButton.No)
        dlg.activateWindow()                   # (a window manager activates it when it shows)
        qtbot.waitUntil(lambda: QApplication.activeWindow() is dlg, timeout=2000)
        qtbot.keyClick(dlg, Qt.Key.Key_Q, Qt.KeyboardModifier.ControlModifier)   # from the progress dialog
        assert len(asked) == 1
        title, text = asked[0]
        assert title == "Quit" and text.startswith("A job is running — Orientation from the reference DEM: ")
        assert text.endswith("Cancel it and quit?")
        assert window.isVisible() and job.isRunning() and not job.is_cancelled()
        answer_next_box(asked, QMessageBox.StandardButton.Yes)
        window.activateWindow()
        qtbot.waitUntil(lambda: QApplication.activeWindow() is window, timeout=2000)
        qtbot.keyClick(window, Qt.Key.Key_Q, Qt.KeyboardModifier.ControlModifier)  # from the window
        assert len(asked) == 2 and not window.isVisible()
        assert job.is_cancelled() and not job.isRunning()
    finally:
        window.interactive = False
    assert window.project.settings.orientation == "gcp"


def test_closing_the_progress_dialog_then_quitting(qtbot, window, sim, monkeypatch):
    """The report's sequence with a real tool job: its progress dialog closed by its X (the job
    is cancelled), then Ctrl+Q: no question (no job runs), the window closes, the job is done."""
    from prismstation.gui.tools import dem_orientation as mod

    def fake_exec(dlg):
        dlg.path.setText(str(sim / "srtm.tif"))
        return QDialog.DialogCode.Accepted
    monkeypatch.setattr(mod.OrientDialog, "exec", fake_exec)
    tool = window.tools["dem_orientation"]
    tool.a_orient.trigger()
    job = tool.job
    qtbot.waitUntil(lambda: job.last[0] > 0, timeout=30000)
    dlg = next(w for w in QApplication.topLevelWidgets() if isinstance(w, QProgressDialog) and w.isVisible())
    dlg.close()
    assert job.is_cancelled()
    window.interactive = True
    try:
        asked = []
        stop = answer_next_box(asked, QMessageBox.StandardButton.No, tries=20)
        window.activateWindow()
        qtbot.waitUntil(lambda: QApplication.activeWindow() is window, timeout=2000)
        qtbot.keyClick(window, Qt.Key.Key_Q, Qt.KeyboardModifier.ControlModifier)
        assert not window.isVisible() and not job.isRunning()
        assert asked == []                              # a cancelled job is not asked about
    finally:
        stop()  # (its poller must not answer a later test's box)
        window.interactive = False


def test_the_quit_question_follows_the_job_and_closes_when_it_ends(qtbot, window):
    """The question keeps the job's progress up to date; the job ending while it is open
    closes it unanswered (nothing is left to cancel): the window stays, the job's outcome shows."""
    import threading

    from PySide6.QtCore import QTimer

    from prismstation.gui.tools._worker import run_with_progress
    release, reported = threading.Event(), threading.Event()

    def work(progress):
        progress(0.40, "matching")
        reported.wait(10)
        progress(0.97, "writing")
        release.wait(20)
        return "out.tif"
    outcome = []

    def done(path):  # as the DSM tool's: a box saying what was written
        box = QMessageBox(QMessageBox.Icon.Information, "DSM", f"Wrote {path}", QMessageBox.StandardButton.Ok,
                          window)
        QTimer.singleShot(50, box.accept)
        outcome.append(path)
        box.exec()
    job = run_with_progress(window.tool_context, "DSM", work, done)
    qtbot.waitUntil(lambda: job.last[0] == 0.40, timeout=10000)
    texts = []

    def watch(left=300):  # every 30 ms, 9 s at most: then No (a question that never changes)
        w = QApplication.activeModalWidget()
        quit_box = isinstance(w, QMessageBox) and w.windowTitle() == "Quit" and w.isVisible()
        if quit_box:
            texts.append(w.text())
            if not reported.is_set():
                reported.set()      # the job reports 97 % while the question is open ...
            elif "97%" in w.text():
                release.set()       # ... then ends
            if left == 0:
                w.button(QMessageBox.StandardButton.No).click()
                release.set()
                return
        if not release.is_set() or quit_box:
            QTimer.singleShot(30, lambda: watch(left - 1))
    window.interactive = True
    try:
        QTimer.singleShot(30, watch)
        window.activateWindow()
        qtbot.waitUntil(lambda: QApplication.activeWindow() is window, timeout=2000)
        qtbot.keyClick(window, Qt.Key.Key_Q, Qt.KeyboardModifier.ControlModifier)  # returns when it closes
    finally:
        window.interactive = False
    assert texts[0] == "A job is running — DSM: 40% (matching).\n\nCancel it and quit?"
    assert any(t.startswith("A job is running — DSM: 97% (writing).") for t in texts)
    assert window.isVisible() and not job.isRunning() and not job.is_cancelled()
    assert "nothing was cancelled" in window.statusBar().currentMessage()
    qtbot.waitUntil(lambda: bool(outcome), timeout=5000)  # the outcome, after the question
