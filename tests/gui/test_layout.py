"""The window's layout and menus driven through the real menus: Rectify with its panel closed,
every dock in View ▸ Panels, a window that stays on the screen as panels open and close."""
from __future__ import annotations

from pathlib import Path

from PySide6.QtWidgets import QDialog, QDockWidget

from tests.gui.test_every_action import every_action


def action(win, path: str):
    """The QAction at menu path ``"Tools ▸ Rectify…"``."""
    found = [a for n, a in every_action(win) if n == path]
    assert found, f"no action {path!r}"
    return found[0]


def test_rectify_with_the_transforms_panel_closed(qtbot, window, tmp_path, monkeypatch):
    from prismstation.gui.tools import rectification
    win = window
    assert not win.docks["transforms"].isVisible()
    out = tmp_path / "n_rect.tif"

    def exec_(dialog):
        dialog.view.setCurrentText("N")
        dialog.kind.setCurrentText("affine")
        dialog.out.setText(str(out))
        return QDialog.DialogCode.Accepted

    monkeypatch.setattr(rectification.RectifyDialog, "exec", exec_)
    messages = []
    win.statusBar().messageChanged.connect(messages.append)
    tool = win.tools["rectify"]
    action(win, "Tools ▸ Rectify…").trigger()
    assert not any("Cannot rectify" in m for m in messages), messages
    assert tool.job is not None
    qtbot.waitUntil(lambda: out.is_file() and any(m.startswith("Wrote") for m in messages),
                    timeout=30000)
    assert not win.docks["transforms"].isVisible()


def test_every_dock_is_in_view_panels(window):
    win = window
    panels = {a for n, a in every_action(win) if n.startswith("View ▸ Panels ▸ ")}
    docks = win.findChildren(QDockWidget)
    assert len(docks) >= 8
    missing = [d.windowTitle() for d in docks if d.toggleViewAction() not in panels]
    assert missing == []
    for title in ("Point transfer", "Reference DEM patches"):
        d = next(d for d in docks if d.windowTitle() == title)
        action(win, f"View ▸ Panels ▸ {title}").trigger()
        assert d.isVisible()


def test_panels_open_and_close_within_the_screen(qtbot, window):
    """Every panel opened from View ▸ Panels: the window keeps its 1920 × 1080 (it grew to
    1600 × 1134 and stayed so); closed again, nothing is left changed."""
    win = window
    win.resize(1920, 1080)
    qtbot.wait(20)
    panels = [(n, a) for n, a in every_action(win) if n.startswith("View ▸ Panels ▸ ")]
    hidden = [(n, a) for n, a in panels if not a.isChecked()]
    assert len(hidden) >= 5
    for n, a in hidden:
        a.trigger()
        qtbot.wait(5)
        assert (win.width(), win.height()) == (1920, 1080), n
    for n, a in hidden:
        a.trigger()
    qtbot.wait(20)
    assert (win.width(), win.height()) == (1920, 1080)


def test_1280x720_keeps_its_size_the_model_readable_and_the_toolbar_whole(qtbot, window):
    win = window
    win.resize(1280, 720)
    win.default_layout()
    qtbot.wait(50)
    assert (win.width(), win.height()) == (1280, 720)
    rows = win.panel.text.viewport().height() / win.panel.sections._row_height()
    assert rows >= 6, f"the model panel shows {rows:.1f} lines"
    tb = win.toolbar
    assert tb.sizeHint().width() <= tb.width()  # no overflow (») button
    assert win.accuracy.isVisible() and win.accuracy.height() < 40


def test_rectify_with_no_output_file_says_so_and_stays_open(qtbot, window, tmp_path):
    """The real dialog, driven by its OK button: a file is suggested beside the project; with
    the name cleared, OK says a file is needed and the dialog stays (it closed, writing nothing)."""
    from PySide6.QtCore import QTimer
    from PySide6.QtWidgets import QApplication, QDialogButtonBox, QMessageBox

    from prismstation.gui.tools.rectification import RectifyDialog
    win = window
    out = tmp_path / "rect.tif"
    seen = {}

    def drive():
        dlg = QApplication.activeModalWidget()
        if not isinstance(dlg, RectifyDialog):
            QTimer.singleShot(20, drive)
            return
        dlg.view.setCurrentText("N")
        seen["suggested"], seen["kind"] = dlg.out.text(), dlg.kind.currentText()
        ok = dlg.findChild(QDialogButtonBox).button(QDialogButtonBox.StandardButton.Ok)
        dlg.out.clear()

        def answer():
            box = QApplication.activeModalWidget()
            if isinstance(box, QMessageBox):
                seen["said"] = (box.windowTitle(), box.text())
                box.accept()
            else:
                QTimer.singleShot(20, answer)
        QTimer.singleShot(0, answer)
        ok.click()                                  # (the box's own loop runs in here)
        seen["open after"] = dlg.isVisible()
        dlg.out.setText(str(out))
        ok.click()
    QTimer.singleShot(0, drive)
    action(win, "Tools ▸ Rectify…").trigger()
    project = Path(win.files.path)
    assert seen["suggested"] == str(project.with_name(f"{project.stem}_N_{seen['kind']}.tif"))
    assert seen["said"] == ("Rectify", "Choose the output GeoTIFF: a file name is needed.")
    assert seen["open after"]
    qtbot.waitUntil(lambda: out.is_file(), timeout=30000)
