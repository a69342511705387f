"""Workflow through the real window: the first `demo` (a progress dialog at once), a new point
by coordinates (the views driven to it), an unreadable import file, rectification's summary,
the DSM validation dialog's prefill and its CRS name."""
from __future__ import annotations

import math
import shutil
import time

import pytest
from PySide6.QtCore import Qt, QTimer
from PySide6.QtWidgets import QApplication, QDialog, QDialogButtonBox, QMessageBox, QProgressDialog

from tests.gui.boxes import answer_next_box
from tests.gui.sim_project import copy_sim, make_sim
from tests.gui.test_height_kind import activate
from tests.gui.test_operator import key, settle
from tests.qt_windows import close_windows, open_window


@pytest.fixture(scope="module")
def sim_master(tmp_path_factory):
    return make_sim(tmp_path_factory.mktemp("flow"))


@pytest.fixture()
def win(qtbot, sim_master, tmp_path):
    d = copy_sim(sim_master, tmp_path / "sim")
    w = open_window(qtbot, d / "p.prismproj")
    w.sim = d
    yield w
    close_windows(qtbot, w)


def test_the_first_demo_shows_its_progress_at_once(qtbot, sim_master, tmp_path, monkeypatch):
    """`prismstation demo` the first time: the window and a progress dialog while the demo is
    made (it showed nothing for ~10 s), then the demo opens with its reference DEM."""
    from prismstation import cli
    from prismstation.cli import demo as demo_cli
    target = tmp_path / "demo"
    seen = {"progress": [], "made": False}

    def fake_ensure(directory=None, *, rebuild=False, progress=None):  # the real one simulates ~30 s
        for k in range(10):
            progress(k / 10, "simulating")
            time.sleep(0.1)
        from prismstation.io.project import load_project, save_project
        shutil.copytree(sim_master, target / "triplet")
        proj = load_project(target / "triplet" / "p.prismproj")
        proj.reference_dem = str(target / "triplet" / "srtm.tif")
        save_project(proj, target / "demo.prismproj")
        seen["made"] = True
        return target / "demo.prismproj"
    monkeypatch.setattr(demo_cli, "ensure_demo", fake_ensure)

    def watch(left=600):
        if left == 0:  # 30 s: whatever blocks is closed, the test fails below
            for w in QApplication.topLevelWidgets():
                w.close()
            return
        dlgs = [w for w in QApplication.topLevelWidgets() if isinstance(w, QProgressDialog) and w.isVisible()]
        if dlgs and not seen["made"]:
            seen["progress"].append(dlgs[0].windowTitle())
        wins = [w for w in QApplication.topLevelWidgets() if type(w).__name__ == "MainWindow" and w.isVisible()]
        if wins and wins[0].project is not None and wins[0].views.height_of is not None:
            seen["dem"] = wins[0].project.reference_dem
            wins[0].close()
            return
        QTimer.singleShot(50, lambda: watch(left - 1))
    QTimer.singleShot(50, watch)
    assert cli.main(["demo", "--dir", str(target)]) == 0
    assert seen["progress"] and seen["progress"][0] == "Making the demo project"
    assert seen["dem"] == str(target / "triplet" / "srtm.tif")


def test_new_point_by_coordinates_drives_the_views_to_it(qtbot, win):
    p = win.project
    ref = next(pid for pid, pt in p.points.items() if pt.kind == "ICP")
    r = p.points[ref]
    for iv in win.views.views.values():
        iv.fit()                                          # the overview, far from the point

    def fill():
        dlg = QApplication.activeModalWidget()
        assert dlg.id_edit.text() == "G10"                 # the next free number, not the count
        dlg.kind.setCurrentText("ICP")
        assert dlg.id_edit.text() == "I42"
        for w, v in ((dlg.e, r.E), (dlg.n, r.N), (dlg.h, r.H)):
            w.setFocus()
            qtbot.keyClicks(w, f"{v:.3f}")
        qtbot.keyClick(dlg.h, Qt.Key.Key_Return)
    QTimer.singleShot(300, fill)
    key(qtbot, win, "Ctrl+Shift+N")
    activate(qtbot, win)
    assert win.current == "I42"
    settle(qtbot, win)
    qtbot.wait(50)
    for v in "NFB":
        m = p.measurement(ref, v)                         # the point is where that ICP was measured
        cx, cy = win.views.views[v].center()
        assert math.hypot(cx - m.x, cy - m.y) < 5.0, (v, (cx, cy), (m.x, m.y))
        assert win.views.views[v].scale() <= 1.0
    key(qtbot, win, "Insert")
    assert win.current == "T21"                           # ties too: T01…T20, then T21


def test_an_unreadable_import_file_clears_the_last_one_and_says_why(qtbot, win):
    csv = win.sim / "good.csv"
    csv.write_text("id,E,N,H\nR1,539000.0,4561000.0,100.0\n")
    binary = win.sim / "image.png"
    binary.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)))
    seen = {}

    def drive():
        dlg = QApplication.activeModalWidget()
        for path in (csv, binary):
            dlg.path_edit.clear()
            dlg.path_edit.setFocus()
            qtbot.keyClicks(dlg.path_edit, str(path))
            qtbot.keyClick(dlg.path_edit, Qt.Key.Key_Return)
            seen[path.name] = (dlg.preview_model.rowCount(), dlg.errors(), dlg.status.text(),
                               dlg.buttons.button(QDialogButtonBox.StandardButton.Ok).isEnabled(),
                               len(dlg.combos))
        dlg.reject()
    QTimer.singleShot(300, drive)
    key(qtbot, win, "Ctrl+I")
    rows, errors, status, ok, combos = seen["good.csv"]
    assert rows == 1 and errors == [] and ok and combos
    rows, errors, status, ok, combos = seen["image.png"]
    assert rows == 0 and combos == 0 and not ok                       # nothing of good.csv stays
    assert errors == [f"{binary}: not a text file (not UTF-8): a point or measurement file is text "
                      "(CSV, QGIS .points, ODM gcp_list.txt or ASP .gcp)"]
    assert "codec" not in errors[0] and "1 problem" in status


def test_rectification_ends_with_a_summary(qtbot, win, monkeypatch):
    from prismstation.gui.tools import rectification as mod
    out = win.sim / "rect.tif"

    def fake_exec(dlg):
        dlg.view.setCurrentText("N")
        dlg.kind.setCurrentText("affine")
        dlg.resolution.setValue(10.0)
        dlg.out.setText(str(out))
        return QDialog.DialogCode.Accepted
    monkeypatch.setattr(mod.RectifyDialog, "exec", fake_exec)
    win.interactive = True
    try:
        seen = []
        answer_next_box(seen, tries=600)
        next(a for a in win.tools_menu.actions() if a.text() == "Rectify…").trigger()
        qtbot.waitUntil(lambda: bool(seen), timeout=30000)
    finally:
        win.interactive = False
    title, text = seen[0]
    assert title == "Rectify" and out.exists()
    assert text.startswith("Rectified view N through the affine transform (6 parameters, 9 GCPs; "
                           "planimetric RMSE ")
    assert "cells of 10 in WGS 84 / UTM zone 29N (EPSG:32629)." in text and "PROJCRS" not in text


def test_dsm_validation_prefills_the_projects_files_and_names_the_crs(qtbot, win, monkeypatch):
    from prismstation.gui.tools import dsm_validation as mod
    win.load_reference_dem(win.sim / "srtm.tif", wait=True)
    shutil.copy(win.sim / "truth_dem.tif", win.sim / "dsm.tif")   # a DSM beside the project
    offered = {}

    def fake_exec(dlg):
        offered.update(dlg.values())
        return QDialog.DialogCode.Accepted
    monkeypatch.setattr(mod.DsmDialog, "exec", fake_exec)
    tool = win.tools["dsm_validation"]
    next(a for a in win.tools_menu.actions() if a.text() == "Validate DSM…").trigger()
    assert offered["dsm"] == str(win.sim / "dsm.tif")
    assert offered["reference"] == str((win.sim / "srtm.tif").resolve())
    assert (offered["dsm_height"], offered["reference_height"]) == ("ellipsoidal", "orthometric")
    assert offered["geoid_constant"] == 55.0                        # the project's geoid
    qtbot.waitUntil(lambda: tool.panel.validation is not None, timeout=60000)
    title = tool.panel.title.text()
    assert "WGS 84 / UTM zone 29N (EPSG:32629)" in title and "PROJCRS" not in title, title


def test_validate_dsm_offers_the_dsm_just_exported_with_the_heights_it_records(qtbot, win, monkeypatch):
    """Export DSM (orthometric: the project's points are), then Tools ▸ Validate DSM…: the
    dialog offers that DSM, its heights orthometric as the file records them (not asked), and
    the bias against the reference is the terrain's, not the geoid's 55 m (it was −54.7 m)."""
    from prismstation.gui.tools import dsm_tool, dsm_validation
    win.load_reference_dem(win.sim / "srtm.tif", wait=True)
    out = win.sim / "exported.tif"

    def export_exec(dlg):
        assert dlg.orthometric.isChecked()                         # the project's points' kind
        dlg.path.setText(str(out))
        dlg.whole.setChecked(True)
        dlg.posting.setValue(20.0)
        return QDialog.DialogCode.Accepted
    monkeypatch.setattr(dsm_tool.DsmDialog, "exec", export_exec)
    next(a for a in win.tools_menu.actions() if a.text() == "Export &DSM…").trigger()
    qtbot.waitUntil(lambda: win.statusBar().currentMessage().startswith("Wrote"), timeout=120000)  # its end
    offered = {}

    def validate_exec(dlg):
        offered.update(dlg.values())
        offered["asked"] = {k: c.isEnabled() for k, c in dlg.kinds.items()}
        offered["notes"] = {k: n.text() for k, n in dlg.kind_notes.items()}
        return QDialog.DialogCode.Accepted
    monkeypatch.setattr(dsm_validation.DsmDialog, "exec", validate_exec)
    tool = win.tools["dsm_validation"]
    next(a for a in win.tools_menu.actions() if a.text() == "Validate DSM…").trigger()
    assert offered["dsm"] == str(out)
    assert offered["dsm_height"] == "orthometric" and offered["asked"]["dsm_height"] is False
    assert offered["notes"]["dsm_height"] == "recorded in the file"
    # the reference (an SRTM-like GeoTIFF with a 2-D CRS) does not say: asked, orthometric offered
    assert offered["reference_height"] == "orthometric" and offered["asked"]["reference_height"]
    assert offered["notes"]["reference_height"] == "the file does not say: choose"
    qtbot.waitUntil(lambda: tool.panel.validation is not None, timeout=60000)
    assert abs(tool.panel.validation.overall.bias) < 10.0, tool.panel.validation.overall
