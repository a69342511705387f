"""The reference DEM kept in the project (saved, reopened, found by the DSM tool), a second
window on the same project (no "recover" of the first one's journal), a non-DEM chosen as the
reference (a message box) — through the real window."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from PySide6.QtWidgets import QDialog, QFileDialog, QMessageBox

from tests.gui.boxes import answer_next_box
from tests.gui.sim_project import copy_sim, make_sim
from tests.gui.test_operator import key, settle
from tests.qt_windows import new_window, open_window


@pytest.fixture(scope="module")
def sim_master(tmp_path_factory):
    return make_sim(tmp_path_factory.mktemp("dem"))


def close_windows(qtbot, *wins):
    """Close (the windows stay for pytest-qt's own teardown)."""
    for w in wins:
        w.undo_stack.setClean()
        w.close()
    qtbot.wait(10)


@pytest.fixture()
def sim(sim_master, tmp_path):
    return copy_sim(sim_master, tmp_path / "sim")


def choose_dem(qtbot, win, monkeypatch, path):
    """View ▸ Reference DEM…, the file dialog answered with ``path``."""
    monkeypatch.setattr(QFileDialog, "getOpenFileName", staticmethod(lambda *a, **k: (str(path), "")))
    win.a_dem.trigger()
    win.dem_loader.wait()


def test_the_reference_dem_is_kept_in_the_project(qtbot, sim, monkeypatch):
    win = open_window(qtbot, sim / "p.prismproj")
    try:
        assert win.project.reference_dem is None and win.undo_stack.isClean()
        choose_dem(qtbot, win, monkeypatch, sim / "srtm.tif")
        assert win.project.reference_dem == str((sim / "srtm.tif").resolve())
        # the status bar says what the DEM holds: its own cells and noise (the simulator's 90 m
        # reference carries 2 m of noise; its relief finer than three cells reads as more: 3.2)
        said = win.statusBar().currentMessage()
        assert said.startswith("Reference DEM: ") and "cells 90 × 9" in said, said
        noise = float(said.split("its own noise ")[1].split(" m")[0])
        assert 1.5 < noise < 6.0, said
        assert not win.undo_stack.isClean() and win.isWindowModified()   # a change to save
        key(qtbot, win, "Ctrl+S")
        assert win.undo_stack.isClean()
    finally:
        close_windows(qtbot, win)
    doc = json.loads((sim / "p.prismproj").read_text())
    assert doc["format"] == "prismstation-project/3" and doc["reference_dem"] == "srtm.tif"

    win = open_window(qtbot, sim / "p.prismproj")      # reopened: loaded again, found by the DSM tool
    try:
        qtbot.waitUntil(lambda: win.views.height_of is not None, timeout=20000)
        assert win.undo_stack.isClean()                # loading it is no change
        seen = []

        def look(dlg):
            seen.append(dlg.reference.text())
            return QDialog.DialogCode.Rejected
        from prismstation.gui.tools import dsm_tool
        monkeypatch.setattr(dsm_tool.DsmDialog, "exec", look)
        win.tools["dsm"].action.trigger()
        assert seen == ["the loaded reference DEM (srtm.tif)"]
    finally:
        close_windows(qtbot, win)


def test_a_project_of_format_1_still_opens(qtbot, sim):
    doc = json.loads((sim / "p.prismproj").read_text())
    doc["format"] = "prismstation-project/1"
    doc.pop("reference_dem", None)
    (sim / "p.prismproj").write_text(json.dumps(doc))
    win = open_window(qtbot, sim / "p.prismproj")
    try:
        assert win.project.reference_dem is None and len(win.project.points) == len(doc["points"])
    finally:
        close_windows(qtbot, win)


def test_a_file_that_is_no_dem_is_a_message_box(qtbot, sim, monkeypatch):
    win = open_window(qtbot, sim / "p.prismproj")
    try:
        win.interactive = win.files.interactive = True
        bad = sim / "notes.txt"
        bad.write_text("not a raster\n")
        seen = []
        answer_next_box(seen)
        choose_dem(qtbot, win, monkeypatch, bad)
        qtbot.waitUntil(lambda: bool(seen), timeout=5000)
        title, text = seen[0]
        assert title == "Reference DEM" and "notes.txt" in text and "Traceback" not in text, text
        assert win.project.reference_dem is None
        win.interactive = win.files.interactive = False
    finally:
        close_windows(qtbot, win)


HOLD = """
import sys, time
from prismstation.io.lock import ProjectLock
ProjectLock(sys.argv[1]).acquire()
print("held", flush=True)
time.sleep(60)
"""


def test_a_second_window_does_not_recover_the_first_ones_journal(qtbot, sim, tmp_path):
    """Another process works on the project (its lock, its journal of unsaved edits): this
    window refuses to open it, with the reason, and never offers its journal for recovery."""
    project = sim / "p.prismproj"
    (sim / "p.prismproj.recovery").write_text(project.read_text())   # the other one's journal
    other = subprocess.Popen([sys.executable, "-c", HOLD, str(project)], stdout=subprocess.PIPE, text=True,
                             env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    try:
        assert other.stdout.readline().strip() == "held"
        win = new_window(qtbot)
        try:
            win.files.interactive = True
            seen = []
            answer_next_box(seen)
            assert not win.open_project(project)
            assert len(seen) == 1, seen
            title, text = seen[0]
            assert title == "Open project" and "is open in another prismstation window" in text
            assert f"process {other.pid}" in text and "Recover" not in title
            assert win.project is None and (sim / "p.prismproj.recovery").exists()
        finally:
            win.files.interactive = False
            close_windows(qtbot, win)
    finally:
        other.kill()
        other.wait()
    # the other process is gone (as after a crash): its lock is stale, its journal is offered
    win = new_window(qtbot)
    try:
        win.files.interactive = True
        seen = []
        answer_next_box(seen, QMessageBox.StandardButton.No)
        assert win.open_project(project)
        assert seen and seen[0][0] == "Recover"
        assert json.loads((sim / "p.prismproj.lock").read_text())["pid"] == os.getpid()
    finally:
        win.files.interactive = False
        close_windows(qtbot, win)
    assert not (sim / "p.prismproj.lock").exists()          # released at close


def test_a_second_window_leaves_the_first_ones_untitled_journal_alone(qtbot, sim, temp_settings):
    """An untitled project's journal lives in the settings folder: another live window's is not
    offered at start; once that window is gone (a crash), it is."""
    win = new_window(qtbot)
    try:
        from prismstation.gui.project_io import autosave_path, untitled_path
        base = untitled_path()
        base.parent.mkdir(parents=True, exist_ok=True)
        autosave_path(None).write_text((sim / "p.prismproj").read_text().replace(
            '"scene": "scene.json"', f'"scene": "{sim / "scene.json"}"'))
        other = subprocess.Popen([sys.executable, "-c", HOLD, str(base)], stdout=subprocess.PIPE, text=True,
                                 env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
        try:
            assert other.stdout.readline().strip() == "held"
            win.files.interactive = True
            seen = []
            stop = answer_next_box(seen, QMessageBox.StandardButton.No, tries=10)
            assert not win.files.recover_untitled()
            qtbot.wait(700)
            stop()            # under load its polls outlast the wait: it must not answer the next box
            assert seen == []                                   # not even asked
        finally:
            other.kill()
            other.wait()
        seen = []
        answer_next_box(seen, QMessageBox.StandardButton.Yes)
        assert win.files.recover_untitled()
        assert seen and seen[0][0] == "Recover" and win.project is not None
    finally:
        win.files.interactive = False
        close_windows(qtbot, win)
