"""The window on a project of images with RPCs (the real Pléiades triplet crops, Aubagne).

The project is made as ``prismstation new --images`` makes it, with points whose measurements
are the real RPCs' projections of known ground points plus known image-space shifts
(:data:`TRUE_SHIFT`) and 0.1 px of noise — so every number the window shows has a known
answer — over a smooth hill that is also the project's reference DEM (a GeoTIFF). The images
are the real ones (their content does not match these synthetic points; the transfer test
measures a real feature instead).
"""
from __future__ import annotations

import csv
import math

import numpy as np
import pytest
import rasterio
from PySide6.QtCore import QPointF, Qt
from PySide6.QtTest import QTest
from rasterio.transform import from_origin

from prismstation.core.models.rpc_model import RpcBias, RpcModel
from prismstation.gui.point_table import COLUMNS
from prismstation.io.rpc_scene import write_scene_for_images
from prismstation.io.scene import read_scene
from prismstation.ops.project import create
from tests.qt_windows import close_windows, open_window

FILES = [f"pleiades_triplet/img_0{i}.tif" for i in (1, 2, 3)]
VIEWS = ("img_01", "img_02", "img_03")
TRUE_SHIFT = {"img_01": (0.8, -1.5), "img_02": (-2.0, 3.0), "img_03": (1.2, 5.0)}  # a0, b0 px
NOISE_PX = 0.1


def terrain(en):
    """A smooth hill (ellipsoidal m) over the crops: the points' truth and the reference DEM."""
    en = np.asarray(en, float).reshape(-1, 2)
    return 250.0 + 40.0 * np.sin(en[:, 0] / 150.0) * np.cos(en[:, 1] / 110.0)


def make_rpc_project(folder, images, n=5, gcps=(0, 4, 12, 20, 24), icps=(6, 8, 16, 18)):
    """An RPC project in ``folder``: ``n × n`` ground points inside every image (GCPs, ICPs,
    the rest tie points) measured in every view; and ``dem.tif`` (5 m) of :func:`terrain`, its
    heights ellipsoidal and the file saying so.
    Returns ``(project path, scene)``."""
    scene_path = folder / "block.scene.json"
    write_scene_for_images(images, scene_path)
    scene = read_scene(scene_path)
    c = np.vstack([v.footprint() for v in scene.views.values()])
    lo, hi = c.min(0), c.max(0)
    lo, hi = lo + 0.3 * (hi - lo), hi - 0.3 * (hi - lo)
    E, N = np.meshgrid(np.linspace(lo[0], hi[0], n), np.linspace(lo[1], hi[1], n))
    en = np.column_stack([E.ravel(), N.ravel()])
    h = terrain(en)
    model = RpcModel(scene, {v: RpcBias("shift", TRUE_SHIFT[v]) for v in scene.views})
    rng = np.random.default_rng(3)
    kind = ["GCP" if i in gcps else "ICP" if i in icps else "TIE" for i in range(len(en))]
    with open(folder / "points.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["id", "E", "N", "H", "kind", "height"])
        for i, k in enumerate(kind):
            if k != "TIE":
                w.writerow([f"P{i:02d}", en[i, 0], en[i, 1], h[i], k, "ellipsoidal"])
    with open(folder / "measurements.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["id", "view", "x", "y"])
        for v in scene.views:
            xy = model.ground_to_image(v, en, h) + rng.normal(0, NOISE_PX, en.shape)
            for i in range(len(en)):
                w.writerow([f"P{i:02d}", v, xy[i, 0], xy[i, 1]])
    create(folder / "block.prismproj", scene_path, folder / "points.csv", folder / "measurements.csv")
    x0, y1 = lo[0] - 400, hi[1] + 400
    nx, ny = int((hi[0] - lo[0] + 800) / 5), int((hi[1] - lo[1] + 800) / 5)
    gE, gN = np.meshgrid(x0 + 2.5 + 5 * np.arange(nx), y1 - 2.5 - 5 * np.arange(ny))
    grid = terrain(np.column_stack([gE.ravel(), gN.ravel()])).reshape(gE.shape)
    with rasterio.open(folder / "dem.tif", "w", driver="GTiff", width=nx, height=ny, count=1,
                       dtype="float32", crs=scene.crs, transform=from_origin(x0, y1, 5, 5)) as ds:
        ds.write(grid.astype("float32"), 1)
        ds.update_tags(HEIGHTS="ellipsoidal")
    return folder / "block.prismproj", scene


@pytest.fixture(scope="module")
def rpc_master(shared_data, tmp_path_factory):
    d = tmp_path_factory.mktemp("rpcwin")
    return make_rpc_project(d, [shared_data / f for f in FILES])


@pytest.fixture()
def rpc_path(rpc_master, tmp_path):
    """A private copy of the project (the scene file names the images by absolute path)."""
    import shutil
    src = rpc_master[0].parent
    for f in src.iterdir():
        shutil.copy(f, tmp_path / f.name)
    return tmp_path / "block.prismproj"


@pytest.fixture()
def win(qtbot, rpc_path):
    w = open_window(qtbot, rpc_path, size=(1600, 1000))
    yield w
    close_windows(qtbot, w)


@pytest.fixture()
def windows(qtbot):
    """Windows a test makes (:func:`tests.qt_windows.new_window`), closed after it."""
    made = []
    yield made
    close_windows(qtbot, *made)


def test_opened_from_file_open_and_the_recent_list(qtbot, rpc_path, windows):
    """File ▸ Open (the dialog answered), then the start page's recent list of a fresh window."""
    from tests.qt_windows import new_window
    from prismstation.gui.app import wait_settled
    w = new_window(qtbot, (1600, 1000))
    windows.append(w)
    w.files.choose_open = lambda *a, **k: str(rpc_path)
    w.a_open.trigger()
    assert wait_settled(w) and w.project is not None and list(w.views.views) == list(VIEWS)
    assert w.solver.solution is not None and w.solver.solution.ok
    w = new_window(qtbot, (1600, 1000))
    windows.append(w)
    rec = w.start_page.recent
    item = next(rec.item(i) for i in range(rec.count())
                if rec.item(i).data(Qt.ItemDataRole.UserRole) == str(rpc_path.resolve()))
    rec.setCurrentItem(item)
    rec.setFocus()
    QTest.keyClick(rec, Qt.Key.Key_Return)
    assert wait_settled(w) and w.project is not None and list(w.views.views) == list(VIEWS)


def test_gui_command_writes_a_picture_of_the_rpc_project(rpc_path, tmp_path):
    from PySide6.QtGui import QImage
    from prismstation.cli import main
    png = tmp_path / "shot.png"
    assert main(["gui", str(rpc_path), "--screenshot", str(png)]) == 0
    assert QImage(str(png)).width() >= 1600


def test_the_views_follow_the_scene_titled_by_their_names(win):
    assert list(win.views.views) == list(VIEWS)
    for v in VIEWS:
        assert win.views.headers[v].text().startswith(f"{v}  ·  zoom")
        assert win.views.views[v].source is not None  # the real image is shown
    assert list(win.status_xy) == list(VIEWS)  # a cursor-position label per view
    assert list(win.loupes) == list(VIEWS)
    assert [win.contrast_tabs.tabText(i) for i in range(win.contrast_tabs.count())] == list(VIEWS)
    # the table's Views column marks long image names by their place; its header names them
    model = win.table_model
    assert {model.cell(pid, "Views") for pid in model.ids} == {"1 2 3"}
    assert model.headerData(COLUMNS.index("Views"), Qt.Orientation.Horizontal, Qt.ItemDataRole.ToolTipRole) == \
        "1 = img_01  2 = img_02  3 = img_03"


def test_the_fit_finds_the_known_shifts_and_the_panel_offers_the_rpc_choices(qtbot, win):
    panel = win.panel
    assert [panel.bias.itemText(i) for i in range(panel.bias.count())] == ["none", "shift", "shift_drift", "affine"]
    assert panel.bias.currentText() == "shift"
    assert not panel.parallax.isVisible() and not panel.form.labelForField(panel.parallax).isVisible()
    assert panel.fixed.isVisible()
    assert [panel.fixed.itemText(i) for i in range(panel.fixed.count())] == ["auto", *VIEWS]
    sol = win.solver.solution
    assert sol.ok and sol.model.height_source == "intersection"
    for v in VIEWS:  # 5 GCPs of 0.01 m: every view's shift, within 4 σ of the truth
        b = sol.bias[v]
        assert np.all(np.abs(np.asarray(b.params) - TRUE_SHIFT[v]) < 4 * np.asarray(b.std) + 1e-3)
    text = panel.plain_text()
    assert "Image residuals per view (px)" in text and "TIE n" in text and "Table 1" not in text
    assert "Parallax line" not in text
    # the accuracy strip: the ICPs' height from the intersection
    assert win.accuracy.values["h"].text().endswith(" m") and "4 ICP" in win.accuracy.count.text()
    # the plots: no height–parallax plot
    assert not win.plots.plots["height"].isVisible() and not win.plots.plots["height_minus_theory"].isVisible()

    # choose shift + drift in the combo box, by the keyboard: an undoable refit
    panel.bias.setFocus()
    with qtbot.waitSignal(win.solver.solution_changed, timeout=20000):
        QTest.keyClick(panel.bias, Qt.Key.Key_Down)  # shift -> shift_drift (activated)
    assert win.project.settings.bias_model == "shift_drift"
    qtbot.waitUntil(lambda: win.solver.solution.bias["img_02"].model == "shift_drift", timeout=20000)
    assert len(win.solver.solution.bias["img_02"].params) == 3
    # hold img_02 fixed: its bias is not fitted
    i = panel.fixed.findData("img_02")
    panel.fixed.setFocus()
    with qtbot.waitSignal(win.solver.solution_changed, timeout=20000):
        QTest.keyClick(panel.fixed, Qt.Key.Key_Down)
        QTest.keyClick(panel.fixed, Qt.Key.Key_Down)
    assert panel.fixed.currentIndex() == i and win.project.settings.fixed_view == "img_02"
    qtbot.waitUntil(lambda: win.solver.solution.settings.fixed_view == "img_02", timeout=20000)
    win.undo_stack.undo()  # each choice was one undoable step: img_02, then img_01, then auto
    assert win.project.settings.fixed_view == "img_01"
    win.undo_stack.undo()
    assert win.project.settings.fixed_view is None
    qtbot.waitUntil(lambda: panel.fixed.currentText() == "auto", timeout=20000)  # after the refit


def test_linked_cursor_goes_through_the_rpcs_and_the_reference_dem(qtbot, win, rpc_path):
    win.load_reference_dem(rpc_path.parent / "dem.tif", wait=True)
    assert win.views.height_of is not None
    sol = win.solver.solution
    r = sol.point("P12")  # a GCP: its measured position in img_01
    x, y = r.measured["img_01"]
    iv = win.views.views["img_01"]
    win.views.drive_to("P12", scale=0.5)
    qtbot.wait(50)
    # move away from the marker (the cursor takes the height of a point under it): 40 px east
    x2 = x + 40.0
    pos = iv.vb.mapViewToScene(QPointF(x2, y))
    QTest.mouseMove(iv.graphics.viewport(), iv.graphics.mapFromScene(pos))
    qtbot.waitUntil(lambda: win.status_xy["img_02"].text() != "img_02  —", timeout=5000)
    linked, ground = win.views.linked("img_01", x2, y)
    assert ground is not None
    # the ground under the cursor lies on the DEM, and projects back to the cursor
    assert abs(ground[2] - terrain(np.array(ground[:2]))[0]) < 0.5
    for v in ("img_02", "img_03"):
        want = sol.ground_to_image(v, np.array(ground[:2]), ground[2])
        assert np.allclose(linked[v], want, atol=1e-6)
        assert win.status_xy[v].text().startswith(f"{v}  x ")
    assert win.status_ground.text().startswith("E ")


def test_without_gcps_the_reference_dem_holds_the_tie_points(qtbot, win, rpc_path):
    """The GCPs made check points (the table's kind action): the first view is held fixed and
    the others' shifts are fitted relative to it, the tie points held to the loaded DEM."""
    for pid in [p for p, q in win.project.points.items() if q.kind == "GCP"]:
        win.set_current(pid)
        win.a_kind["ICP"].trigger()
    win.load_reference_dem(rpc_path.parent / "dem.tif", wait=True)
    qtbot.waitUntil(lambda: win.solver.solution is not None and win.solver.solution.revision == win.project.revision
                    and win.solver.solution.model.fitted("img_02"), timeout=30000)
    sol = win.solver.solution
    assert sol.ok and not any(r.kind == "GCP" for r in sol.points)
    assert sol.bias["img_01"].cov is None or not len(sol.bias["img_01"].params)  # the datum
    for v in ("img_02", "img_03"):
        rel = np.subtract(TRUE_SHIFT[v], TRUE_SHIFT["img_01"])
        # relative to img_01's own shift: found to 0.13, 0.17 px (σ 0.09, 0.16) along the lines,
        # where img_01's line shift also moves the intersected heights the DEM holds
        assert np.all(np.abs(np.asarray(sol.bias[v].params) - rel) < 0.5)
    assert "held fixed (the datum)" in win.panel.plain_text()


def test_a_new_point_is_predicted_with_an_ellipse_then_measured_in_every_view(qtbot, win):
    sol = win.solver.solution
    # a new tie point clicked in img_01 (Create point, then a click in the view)
    win.a_new_point.trigger()
    pid = win.current
    iv = win.views.views["img_01"]
    iv.center_on(500.0, 480.0, 0.5)
    qtbot.wait(50)
    pos = iv.graphics.mapFromScene(iv.vb.mapViewToScene(QPointF(500.0, 480.0)))
    QTest.mouseClick(iv.graphics.viewport(), Qt.MouseButton.LeftButton, pos=pos)
    qtbot.waitUntil(lambda: win.project.measurement(pid, "img_01") is not None, timeout=5000)
    qtbot.waitUntil(lambda: win.views.predictions.get(pid, "img_02") is not None, timeout=20000)
    for v in ("img_02", "img_03"):
        p = win.views.predictions.get(pid, v)
        assert np.all(np.isfinite(p.xy)) and p.cov.shape == (2, 2)
        w = np.linalg.eigvalsh(p.cov)
        assert np.all(w > 0) and math.sqrt(w.max()) < 200  # an ellipse of a few to tens of px
    m = win.project.measurement(pid, "img_01")
    assert abs(m.x - 500.0) < 1 and abs(m.y - 480.0) < 1
    del sol


def strongest_corner(path, margin=200):
    """Image ``(x, y)`` (pixel centre) of the strongest Shi–Tomasi corner of the image at
    least ``margin`` px inside it."""
    import cv2
    with rasterio.open(path) as ds:
        a = ds.read(1).astype(np.float32)
    lo, hi = np.percentile(a, (1, 99))
    a = np.clip((a - lo) / (hi - lo) * 255, 0, 255).astype(np.uint8)
    mask = np.zeros_like(a)
    mask[margin:-margin, margin:-margin] = 255
    c = cv2.goodFeaturesToTrack(a, 1, 0.01, 10, mask=mask, blockSize=9)
    return float(c[0, 0, 0]) + 0.5, float(c[0, 0, 1]) + 0.5


def test_transfer_finds_a_real_feature_in_the_other_images(qtbot, win):
    """A point put on a corner of img_01 is found in img_02 and img_03 by the transfer tool
    through the real RPCs (bias model none: the project's synthetic shifts are not the real
    images' — with them the three rays of a real feature miss each other by ~2 px)."""
    tool = win.tool_context.tools["transfer"]
    win.panel.bias.setFocus()
    with qtbot.waitSignal(win.solver.solution_changed, timeout=20000):
        QTest.keyClick(win.panel.bias, Qt.Key.Key_Up)  # shift -> none
    qtbot.waitUntil(lambda: win.solver.solution.settings.bias_model == "none", timeout=20000)
    win.a_new_point.trigger()  # Create point, then a click on the corner: the transfer starts
    pid = win.current
    x, y = strongest_corner(win.project.scene.views["img_01"].image)
    iv = win.views.views["img_01"]
    iv.center_on(x, y, 0.5)
    qtbot.wait(50)
    QTest.mouseClick(iv.graphics.viewport(), Qt.MouseButton.LeftButton,
                     pos=iv.graphics.mapFromScene(iv.vb.mapViewToScene(QPointF(x, y))))
    qtbot.waitUntil(lambda: tool.pid == pid and bool(tool.candidates), timeout=120000)
    m = win.project.measurement(pid, "img_01")
    assert abs(m.x - x) < 1 and abs(m.y - y) < 1
    assert set(tool.candidates) == {"img_02", "img_03"}
    assert all(t.ok for t in tool.candidates.values()), {
        v: (t.match.status, t.match.reason) for v, t in tool.candidates.items()}
    tool.a_accept.trigger()
    for v in ("img_02", "img_03"):
        assert win.project.measurement(pid, v) is not None
    qtbot.waitUntil(lambda: set(VIEWS) <= set(getattr(win.solver.solution.point(pid), "residual_px", ())),
                    timeout=20000)
    r = win.solver.solution.point(pid)
    assert max(np.hypot(*r.residual_px[v]) for v in VIEWS) < 1.0  # the three rays meet


def test_the_dsm_and_orientation_tools_are_offered(qtbot, win):
    """Images with RPCs list ``dsm`` and ``orient-dem`` among their workflows (the jobs
    themselves: tests/gui/tools/test_rpc_workflows_window.py)."""
    assert win.tool_context.tools["dsm"].action.isEnabled()
    assert win.tool_context.tools["dem_orientation"].a_orient.isEnabled()
    assert win.tool_context.tools["transfer"].a_ties.isEnabled()  # automatic tie points: any views


def test_report_export_of_an_rpc_project(qtbot, win, tmp_path):
    out = tmp_path / "report.html"
    assert win.export_report(str(out))
    html = out.read_text()
    assert "View held fixed" in html and "Height–parallax model" not in html
    for v in VIEWS:
        assert f"view {v}" in html


def test_the_plots_draw_the_tie_points_of_a_model_that_fits_them(win):
    d = win.plots._data
    assert d.ties and len(d.vec_tie_ids) == 16 and len(d.vec_gcp_ids) == 5 and len(d.vec_icp_ids) == 4
    assert set(d.std_ids) == {p for p, q in win.project.points.items() if q.kind in ("GCP", "TIE")}
    std = win.plots.plots["std_residuals"].getPlotItem()
    assert "tie points" in std.titleLabel.text
    assert std.getAxis("bottom").labelText == "point"     # not "GCP": it counts tie points too
    assert "16 tie points in img_01" in win.plots.summary.text()


def test_space_resection_works_on_a_view_with_rpcs(qtbot, win):
    """Tools ▸ Space resection…: a frame camera on img_01's 5 GCPs (no along-track angle: the
    scene's B/H is not offered)."""
    menu = win.tools_menu
    act = next(a for a in menu.actions() if a.text() == "Space resection…")
    act.trigger()
    dlg = win.tool_context.tools["resection"].dialog
    assert [dlg.view.itemText(i) for i in range(dlg.view.count())] == list(VIEWS)
    res = dlg.run()
    assert res is not None and "View img_01" in dlg.text.toPlainText()
    dlg.close()


def test_automatic_tie_points_over_the_first_view(qtbot, win):
    """Tools ▸ Automatic tie points on a 3 × 3 grid of img_01, through the raw RPCs: the points
    found are measured in all three images, and their rays meet."""
    tool = win.tool_context.tools["transfer"]
    win.panel.bias.setFocus()
    with qtbot.waitSignal(win.solver.solution_changed, timeout=20000):
        QTest.keyClick(win.panel.bias, Qt.Key.Key_Up)  # shift -> none
    qtbot.waitUntil(lambda: win.solver.solution.settings.bias_model == "none", timeout=20000)
    before = set(win.project.points)
    job = tool.start_ties(3)
    qtbot.waitUntil(lambda: not job.isRunning(), timeout=300000)
    qtbot.waitUntil(lambda: set(win.project.points) != before, timeout=10000)
    new = sorted(set(win.project.points) - before)
    assert len(new) >= 4  # of 9 (a few fall on shadow or featureless slopes)
    assert tool.summary.startswith(f"{len(new)} of 9 grid points added")
    for pid in new:
        assert all(win.project.measurement(pid, v) is not None for v in VIEWS)
    qtbot.waitUntil(lambda: all(set(VIEWS) <= set(getattr(win.solver.solution.point(p), "residual_px", ()))
                                for p in new), timeout=20000)
    sol = win.solver.solution
    assert max(np.hypot(*sol.point(p).residual_px[v]) for p in new for v in VIEWS) < 1.0


def test_a_pair_opens_with_two_views(qtbot, shared_data, tmp_path, windows):
    """The Réunion pair (two Pléiades images, RPCs in the tags): two panes, the fit finds both
    shifts from the GCPs, the automatic tie points offered between the two."""
    path, _ = make_rpc_project(tmp_path, [shared_data / f"pleiades_pair_reunion/img_0{i}.tif" for i in (1, 2)])
    w = open_window(qtbot, path, size=(1600, 1000))
    windows.append(w)
    assert list(w.views.views) == ["img_01", "img_02"] and list(w.status_xy) == ["img_01", "img_02"]
    assert all(w.views.views[v].source is not None for v in ("img_01", "img_02"))
    assert [w.panel.fixed.itemText(i) for i in range(w.panel.fixed.count())] == ["auto", "img_01", "img_02"]
    sol = w.solver.solution
    assert sol.ok
    for v in ("img_01", "img_02"):
        b = sol.bias[v]
        assert np.all(np.abs(np.asarray(b.params) - TRUE_SHIFT[v]) < 4 * np.asarray(b.std) + 1e-3)
    assert w.tool_context.tools["transfer"].a_ties.isEnabled()


def test_the_vector_plot_shows_any_image_and_not_one_held_fixed(qtbot, win):
    """The residual vectors of the first image by default; held fixed (nothing fitted there),
    the first fitted one; any image chosen in the plots' bar, by the keyboard."""
    plots, panel = win.plots, win.panel
    box = plots.view_box
    assert box.isVisible() and [box.itemText(i) for i in range(box.count())] == list(VIEWS)
    assert plots._data.view == "img_01" and box.currentText() == "img_01"
    panel.fixed.setFocus()
    with qtbot.waitSignal(win.solver.solution_changed, timeout=20000):
        QTest.keyClick(panel.fixed, Qt.Key.Key_Down)             # auto -> img_01 held fixed
    qtbot.waitUntil(lambda: win.solver.solution.settings.fixed_view == "img_01", timeout=20000)
    assert plots._data.view == "img_02" and box.currentText() == "img_02"
    assert "view img_02" in plots._titles["vectors"] and "in img_02" in plots.summary.text()
    box.setFocus()
    QTest.keyClick(box, Qt.Key.Key_Down)                          # the operator's choice: img_03
    assert plots._data.view == "img_03" and "view img_03" in plots._titles["vectors"]
    assert len(plots._data.vec_gcp_ids) == 5
    win.undo_stack.undo()                                         # (a refit keeps the choice)
    qtbot.waitUntil(lambda: win.solver.solution.settings.fixed_view is None, timeout=20000)
    assert plots._data.view == "img_03"


def test_the_dsm_dialog_of_an_rpc_project(qtbot, win, monkeypatch):
    """Posting twice the images' 0.5 m pixel (it offered PRISM's 5 m); the extent the ground
    every image sees or the first image's visible area (not N's); void filling offered, the
    height model (a triplet's) not."""
    from PySide6.QtWidgets import QDialog

    from prismstation.gui.tools import dsm_tool
    seen = {}

    def look(dlg):
        seen.update(posting=dlg.posting.value(), whole=dlg.whole.text(), area=dlg.area.text(),
                    checked=dlg.area.isChecked(), tip=dlg.posting.toolTip(), window=dlg.request().window,
                    fill=dlg.fill.isEnabled(), heights=dlg.heights.isEnabled())
        return QDialog.DialogCode.Rejected
    monkeypatch.setattr(dsm_tool.DsmDialog, "exec", look)
    win.tool_context.tools["dsm"].action.trigger()
    gsd = max(v.pixel_size_m for v in win.project.scene.views.values())
    assert 0.3 < gsd < 1.0                                   # (Pléiades)
    assert seen["posting"] == round(2 * gsd, 1) and "2 × the images'" in seen["tip"]
    first = next(iter(win.project.scene.views))
    assert seen["whole"] == "the ground every image sees" and f"visible {first} area" in seen["area"]
    rows, cols = win.project.scene.views[first].shape
    w = seen["window"]
    assert (w is None) != seen["checked"] and (w is None or (w[0] >= 0 and w[0] + w[2] <= cols and w[1] + w[3] <= rows))
    assert seen["fill"] and not seen["heights"]


def test_a_status_message_is_shown_whole(qtbot, win, rpc_path):
    """Three views named img_0…: the message was cut where the mode's label begins; now the
    views' cursor positions step aside while it needs their room, and come back after."""
    sb = win.statusBar()
    win.load_reference_dem(rpc_path.parent / "dem.tif", wait=True)
    qtbot.waitUntil(lambda: sb.currentMessage().startswith("Reference DEM: "), timeout=5000)
    msg = sb.currentMessage()
    qtbot.wait(20)
    assert sb.fontMetrics().horizontalAdvance(msg) <= win.status.message_room(), msg
    assert win.measure_mode.label.isVisible() and win.status_fit.isVisible()
    assert not all(lab.isVisible() for lab in win.status_xy.values())
    sb.clearMessage()
    assert all(lab.isVisible() for lab in win.status_xy.values()) and win.status_ground.isVisible()
