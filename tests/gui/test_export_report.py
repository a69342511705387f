"""File ▸ Export report… driven as an operator does: the menu action triggered and Ctrl+E pressed,
with the save dialog (and the operator prompt) answered; the file must be written and the window
must say so."""
from __future__ import annotations

import json

import pytest
from PySide6.QtCore import Qt


@pytest.fixture()
def answered(monkeypatch, tmp_path):
    """Patch the save dialog to answer ``answered.path`` and the operator prompt ``answered.name``;
    records the prompts' calls."""
    from PySide6.QtWidgets import QFileDialog, QInputDialog

    class Answers:
        path = str(tmp_path / "report.json")
        name = "A. Operator"
        asked: list = []

    def save_name(parent, title, directory="", filt="", *a, **k):
        Answers.asked.append(("file", title))
        return Answers.path, "JSON (*.json)"

    def get_text(parent, title, label, *a, **k):
        Answers.asked.append(("operator", k.get("text", a[1] if len(a) > 1 else "")))
        return Answers.name, True

    monkeypatch.setattr(QFileDialog, "getSaveFileName", staticmethod(save_name))
    monkeypatch.setattr(QInputDialog, "getText", staticmethod(get_text))
    return Answers


def _written(win, qtbot, path):
    from pathlib import Path
    qtbot.waitUntil(lambda: Path(path).exists(), timeout=5000)
    assert "Report written" in win.statusBar().currentMessage()
    return json.loads(Path(path).read_text())


def test_menu_action_writes_the_report(window, qtbot, answered):
    win = window
    file_menu = next(a.menu() for a in win.menuBar().actions() if a.text().replace("&", "") == "File")
    export = next(a for a in file_menu.actions() if a.text().replace("&", "").startswith("Export report"))
    export.trigger()
    rep = _written(win, qtbot, answered.path)
    assert rep["header"]["operator"] == "A. Operator"
    assert [k for k, _ in answered.asked] == ["file", "operator"]
    assert len(rep["points"]) == len(win.solver.solution.points)


def test_ctrl_e_writes_the_report(window, qtbot, answered, tmp_path):
    win = window
    answered.path = str(tmp_path / "keyed.csv")
    qtbot.keyClick(win, Qt.Key.Key_E, Qt.KeyboardModifier.ControlModifier)
    from pathlib import Path
    qtbot.waitUntil(lambda: Path(answered.path).exists(), timeout=5000)
    assert "Report written" in win.statusBar().currentMessage()
    head = Path(answered.path).read_text().splitlines()[0].split(",")
    assert head[:3] == ["id", "kind", "view"]


def test_the_operator_prompt_remembers_the_name_and_cancel_writes_nothing(window, qtbot, answered,
                                                                         tmp_path):
    win = window
    win.a_export.trigger()
    _written(win, qtbot, answered.path)
    answered.asked.clear()
    answered.path = str(tmp_path / "second.json")
    win.a_export.trigger()
    assert ("operator", "A. Operator") in answered.asked  # offered the last name given
    _written(win, qtbot, answered.path)
    answered.path = ""                                     # the save dialog cancelled
    win.statusBar().clearMessage()
    win.a_export.trigger()
    assert win.statusBar().currentMessage() == ""


def test_a_failed_export_is_shown_not_raised(window, qtbot, answered, monkeypatch, tmp_path):
    from PySide6.QtWidgets import QMessageBox
    shown = []
    monkeypatch.setattr(QMessageBox, "warning", staticmethod(lambda p, t, m, *a, **k: shown.append(m)))
    answered.path = str(tmp_path / "report.docx")
    window.a_export.trigger()
    assert shown and "unknown report format" in shown[0]
