"""Every menu and toolbar action of a loaded project, triggered as the operator would: none may
raise. File dialogs and message boxes are answered (a save dialog gives a fresh file, an open
dialog is cancelled, a tool's own dialog is accepted with its defaults), so the code behind
each dialog runs too. A new action is covered the moment it is in a menu or the toolbar."""
from __future__ import annotations

import itertools

import pytest
import shiboken6
from PySide6.QtWidgets import (QDialog, QFileDialog, QInputDialog, QMenu, QMessageBox,
                               QToolBar)


def walk_menu(menu: QMenu, path: str):
    for a in menu.actions():
        if a.isSeparator():
            continue
        name = f"{path} ▸ {a.text().replace('&', '')}"
        if a.menu() is not None:
            yield from walk_menu(a.menu(), name)
        else:
            yield name, a


def every_action(win):
    """``[(name, QAction)]``: the menus (submenus walked), then the toolbars."""
    out = []
    for top in win.menuBar().actions():
        out += list(walk_menu(top.menu(), top.text().replace("&", "")))
    for tb in win.findChildren(QToolBar):
        out += [(f"toolbar {tb.windowTitle()} ▸ {a.text()}", a) for a in tb.actions()
                if not a.isSeparator() and a.text()]
    return out


@pytest.fixture()
def answered(monkeypatch, tmp_path):
    """Every file dialog and message box answered without a screen; returns what was asked."""
    asked = []
    n = itertools.count()

    def save_name(parent, caption="", directory="", filt="", *a, **k):
        asked.append(("save", caption))
        ext = filt.split("*")[1].split(")")[0].split(" ")[0] if "*" in filt else ".out"
        return str(tmp_path / f"answer{next(n)}{ext}"), filt

    def open_name(parent, caption="", *a, **k):
        asked.append(("open", caption))
        return "", ""

    def box(kind, answer):
        def f(parent, title="", *a, **k):
            asked.append((kind, title))
            return answer
        return f

    B = QMessageBox.StandardButton
    monkeypatch.setattr(QFileDialog, "getSaveFileName", save_name)
    monkeypatch.setattr(QFileDialog, "getOpenFileName", open_name)
    monkeypatch.setattr(QFileDialog, "getOpenFileNames", lambda *a, **k: ([], ""))
    monkeypatch.setattr(QFileDialog, "getExistingDirectory", box("dir", ""))
    monkeypatch.setattr(QInputDialog, "getText", box("text", ("", False)))
    for name, answer in (("question", B.No), ("warning", B.Ok), ("information", B.Ok),
                         ("critical", B.Ok), ("about", None)):
        monkeypatch.setattr(QMessageBox, name, box(name, answer))
    monkeypatch.setattr(QDialog, "exec", lambda self: (asked.append(("dialog", self.windowTitle())),
                                                       QDialog.DialogCode.Accepted)[1])
    return asked


def trigger_all(qtbot, win, actions) -> list[str]:
    """Trigger every enabled action (Quit last); ``["name: Error: message"]`` of what raised."""
    quit_last = [(n, a) for n, a in actions if "Quit" in n]
    failures = []
    for name, a in [x for x in actions if "Quit" not in x[0]] + quit_last:
        if not shiboken6.isValid(a) or not a.isEnabled():  # a recent-files entry renewed
            continue
        if "Quit" in name and win.project is not None:
            win.files.save()  # the unsaved-changes prompt would (rightly) keep it open
        with qtbot.capture_exceptions() as exceptions:
            a.trigger()
            qtbot.wait(30)
        failures += [f"{name}: {e[0].__name__}: {e[1]}" for e in exceptions]
        if "Quit" not in name and win.current is None and win.project and win.project.points:
            win.set_current(next(iter(win.project.points)))
    return failures


def test_no_menu_or_toolbar_action_raises(qtbot, window, answered):
    win = window
    win.set_current(next(iter(win.project.points)))
    actions = every_action(win)
    names = [n for n, _ in actions]
    assert len(actions) > 40 and any("Rectify" in n for n in names), names
    assert trigger_all(qtbot, win, actions) == []
    assert not win.isVisible()  # File ▸ Quit closed it (nothing was left to save)


@pytest.fixture()
def no_project_window(qtbot):
    from tests.qt_windows import close_windows, new_window
    win = new_window(qtbot)
    yield win
    close_windows(qtbot, win)


def test_no_action_raises_on_the_start_page(qtbot, no_project_window, answered):
    win = no_project_window
    assert win.project is None and win.central.currentWidget() is win.start_page
    assert trigger_all(qtbot, win, every_action(win)) == []
    assert not win.isVisible()
