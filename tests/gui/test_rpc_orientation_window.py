"""The window keeps the same RPC orientation as the command line: on the pair of
:mod:`tests.cli.test_rpc_orientation` (real SRTM relief, the right RPC 40 px off along the
lines), the reference DEM chosen through View ▸ Reference DEM…, its σ set in the model panel
and the project saved through File ▸ Save store the settings and the fit's result; ``fit``
from the command line then finds nothing to store (the same orientation) and ``dsm`` reads it."""
from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import Qt
from PySide6.QtTest import QTest
from PySide6.QtWidgets import QFileDialog

from prismstation.cli import main
from prismstation.io.project import load_project
from tests.cli.test_rpc_orientation import LINE_BIAS_PX, dsm_minus_truth, make_pair
from tests.qt_windows import close_windows, open_window


@pytest.fixture()
def pair_window(qtbot, tmp_path, shared_data):
    d, world, srtm = make_pair(tmp_path, shared_data / "srtm" / "N44E005.hgt")
    win = open_window(qtbot, d / "p.prismproj")
    yield d, world, srtm, win
    close_windows(qtbot, win)


def test_panel_settings_saved_and_read_by_the_command_line(pair_window, monkeypatch, capsys, qtbot):
    d, world, srtm, win = pair_window
    panel = win.panel
    assert panel.ref_sigma.isVisible() and panel.use_gcps.isVisible() and panel.use_gcps.isChecked()
    sol = win.solver.refit_now()
    assert "Heights not fixed" in panel.plain_text() and "img1: b0" in panel.plain_text()

    # View ▸ Reference DEM…, as the operator picks the file
    monkeypatch.setattr(QFileDialog, "getOpenFileName", lambda *a, **k: (str(srtm), ""))
    win.a_dem.trigger()
    win.dem_loader.wait()
    qtbot.waitUntil(lambda: win.solver.height_of is not None, timeout=10000)
    # the reference's σ typed into the model panel
    panel.ref_sigma.selectAll()
    QTest.keyClicks(panel.ref_sigma, "6")
    QTest.keyClick(panel.ref_sigma, Qt.Key.Key_Return)
    assert win.project.settings.reference_sigma_m == 6.0
    sol = win.solver.refit_now()
    assert sol.model.held == 49 and "Heights not fixed" not in panel.plain_text()
    assert "49 (σ 6 m ⊕ slope)" in panel.plain_text()
    b0 = sol.bias["img1"].params[1]
    assert abs(b0 + LINE_BIAS_PX) < max(3 * sol.bias["img1"].std[1], 0.5)

    # a bias model of one view, chosen as the operator does, then every view's again
    def choose(combo, text):
        combo.setCurrentIndex(combo.findText(text))
        combo.activated.emit(combo.currentIndex())
    choose(panel.bias_view, "img1")
    choose(panel.bias, "shift_drift")
    assert win.project.settings.view_bias == (("img1", "shift_drift"),)
    assert win.solver.refit_now().bias["img1"].model == "shift_drift"
    choose(panel.bias_view, "img0")
    assert panel.bias.currentText() == "shift"
    choose(panel.bias_view, "every view")
    choose(panel.bias, "shift")
    assert win.project.settings.view_bias == () and win.project.settings.bias_model == "shift"
    assert win.solver.refit_now().bias["img1"].params[1] == pytest.approx(b0, abs=1e-9)

    win.a_save.trigger()
    p = load_project(d / "p.prismproj")
    assert p.settings.reference_sigma_m == 6.0 and p.reference_dem == str(srtm.resolve())
    assert p.orientation["reference_heights"] == 49
    assert p.orientation["views"]["img1"]["params"][1] == pytest.approx(b0, abs=1e-9)

    # the command line fits the same stored orientation: nothing new to store (the window
    # holds the project: a different result would say "not stored")
    capsys.readouterr()
    assert main(["fit", str(d / "p.prismproj")]) == 0
    out = capsys.readouterr().out
    assert "stored" not in out, out
    assert main(["dsm", str(d / "p.prismproj"), "-o", str(d / "dsm.tif"), "--posting", "4"]) == 0
    assert abs(np.median(dsm_minus_truth(d / "dsm.tif", world))) < 6.0
