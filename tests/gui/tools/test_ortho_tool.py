"""Tools ▸ Orthoimage… in the real window: through the menu action, onto the loaded reference
DEM, shown in its dock with the project's points at their known positions, checked at them in
a worker; the dialog's choices reach the export; the progress dialog's Cancel leaves no file."""
from __future__ import annotations

import numpy as np
from PySide6.QtCore import Qt
from PySide6.QtTest import QTest
from PySide6.QtWidgets import QDialog, QProgressDialog, QPushButton

from prismstation.gui.tools import ortho_tool
from prismstation.io.ortho import read_ortho_info


def _answer(monkeypatch, seen, **values):
    """Patch the dialog: ``exec`` sets ``values`` on its widgets and answers OK."""
    def exec_(dlg):
        seen.append(dlg)
        for name, v in values.items():
            w = getattr(dlg, name)
            if name in ("path", "dem_path"):
                w.setText(str(v))
            elif name == "views":
                for view, cb in w.items():
                    cb.setChecked(view in v)
            elif name in ("use_reference", "use_file", "use_constant", "whole", "area", "show_result"):
                w.setChecked(v)
            elif name in ("dem_kind",):
                w.setCurrentIndex(w.findData(v))
            elif name == "resampling":
                w.setCurrentText(v)
            else:
                w.setValue(v)
        return QDialog.DialogCode.Accepted
    monkeypatch.setattr(ortho_tool.OrthoDialog, "exec", exec_)


def _menu_action(window):
    return next(a for a in window.tools_menu.actions() if a.text() == "&Orthoimage…")


def test_menu_ortho_on_the_reference_dem_shown_with_the_points_and_checked(qtbot, window, sim, tmp_path,
                                                                          job_outcome, monkeypatch):
    window.load_reference_dem(sim / "srtm.tif", wait=True)
    qtbot.waitUntil(lambda: not window.solver.busy(), timeout=20000)
    tool = window.tools["ortho"]
    seen = []
    out = tmp_path / "n.tif"
    _answer(monkeypatch, seen, path=out, views=("N",), posting=5.0)
    _menu_action(window).trigger()
    dlg = seen[0]
    assert dlg.use_reference.isEnabled() and dlg.use_reference.isChecked() and "srtm.tif" in dlg.use_reference.text()
    kind, export = job_outcome(tool.job, timeout=120000)
    assert kind == "result", export
    info = read_ortho_info(out)
    assert "srtm.tif" in info["tags"]["ORTHO_DEM"] and info["tags"]["ORTHO_DEM_KIND"] == "orthometric"
    assert info["transform"][0] == 5.0
    assert tool.message.startswith(f"Wrote {out}") and "expected accuracy" in tool.message
    # the dock shows it, every GCP and ICP at its known position
    viewer = tool.viewer
    assert tool.dock.isVisible() and viewer.path == str(out) and viewer.source is not None
    p = window.project
    gcps = [q for q in p.points.values() if q.kind == "GCP"]
    x, y = viewer.points["GCP"].getData()
    assert len(x) == len(gcps)
    a, _, c, _, e, f = info["transform"]
    assert np.allclose(x, [(q.E - c) / a for q in gcps]) and np.allclose(y, [(q.N - f) / e for q in gcps])
    assert len(viewer.labels.labels) == len(gcps) + len([q for q in p.points.values() if q.kind == "ICP"])
    # checked at the points: an arrow per point found, the RMSE beside the expected accuracy
    job = viewer.validate()
    kind, val = job_outcome(job, timeout=120000)
    assert kind == "result", val
    found = [q for q in val.points if q.found and q.kind == "ICP"]
    assert len(found) >= 30
    xs, ys = viewer.arrows["ICP"].getData()
    assert len(xs) == 2 * len(found)
    assert "ICP" in viewer.summary.text() and "expected" in viewer.summary.text()
    # a new fit: the check of the old one goes
    window.solver.solution_changed.emit(window.solver.solution)
    xs, _ = viewer.arrows["ICP"].getData()
    assert viewer.validation is None and (xs is None or len(xs) == 0)


def test_the_dialogs_choices_reach_the_export(qtbot, window, tmp_path, job_outcome, monkeypatch):
    tool = window.tools["ortho"]
    iv = window.views.views["N"]
    iv.center_on(600, 600, 400 / iv.width())
    qtbot.wait(50)
    calls = []
    real = ortho_tool.export_orthos
    monkeypatch.setattr(ortho_tool, "export_orthos", lambda sol, p, req, **k: calls.append(req) or real(sol, p, req, **k))
    seen = []
    _answer(monkeypatch, seen, path=tmp_path / "c.tif", views=("F", "B"), use_constant=True, height=120.0,
            area=True, posting=10.0, resampling="cubic", show_result=False)
    _menu_action(window).trigger()
    kind, export = job_outcome(tool.job, timeout=120000)
    assert kind == "result", export
    req = calls[0]
    assert req.views == ("F", "B") and req.dem is None and req.height_m == 120.0 and req.resampling == "cubic"
    assert req.window == seen[0].visible and req.window[2] < 1200 and req.posting_m == 10.0
    assert [o.view for o in export.orthos] == ["F", "B"] and export.orthos[0].transform == export.orthos[1].transform
    assert "constant height 120 m" in tool.message and tool.viewer.path is None     # not shown


def test_cancel_button_of_the_progress_dialog_stops_and_leaves_no_file(qtbot, window, sim, tmp_path, job_outcome,
                                                                       monkeypatch):
    tool = window.tools["ortho"]
    out = tmp_path / "out" / "o.tif"
    out.parent.mkdir()
    _answer(monkeypatch, [], path=out, views=("N", "F", "B"), use_file=True, dem_path=sim / "truth_dem.tif",
            dem_kind="ellipsoidal", posting=1.0)
    _menu_action(window).trigger()
    job = tool.job
    progressed = []
    job.progress.connect(lambda f, m: progressed.append(f))
    qtbot.waitUntil(lambda: bool(progressed), timeout=20000)
    dlg = next(d for d in window.findChildren(QProgressDialog) if d.isVisible())
    button = next(b for b in dlg.findChildren(QPushButton) if b.text() == "Cancel")
    QTest.mouseClick(button, Qt.MouseButton.LeftButton)
    kind, _ = job_outcome(job, timeout=60000)
    assert kind == "cancelled"
    assert max(progressed) < 0.5, progressed
    assert list(out.parent.iterdir()) == []
