"""Predictions, their ellipses and linked navigation in the real window, through real input:
Shift-clicks in the views, the wheel, a drag, the View menu's toggle."""
from __future__ import annotations

import math

import numpy as np
import rasterio
from PySide6.QtCore import QEvent, QPoint, QPointF, Qt
from PySide6.QtGui import QMouseEvent, QWheelEvent
from PySide6.QtWidgets import QApplication
from rasterio.transform import from_origin

from prismstation.ops.predict import CHI2_95_2D
from prismstation.sim.small_project import Terrain
from tests.gui.test_operator import click_image, settle

SHIFT = Qt.KeyboardModifier.ShiftModifier


def write_dem(win, path, sigma=4.0, seed=5, scene=None):
    """A 30 m GeoTIFF DEM of the demo's terrain (the test project's heights) with noise."""
    sc = win.project.scene if scene is None else scene
    size, p = sc.views["N"].shape[1], sc.views["N"].pixel_size_m
    centre = sc.views["N"].map_to_image.inverse()(np.array([size / 2, size / 2]))
    terrain = Terrain(centre, size * p, 5)
    x0, y1 = centre - 0.8 * size * p
    x0, y1 = x0, centre[1] + 0.8 * size * p
    n = int(1.6 * size * p / 30)
    E, N = np.meshgrid(x0 + 30 * (np.arange(n) + 0.5), y1 - 30 * (np.arange(n) + 0.5))
    h = terrain(np.stack([E, N], -1)) + np.random.default_rng(seed).normal(0, sigma, E.shape)
    with rasterio.open(path, "w", driver="GTiff", width=n, height=n, count=1, dtype="float32",
                       crs=sc.crs, transform=from_origin(x0, y1, 30, 30)) as ds:
        ds.write(h.astype(np.float32), 1)
    return path


def d2(pred, truth):
    e = np.subtract(truth, pred.xy)
    return float(e @ np.linalg.solve(pred.cov, e))


def ellipse_extent(ov, pr):
    """Bounds of the ellipse drawn around prediction ``pr`` (points within 3 semi-axes)."""
    pts = ov.ellipse_points()
    pts = pts[np.isfinite(pts[:, 0])]
    pts = pts[np.hypot(*(pts - pr.xy).T) < 3 * pr.ellipse()[0]]
    assert len(pts) > 10
    return pts.min(axis=0), pts.max(axis=0)


def markers(ov):
    x, y = ov.predicted.getData()
    return np.column_stack([x, y])


def test_predictions_use_the_dem_then_the_intersection_and_show_their_ellipse(qtbot, window, tmp_path):
    win, truth = window, window.demo.truth["I3"]
    win.load_reference_dem(write_dem(win, tmp_path / "dem.tif"), wait=True)
    settle(qtbot, win)
    win.tools["transfer"].a_auto.setChecked(False)   # this test places every view by hand
    win.set_current(None)
    qtbot.keyClick(win, Qt.Key.Key_Insert)           # New point
    pid = win.current
    for v in "NFB":
        win.views.views[v].center_on(*truth[v], 0.5)
    click_image(qtbot, win, "N", *truth["N"], SHIFT)  # Shift: place, even on another marker
    settle(qtbot, win)
    preds = {v: win.views.predictions.get(pid, v) for v in "FB"}
    for v, pr in preds.items():
        assert pr.source == "reference"
        assert d2(pr, truth[v]) < 13.8                       # inside the 99.9 % ellipse
        ov = win.views.overlays[v]
        assert np.any(np.all(np.isclose(markers(ov), pr.xy), axis=1))   # the hollow marker
        lo, hi = ellipse_extent(ov, pr)                      # what is drawn: the 95 % ellipse
        a, b, _ = pr.ellipse()
        assert 2 * b - 1e-6 <= (hi - lo).max() <= 2 * a + 1e-6
        assert np.allclose((hi + lo) / 2, pr.xy, atol=0.05 * a)
        assert math.isclose(math.sqrt(CHI2_95_2D * np.linalg.eigvalsh(pr.cov)[1]), a)
    a_dem = preds["B"].ellipse()[0]

    click_image(qtbot, win, "F", *truth["F"], SHIFT)
    settle(qtbot, win)
    pr = win.views.predictions.get(pid, "B")
    assert pr.source == "intersection" and win.views.predictions.get(pid, "F") is None
    assert pr.ellipse()[0] < a_dem                            # two rays beat the DEM
    assert math.hypot(*np.subtract(pr.xy, truth["B"])) < 1.5
    assert d2(pr, truth["B"]) < 13.8
    # the current-point square and the hollow marker sit at the prediction
    assert win.views.point_position(pid, "B") == pr.xy

    click_image(qtbot, win, "B", *truth["B"], SHIFT)         # measured everywhere: no ellipse
    settle(qtbot, win)
    assert win.views.predictions.get(pid, "B") is None
    drawn = win.views.overlays["B"].ellipse_points()
    assert not np.any(np.hypot(*(drawn - pr.xy).T) < 3 * pr.ellipse()[0])
    assert not np.any(np.all(np.isclose(markers(win.views.overlays["B"]), pr.xy), axis=1))


def test_the_demo_opens_with_its_reference_dem(qtbot, demo, monkeypatch, tmp_path):
    from prismstation.cli.demo import reference_dem
    from prismstation.gui.app import run
    from prismstation.gui.main_window import MainWindow
    from prismstation.io.scene import read_scene
    assert reference_dem(demo.path) is None
    (demo.path.parent / "triplet").mkdir()
    dem = write_dem(None, demo.path.parent / "triplet" / "srtm.tif", scene=read_scene(demo.scene_path))
    assert reference_dem(demo.path) == dem
    loaded, on_dem = [], MainWindow._on_dem

    def spy(self, heights):
        loaded.append((heights.path, self))
        on_dem(self, heights)
    monkeypatch.setattr(MainWindow, "_on_dem", spy)
    assert run(str(demo.path), screenshot=str(tmp_path / "s.png"), reference_dem=reference_dem(demo.path)) == 0
    (path, win), = loaded
    assert str(path) == str(dem)
    assert win.views.height_of is not None
    assert 1.0 < win.views.predictions.sigma_dem < 10.0   # measured at the points (4 m noise)


def test_an_unmeasured_gcp_is_predicted_from_its_ground(qtbot, window):
    win = window
    pr = win.views.predictions.get("G9", "F")
    assert pr.source == "ground"
    assert d2(pr, win.demo.truth["G9"]["F"]) < 13.8
    assert 0.01 < pr.ellipse()[0] < 3.0


# ------------------------------------------------------------------ linked navigation
def wheel(qtbot, iv, steps=1):
    vp = iv.graphics.viewport()
    pos = QPointF(vp.width() / 2, vp.height() / 2)
    ev = QWheelEvent(pos, QPointF(vp.mapToGlobal(pos.toPoint())), QPoint(0, 0), QPoint(0, 120 * steps),
                     Qt.MouseButton.NoButton, Qt.KeyboardModifier.NoModifier, Qt.ScrollPhase.NoScrollPhase, False)
    QApplication.sendEvent(vp, ev)
    qtbot.wait(5)


def drag(qtbot, iv, dx, dy):
    vp = iv.graphics.viewport()
    p0 = QPointF(vp.width() / 2, vp.height() / 2)

    def send(kind, p, buttons):
        btn = Qt.MouseButton.LeftButton if kind != QEvent.Type.MouseMove else Qt.MouseButton.NoButton
        QApplication.sendEvent(vp, QMouseEvent(kind, p, QPointF(vp.mapToGlobal(p.toPoint())), btn, buttons,
                                               Qt.KeyboardModifier.NoModifier))
    send(QEvent.Type.MouseButtonPress, p0, Qt.MouseButton.LeftButton)
    for k in range(1, 11):
        send(QEvent.Type.MouseMove, p0 + QPointF(dx * k / 10, dy * k / 10), Qt.MouseButton.LeftButton)
    send(QEvent.Type.MouseButtonRelease, p0 + QPointF(dx, dy), Qt.MouseButton.NoButton)
    qtbot.wait(5)


def same_ground(win, name, tol_px=0.5, tol_scale=0.01):
    """The other views show the ground the view ``name`` shows (centre and width)."""
    sol, views = win.solver.solution, win.views
    iv = views.views[name]
    c = np.array(iv.center())
    h = views.ground_height(name, c)
    en = sol.image_to_ground(name, np.array([c, c + [100.0, 0]]), h)
    for v, other in views.views.items():
        if v == name:
            continue
        q = sol.ground_to_image(v, en, h)
        assert np.hypot(*(np.array(other.center()) - q[0])) < tol_px, v
        k = np.hypot(*(q[1] - q[0])) / 100.0
        assert abs(other.scale() / (iv.scale() * k) - 1) < tol_scale, v


def test_linked_navigation_wheel_and_drag_move_the_other_views_without_feedback(qtbot, window):
    win = window
    assert win.a_linked_nav.isChecked()                 # on by default, in the View menu
    assert win.a_linked_nav in win.menuBar().actions()[2].menu().actions()
    seen = []
    win.views.navigated.connect(seen.append)
    N = win.views.views["N"]
    N.center_on(300, 500, 2.0)
    wheel(qtbot, N, 2)                                  # zoom in by hand in N
    assert seen == ["N"]                                # the others' moves are not followed
    assert N.scale() < 2.0
    same_ground(win, "N")
    rect_n = N.visible_rect()
    F = win.views.views["F"]
    drag(qtbot, F, 60, -40)                             # pan F by hand
    assert seen[-1] == "F" and "N" not in seen[1:] and "B" not in seen[1:]
    same_ground(win, "F")
    assert N.visible_rect() != rect_n                   # N followed F

    win.a_linked_nav.trigger()                          # off from the menu
    assert not win.a_linked_nav.isChecked()
    before = {v: win.views.views[v].visible_rect() for v in "NB"}
    wheel(qtbot, F, -1)
    drag(qtbot, F, -30, 20)
    assert {v: win.views.views[v].visible_rect() for v in "NB"} == before
    win.a_linked_nav.trigger()
