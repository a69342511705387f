"""Tools ▸ Export DSM… and Tools ▸ Orient from reference DEM… in the real window on a project of
images with RPCs (the synthetic block of :mod:`tests.cli.test_rpc_workflows`: a triplet whose
RPCs are all off by 14 m east, −9 m north, +4 m up, the true terrain as the reference DEM),
through the menu actions, in workers."""
from __future__ import annotations

import numpy as np
import pytest
import rasterio
from PySide6.QtWidgets import QDialog

from prismstation.gui.tools import dem_orientation, dsm_tool
from tests.cli.test_rpc_workflows import make_block
from tests.ops.test_rpc_dsm import SHIFT
from tests.qt_windows import close_windows, open_window


def _action(win, text):
    return next(a for a in win.tools_menu.actions() if a.text() == text)


@pytest.fixture()
def block_window(qtbot, tmp_path):
    (tmp_path / "block").mkdir()
    d, _, _ = make_block(tmp_path / "block")
    win = open_window(qtbot, d / "b.prismproj")
    yield d, win
    close_windows(qtbot, win)


def test_dsm_and_orientation_from_the_menu(block_window, tmp_path, job_outcome, monkeypatch):
    d, win = block_window
    dsm, orient = _action(win, "Export &DSM…"), _action(win, "Orient from reference &DEM…")
    assert dsm.isEnabled() and orient.isEnabled()

    def dsm_dialog(dlg):
        dlg.path.setText(str(tmp_path / "dsm.tif"))
        dlg.posting.setValue(8.0)
        return QDialog.DialogCode.Accepted
    monkeypatch.setattr(dsm_tool.DsmDialog, "exec", dsm_dialog)
    dsm.trigger()
    tool = win.tools["dsm"]
    kind, out = job_outcome(tool.job, timeout=120000)
    assert kind == "result", out
    assert "Pairs agree to NMAD" in tool.message and out.dsm.fill_fraction > 0.8
    # no GCP, no reference: the line bias the data cannot determine decides the heights
    assert tool.message.startswith("HEIGHTS NOT FIXED") and "img2: b0" in tool.message
    with rasterio.open(tmp_path / "dsm.tif") as ds:
        assert ds.count == 3 and np.isfinite(ds.read(1, masked=True).filled(np.nan)).mean() > 0.5

    def orient_dialog(dlg):
        dlg.path.setText(str(d / "ref.tif"))
        return QDialog.DialogCode.Accepted
    monkeypatch.setattr(dem_orientation.OrientDialog, "exec", orient_dialog)
    orient.trigger()
    tool = win.tools["dem_orientation"]
    kind, result = job_outcome(tool.job, timeout=120000)
    assert kind == "result" and result.ok and result.record is not None
    o = result.detail
    assert np.all(np.abs(np.array(o.shift_m) - SHIFT) < np.maximum(4 * np.array(o.sigma_m), [1.5, 1.5, 0.75]))
    p = win.project
    assert p.settings.orientation == "dem" and set(p.dem_control["biases"]) == {"img0", "img1", "img2"}
    assert "the block moved dE +1" in win.statusBar().currentMessage()
    assert "the block moved" in tool.panel.summary.text()
    win.undo_stack.undo()                      # one undoable step
    assert p.settings.orientation == "gcp" and p.dem_control is None
