"""Tools ▸ Export DSM… in the real window: through the menu action, with the engine's options,
the loaded reference DEM as the prior, the fill in the result message, and the progress
dialog's Cancel button."""
from __future__ import annotations

import numpy as np
import rasterio
from PySide6.QtCore import Qt
from PySide6.QtTest import QTest
from PySide6.QtWidgets import QDialog, QProgressDialog, QPushButton

from prismstation.gui.tools import dsm_tool


def _settle(qtbot, win):
    qtbot.waitUntil(lambda: not win.solver.busy(), timeout=20000)
    qtbot.wait(20)


def _answer(monkeypatch, seen, **values):
    """Patch the dialog: ``exec`` sets ``values`` on its widgets and answers OK (the prefilled
    path is kept as ``dlg.prefilled``)."""
    def exec_(dlg):
        seen.append(dlg)
        dlg.prefilled = dlg.path.text()
        for name, v in values.items():
            w = getattr(dlg, name)
            if name == "path":
                w.setText(str(v))
            elif name in ("fill", "reference", "area", "whole", "orthometric", "ellipsoidal"):
                w.setChecked(v)
            elif name == "heights":
                w.setCurrentIndex(w.findData(v))
            else:
                w.setValue(v)
        return QDialog.DialogCode.Accepted
    monkeypatch.setattr(dsm_tool.DsmDialog, "exec", exec_)


def _menu_action(window):
    return next(a for a in window.tools_menu.actions() if a.text() == "Export &DSM…")


def test_menu_export_with_the_reference_prior_reports_fill(qtbot, window, sim, tmp_path, job_outcome, monkeypatch):
    from rasterio.warp import Resampling, reproject

    import prismstation.ops.dsm as ops_dsm
    tool = window.tools["dsm"]
    assert not hasattr(window, "dsm_tool")          # the tool lives in the registry, not on the window
    window.load_reference_dem(sim / "srtm.tif", wait=True)
    _settle(qtbot, window)
    assert window.solver.height_of is not None
    iv = window.views.views["N"]
    iv.center_on(600, 600, 700 / iv.width())
    qtbot.wait(50)
    calls = []
    real = ops_dsm.make_dsm
    monkeypatch.setattr(ops_dsm, "make_dsm", lambda *a, **k: calls.append(k) or real(*a, **k))
    seen = []
    out = tmp_path / "dsm.tif"
    # a minimum of 100 % cannot be met: the message must warn
    _answer(monkeypatch, seen, path=out, posting=10.0, uncertainty=60.0, min_fill=100.0, area=True,
            ellipsoidal=True)        # the truth is ellipsoidal
    _menu_action(window).trigger()
    assert seen and seen[0].reference.isEnabled() and seen[0].reference.isChecked()
    assert "srtm.tif" in seen[0].reference.text()
    kind, export = job_outcome(tool.job, timeout=60000)
    assert kind == "result", export
    dsm = export.dsm
    k = calls[0]
    assert k["reference"] is not None and k["height_uncertainty_m"] == 60.0 and k["posting_m"] == 10.0
    assert k["reference"][0] is window.solver.height_of.grid.heights
    fill = 100.0 * dsm.fill_fraction
    assert tool.message.startswith("LOW FILL") and f"{fill:.1f} %" in tool.message
    assert tool.message in window.statusBar().currentMessage()
    with rasterio.open(out) as ds, rasterio.open(sim / "truth_dem.tif") as t:
        a = ds.read(1).astype(float)
        ref = np.full(a.shape, np.nan)
        reproject(t.read(1).astype(float), ref, src_transform=t.transform, src_crs=t.crs,
                  dst_transform=ds.transform, dst_crs=ds.crs, resampling=Resampling.bilinear)
        assert ds.transform.a == 10.0 and abs(float(ds.tags()["FILL_PERCENT"]) - fill) < 0.01
    d = (a - ref)[np.isfinite(a - ref)]
    nmad = 1.4826 * np.median(np.abs(d - np.median(d)))
    print(f"DSM {a.shape} with the reference prior: fill {fill:.1f} %, median {np.median(d):+.2f} m, NMAD {nmad:.2f} m")
    assert fill > 80.0 and abs(np.median(d)) < 3.0 and nmad < 3.0


def test_result_message_warns_only_below_the_minimum():
    from prismstation.ops.dsm import Dsm
    from prismstation.ops.dsm_export import DsmExport, DsmRequest
    mask = np.array([[1, 1], [1, 0]], np.uint8)
    seen = np.ones((2, 2), bool)
    d = Dsm(np.zeros((2, 2), np.float32), (5, 0, 0, 0, -5, 0), "EPSG:32654", "ellipsoidal", 0.75,
            mask, seen, np.zeros((2, 2), np.uint8), 5.0)
    text, low = dsm_tool.result_message(DsmExport("x.tif", d, DsmRequest("x.tif", min_fill_percent=70.0)))
    assert not low and "75.0 % of the 4 cells" in text and "LOW FILL" not in text
    text, low = dsm_tool.result_message(DsmExport("x.tif", d, DsmRequest("x.tif", min_fill_percent=80.0)))
    assert low and text.startswith("LOW FILL: only 75.0 %")
    d.info["heights"] = {"model": "rays", "reason": "leave-one-out over 9 GCPs: line 3.44 m, rays 2.26 m RMS"}
    text, _ = dsm_tool.result_message(DsmExport("x.tif", d, DsmRequest("x.tif", min_fill_percent=70.0)))
    assert text.endswith("Heights: rays through the biases (leave-one-out over 9 GCPs: line 3.44 m, rays 2.26 m RMS)")


def test_cancel_button_of_the_progress_dialog_stops_and_leaves_no_file(qtbot, window, tmp_path, job_outcome, monkeypatch):
    tool = window.tools["dsm"]
    out = tmp_path / "out" / "dsm.tif"
    out.parent.mkdir()
    seen = []
    _answer(monkeypatch, seen, path=out, posting=5.0, whole=True)
    _menu_action(window).trigger()
    job = tool.job
    assert job is not None and job.isRunning()
    progressed = []
    job.progress.connect(lambda f, m: progressed.append(f))
    qtbot.waitUntil(lambda: bool(progressed), timeout=20000)
    dlg = next(d for d in window.findChildren(QProgressDialog) if d.isVisible())
    button = next(b for b in dlg.findChildren(QPushButton) if b.text() == "Cancel")
    QTest.mouseClick(button, Qt.MouseButton.LeftButton)
    kind, _ = job_outcome(job, timeout=30000)
    assert kind == "cancelled"
    assert not job.isRunning()
    assert max(progressed) < 0.5, progressed         # the engine stopped, not merely the write
    assert list(out.parent.iterdir()) == []          # neither the DSM nor a temporary file
    assert "cancelled" in window.statusBar().currentMessage()


def test_dialog_prefilled_from_the_project_and_a_fine_posting_kept(qtbot, window, sim, tmp_path, job_outcome, monkeypatch):
    """The path beside the project, the geoid named, the heights kind of the project's points;
    a 1 m posting and the height model reach the export as typed (were: 1 m became 5 m, no
    --heights in the window); the scratch copy of the GeoTIFF is not written beside the output."""
    import tempfile

    import prismstation.io.cog as cog_io
    import prismstation.ops.dsm as ops_dsm
    from prismstation.model.project import has_ground
    tool = window.tools["dsm"]
    p = window.project
    seen, calls, beside = [], [], []
    real, real_copy = ops_dsm.make_dsm, cog_io.rio_copy
    monkeypatch.setattr(ops_dsm, "make_dsm", lambda *a, **k: calls.append(k) or real(*a, **k))
    out = tmp_path / "out" / "fine.tif"
    out.parent.mkdir()
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))

    def copy(src, dst, **kw):              # while the COG is written: what lies where
        beside.append(sorted(f.name for f in out.parent.iterdir()))
        beside.append(sorted(f.name for f in scratch.iterdir()))
        return real_copy(src, dst, **kw)
    monkeypatch.setattr(cog_io, "rio_copy", copy)
    iv = window.views.views["N"]
    iv.center_on(500, 500, 160 / iv.width())
    qtbot.wait(50)
    _answer(monkeypatch, seen, path=out, posting=1.0, heights="rays", area=True, min_fill=0.0)
    _menu_action(window).trigger()
    dlg = seen[0]
    assert dlg.prefilled == str(sim / "p_dsm.tif")
    kinds = [q.height_kind for q in p.points.values() if has_ground(q)]
    assert dlg.orthometric.isChecked() == (kinds.count("orthometric") >= kinds.count("ellipsoidal"))
    assert "geoid: constant" in dlg.orthometric.text() or "geoid: grid" in dlg.orthometric.text()
    kind, res = job_outcome(tool.job, timeout=120000)
    assert kind == "result", res
    assert calls[0]["posting_m"] == 1.0 and calls[0]["heights_model"] == "rays"
    assert res.dsm.posting_m == 1.0 and res.dsm.info["heights"]["model"] == "rays"
    with rasterio.open(out) as ds:
        assert ds.transform.a == 1.0
    # beside the output only the compressed file being written; the scratch copy elsewhere
    assert all(n.startswith(".") for n in beside[0]) and len(beside[0]) <= 2, beside
    assert any(n.startswith("prismstation-dsm-") for n in beside[1]), beside
    assert sorted(f.name for f in out.parent.iterdir()) == ["fine.tif"]
    assert list(scratch.iterdir()) == []
