"""The rectification, resection, DSM validation and deblock tools in the real window
(offscreen): numbers compared with the engine called directly on the same inputs."""
from __future__ import annotations

import json
import os

import numpy as np
import pytest

from tests.qt_windows import close_windows, open_window
import rasterio
from rasterio.transform import Affine

from prismstation.core.models.rectify import KINDS, compare_transforms
from prismstation.gui.tools._rect_common import view_points
from tests.gui.tools.single_view import make_single_view

pytest.importorskip("pytestqt")


_open_window = open_window


def _close_window(qtbot, win):
    close_windows(qtbot, win)


@pytest.fixture()
def sv_window(qtbot, tmp_path):
    """The real main window on a single-view project, image loaded and fitted."""
    win = _open_window(qtbot, make_single_view(tmp_path / "single"))
    yield win
    _close_window(qtbot, win)


def _cell(table, r, c):
    return table.item(r, c).text()


def test_single_view_opens_and_transform_table_matches_engine(sv_window, qtbot, tmp_path):
    window = sv_window
    assert list(window.views.views) == ["A"]
    assert window.views.views["A"].source is not None
    panel = window.tools["rectify"].panel
    panel.refresh()
    ids, xy, g, chk = view_points(window.project, "A")
    assert chk.sum() == 6 and (~chk).sum() == 14
    ref = compare_transforms(xy, g[:, :2], chk)
    t = panel.rmse
    assert t.rowCount() == len(KINDS)
    for i, r in enumerate(ref):
        assert _cell(t, i, 0) == r.kind
        assert float(_cell(t, i, 2)) == pytest.approx(r.rmse_gcp, abs=1e-3)
        assert float(_cell(t, i, 3)) == pytest.approx(r.rmse_icp, abs=1e-3)
    # the quadratic truth: poly2 fits its ICPs better than affine
    assert ref[3].rmse_icp < ref[0].rmse_icp
    # residuals of the chosen transform, ICPs included
    panel.kind.setCurrentText("poly2")
    assert panel.resid.rowCount() == len(ids)
    k = ids.index("I1")
    assert float(_cell(panel.resid, k, 2)) == pytest.approx(ref[3].residuals[k, 0], abs=1e-3)
    # an edit refreshes: turning GCPs into ICPs leaves too few for poly3, with a message
    from prismstation.gui import commands as cmd
    for pid in ("G1", "G2", "G3", "G4", "G5"):
        window.undo_stack.push(cmd.SetKind(window.project, pid, "ICP"))
    qtbot.waitUntil(lambda: "poly3" in panel.message.text(), timeout=3000)
    assert "at least 10" in panel.message.text()
    for pid in ("G1", "G2", "G3", "G4", "G5"):
        window.undo_stack.undo()
    qtbot.waitUntil(lambda: panel.message.text() == "", timeout=3000)
    dock = window.docks["transforms"]
    dock.setFloating(True)
    dock.resize(640, 620)
    qtbot.wait(50)
    assert dock.grab().save(_picture("rectification.png", tmp_path))


def test_rectify_export_in_worker(sv_window, job_outcome, tmp_path):
    window = sv_window
    out = tmp_path / "rect.tif"
    job = window.tools["rectify"].start("A", "affine", out, resolution=20.0, progress_dialog=True)
    assert job is not None
    kind, res = job_outcome(job)
    assert kind == "result", res
    assert window.statusBar().currentMessage().startswith(f"Wrote {res.path}")
    with rasterio.open(out) as ds:
        assert ds.crs.to_epsg() == 32629
        assert ds.res == pytest.approx((20.0, 20.0))
        # the image covers ~4 km × 4 km at 10 m: about 200 cells of 20 m
        assert 190 <= ds.width <= 215 and 190 <= ds.height <= 215
        assert ds.read(1).max() > 0


def test_rectify_cancel_removes_the_partial_file(sv_window, job_outcome, tmp_path):
    out = tmp_path / "cancelled.tif"
    job = sv_window.tools["rectify"].start("A", "poly2", out, resolution=2.0)  # 16 blocks
    job.cancel()
    assert job_outcome(job) == ("cancelled", None)
    assert "cancelled" in sv_window.statusBar().currentMessage()
    assert not out.exists()


def test_too_few_points_is_a_message_not_a_file(sv_window, tmp_path):
    from prismstation.gui import commands as cmd
    for pid in ("G1", "G2", "G3", "G4", "G5"):  # 9 GCPs left: poly3 needs 10
        sv_window.undo_stack.push(cmd.SetKind(sv_window.project, pid, "ICP"))
    assert sv_window.tools["rectify"].start("A", "poly3", tmp_path / "x.tif") is None
    assert "at least 10" in sv_window.statusBar().currentMessage()
    assert not (tmp_path / "x.tif").exists()


@pytest.fixture()
def two_frame_window(qtbot, tmp_path):
    from tests.gui.tools.single_view import make_frame_view
    path, cam = make_frame_view(tmp_path / "frame2", two_views=True)
    win = _open_window(qtbot, path)
    win.frame_camera = cam
    yield win
    _close_window(qtbot, win)


def test_bh_from_two_resections(two_frame_window):
    from prismstation.core.models.resection import base_height
    from tests.gui.tools.single_view import FRAME_EO, FRAME_EO_B
    window = two_frame_window
    assert list(window.views.views) == ["A", "A2"]
    d = window.tools["resection"].open()
    d.focal.setValue(100.0)
    d.pitch.setValue(50.0)
    d.left_view.setCurrentText("A")
    d.right_view.setCurrentText("A2")
    bh = d.compute_bh()
    truth = base_height(FRAME_EO[:3], FRAME_EO_B[:3])  # ≈ 600 m / 3025 m
    assert d.results["A"].converged and d.results["A2"].converged
    assert bh.base_m == pytest.approx(truth.base_m, abs=3.0)
    assert bh.b_over_h == pytest.approx(truth.b_over_h, rel=2e-3)
    assert "resections of A and A2" in d.bh_label.text()


from pathlib import Path  # noqa: E402

_DOCS = Path(__file__).resolve().parents[3] / "docs"


def _picture(name: str, tmp_path) -> str:
    """Where a dock's grab goes: docs/ on request (PRISMSTATION_SCREENSHOTS=1, to bring the
    docs' picture up to date), else the test's folder — a test run leaves the tree alone."""
    return str((_DOCS if os.environ.get("PRISMSTATION_SCREENSHOTS") else tmp_path) / name)


@pytest.fixture()
def big_window(qtbot, tmp_path):
    """The window on a 2400 px single view with 8 × 8 block artefacts (tiles are displayed)."""
    win = _open_window(qtbot, make_single_view(tmp_path / "big", size=2400, blocky=True))
    yield win
    _close_window(qtbot, win)


def test_deblock_toggle_changes_displayed_tiles(big_window, qtbot):
    from prismstation.core.matching.deblock import deblock
    window = big_window
    iv = window.views.views["A"]
    iv.center_on(1200, 1200, 0.5)  # zoom in: full-resolution tiles
    qtbot.waitUntil(lambda: iv.tiles_complete() and bool(iv.displayed_tiles()), timeout=10000)
    key = next(k for k in iv.displayed_tiles() if k[0] == 1)
    raw = iv.source.cached_tile(*key)
    before = np.array(iv._tiles[key].image)
    np.testing.assert_array_equal(before, raw)
    window.tools["deblock"].actions["A"].setChecked(True)
    qtbot.waitUntil(lambda: key in iv._tiles, timeout=5000)
    after = np.array(iv._tiles[key].image)
    np.testing.assert_array_equal(after, deblock(raw))
    assert np.any(after != raw)
    window.tools["deblock"].actions["A"].setChecked(False)
    qtbot.waitUntil(lambda: key in iv._tiles, timeout=5000)
    np.testing.assert_array_equal(np.array(iv._tiles[key].image), raw)


@pytest.fixture()
def frame_window(qtbot, tmp_path):
    from tests.gui.tools.single_view import make_frame_view
    path, cam = make_frame_view(tmp_path / "frame")
    win = _open_window(qtbot, path)
    win.frame_camera = cam
    yield win
    _close_window(qtbot, win)


def test_resection_dialog_converges_on_a_frame_camera(frame_window, qtbot):
    from tests.gui.tools.single_view import FRAME_EO
    window = frame_window
    cam = window.frame_camera
    d = window.tools["resection"].open()
    assert d.cx.value() == pytest.approx(200.0) and d.cy.value() == pytest.approx(200.0)
    d.focal.setValue(cam.focal_m * 1000)
    d.pitch.setValue(cam.pixel_m * 1e6)
    res = d.run()
    assert res is not None and res.converged
    err = res.params - FRAME_EO
    err[3:] = (err[3:] + np.pi) % (2 * np.pi) - np.pi
    assert np.all(np.abs(err) < 4 * res.sigma + 1e-9), (err, res.sigma)
    assert res.sigma0_px == pytest.approx(0.1, rel=0.5)
    # the history is plotted: three curves per plot, one point per iteration
    curves = d.plot_angles.getPlotItem().listDataItems()
    assert len(curves) == 3 and len(curves[0].xData) == len(res.corrections)
    qtbot.wait(50)  # (laid out)
    for pw in (d.plot_angles, d.plot_pos):  # the legend under the axis, not over the curves
        pi = pw.getPlotItem()
        assert len(pi.legend.items) == 3
        assert not pi.legend.sceneBoundingRect().intersects(pi.vb.sceneBoundingRect())
    assert "approximation for a pushbroom" in " ".join(
        w.text() for w in d.findChildren(type(d.bh_label)))
    # B/H from typed positions (docs/model.md §6 arithmetic, by hand)
    for v, s in zip((0, 0, 691650, 100000, 0, 691650), [s for row in d.pos for s in row]):
        s.setValue(v)
    bh = d.compute_bh()
    assert bh.b_over_h == pytest.approx(100000 / 691650)
    assert "B/H = 0.1446" in d.bh_label.text()


def _write(path, arr, transform, dtype="float32", nodata=None):
    with rasterio.open(path, "w", driver="GTiff", width=arr.shape[1], height=arr.shape[0], count=1,
                       dtype=dtype, crs="EPSG:32629", transform=transform, nodata=nodata) as ds:
        ds.write(arr.astype(dtype), 1)


def test_residual_sd_dock_matches_solution(sv_window):
    window = sv_window
    sol = window.solver.solution
    tool = window.tools["dsm_validation"]
    t = tool.sd_panel.table
    assert not tool.sd_dock.isVisible() and t.rowCount() == 0   # hidden: not filled per click
    tool.sd_dock.show()
    assert t.rowCount() == 1 and t.item(0, 0).text() == "A"
    for kind, col in (("GCP", 1), ("ICP", 4)):
        r = np.array([p.residual_px["A"] for p in sol.points if p.kind == kind])
        assert int(t.item(0, col).text()) == len(r)
        sd = r.std(axis=0, ddof=1)  # by hand
        assert float(t.item(0, col + 1).text()) == pytest.approx(sd[0], abs=1e-3)
        assert float(t.item(0, col + 2).text()) == pytest.approx(sd[1], abs=1e-3)


def test_dsm_validation_shows_known_bias(sv_window, qtbot, job_outcome, tmp_path):
    window = sv_window
    rng = np.random.default_rng(3)
    n = 160
    yy, xx = np.mgrid[0:n, 0:n]
    z = 400 + 120 * np.sin(xx / 19.0) * np.cos(yy / 27.0) + 0.8 * xx
    from scipy import ndimage
    noise = 4.0 * ndimage.gaussian_filter(rng.normal(0, 1.0, (n, n)), 3) + rng.normal(0, 0.3, (n, n))
    classes = np.where(xx < n // 2, 1, 2).astype("uint8")
    dsm = z + 2.5 + noise + np.where(classes == 2, 1.0, 0.0)   # class 2 one metre higher
    geo = Affine(30.0, 0, 500000.0, 0, -30.0, 4600000.0)
    _write(tmp_path / "dsm.tif", dsm, geo)
    _write(tmp_path / "ref.tif", z, geo)
    _write(tmp_path / "mask.tif", classes, geo, "uint8", nodata=0)
    tool = window.tools["dsm_validation"]
    job = tool.start(str(tmp_path / "dsm.tif"), str(tmp_path / "ref.tif"),
                     mask=str(tmp_path / "mask.tif"))
    kind, msg = job_outcome(job)
    assert kind == "result", msg
    d = (dsm.astype("float32").astype(float) - z.astype("float32").astype(float))  # by hand
    t = tool.panel.table
    head = [t.horizontalHeaderItem(c).text() for c in range(t.columnCount())]
    assert [t.item(r, 0).text() for r in range(t.rowCount())] == ["all", "class 1", "class 2"]
    assert int(t.item(0, head.index("count")).text()) == n * n
    assert float(t.item(0, head.index("bias")).text()) == pytest.approx(d.mean(), abs=1e-3)
    assert float(t.item(0, head.index("bias")).text()) == pytest.approx(3.0, abs=0.05)
    assert float(t.item(0, head.index("sd")).text()) == pytest.approx(d.std(ddof=1), abs=1e-3)
    assert float(t.item(1, head.index("bias")).text()) == pytest.approx(d[classes == 1].mean(), abs=1e-3)
    assert float(t.item(2, head.index("bias")).text()) == pytest.approx(d[classes == 2].mean(), abs=1e-3)
    # the map and the histogram are drawn
    assert tool.panel.map_item.image.shape == (n, n, 3)
    assert len(tool.panel.hist.getPlotItem().items) >= 2
    # exports
    tool.panel.export(tmp_path / "v.json")
    tool.panel.export(tmp_path / "v.csv")
    js = json.loads((tmp_path / "v.json").read_text())
    assert js["validation"]["bias"] == pytest.approx(d.mean(), abs=1e-6)
    assert js["validation"]["per_class"]["2"]["count"] == int((classes == 2).sum())
    lines = (tmp_path / "v.csv").read_text().splitlines()
    assert lines[0].startswith("cells,count,bias") and len(lines) == 4
    assert float(lines[1].split(",")[2]) == pytest.approx(d.mean(), abs=1e-6)
    tool.dock.setFloating(True)
    tool.dock.resize(1100, 560)
    qtbot.wait(50)
    assert tool.dock.grab().save(_picture("dsm_validation.png", tmp_path))
