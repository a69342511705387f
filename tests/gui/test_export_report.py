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


def test_the_export_proposes_a_file_in_the_project_folder_and_asks_the_operator_once(window, qtbot, answered,
                                                                                     tmp_path, monkeypatch):
    """The first export starts in the project's folder, the next ones in the folder the last
    report went to."""
    from pathlib import Path

    from PySide6.QtWidgets import QFileDialog
    win = window
    offered = []
    save = QFileDialog.getSaveFileName

    def look(parent, title, directory="", *a, **k):
        offered.append(directory)
        return save(parent, title, directory, *a, **k)
    monkeypatch.setattr(QFileDialog, "getSaveFileName", staticmethod(look))
    win.a_export.trigger()
    _written(win, qtbot, answered.path)
    assert offered == [str(win.demo.path.parent / f"{win.demo.path.stem}_report.pdf")]
    assert [k for k, _ in answered.asked] == ["file", "operator"]
    answered.asked.clear()
    answered.path = str(tmp_path / "second.json")
    win.a_export.trigger()                                 # the operator is remembered: not asked
    assert [k for k, _ in answered.asked] == ["file"]
    assert offered[-1] == str(Path(answered.path).with_name(f"{win.demo.path.stem}_report.pdf"))  # its folder too
    rep = _written(win, qtbot, answered.path)
    assert rep["header"]["operator"] == "A. Operator"
    assert "operator A. Operator" in win.statusBar().currentMessage()
    answered.name = "B. Other"                             # File ▸ Report operator… changes it
    file_menu = next(a.menu() for a in win.menuBar().actions() if a.text().replace("&", "") == "File")
    next(a for a in file_menu.actions() if a.text().replace("&", "") == "Report operator…").trigger()
    assert answered.asked[-1] == ("operator", "A. Operator")
    answered.path = str(tmp_path / "third.json")
    win.a_export.trigger()
    assert _written(win, qtbot, answered.path)["header"]["operator"] == "B. Other"
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


def test_window_and_command_line_write_the_same_report(window, qtbot, answered, tmp_path):
    """The same project reported from File ▸ Export report… and from ``prismstation report``:
    the same content but for the time it was made."""
    from prismstation.cli import main
    win = window
    win.a_export.trigger()
    from_window = _written(win, qtbot, answered.path)
    cli = tmp_path / "cli.json"
    assert main(["report", str(win.demo.path), "-o", str(cli), "--operator", answered.name]) == 0
    from_cli = json.loads(cli.read_text())
    for rep in (from_window, from_cli):
        rep["header"].pop("created")
    assert from_window["header"]["project"] == from_cli["header"]["project"] == str(win.demo.path)
    assert _same(from_window, from_cli)


def _same(a, b, path="") -> bool:
    """Equal structures, floats to 1e-9 relative (two fits of the same data)."""
    if isinstance(a, dict):
        assert a.keys() == b.keys(), path
        return all(_same(a[k], b[k], f"{path}.{k}") for k in a)
    if isinstance(a, list):
        assert len(a) == len(b), path
        return all(_same(x, y, f"{path}[{i}]") for i, (x, y) in enumerate(zip(a, b)))
    if isinstance(a, float) and isinstance(b, float):
        assert a == pytest.approx(b, rel=1e-9, abs=1e-9), path
        return True
    assert a == b, path
    return True


def test_an_edit_just_made_is_in_the_report(window, qtbot, answered):
    """Export right after an edit, before the background fit has caught up: the report is of
    the points as they are now."""
    win = window
    gcp = next(p.id for p in win.project.points.values() if p.kind == "GCP")
    win.project.set_kind(gcp, "ICP")
    assert win.solver.solution.revision != win.project.revision
    win.a_export.trigger()
    rep = _written(win, qtbot, answered.path)
    assert next(p for p in rep["points"] if p["id"] == gcp)["kind"] == "ICP"
    assert rep["statistics"]["ground"]["ICP"]["x"]["n"] == \
        sum(1 for p in win.solver.solution.points if p.kind == "ICP" and p.ground_residual is not None)


def test_the_reports_figures_are_freed_at_once(window, answered, tmp_path):
    """Each PDF export left its figures' widgets (~26 MB) until an event loop deleted them
    later: a script's exports, or the window's in a loop that does not return, piled up."""
    from PySide6.QtWidgets import QApplication
    before = len(QApplication.allWidgets())
    for k in range(2):
        assert window.export_report(str(tmp_path / f"r{k}.pdf"))
    assert len(QApplication.allWidgets()) == before
