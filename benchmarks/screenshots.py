"""The pictures of the window in docs/, made from the demo project (offscreen).

``window_WxH.png`` and ``screenshot.png`` (the demo as it opens), ``editing_WxH.png`` (the known
height of G01 typed in the table, the views at 1:1 on it), ``predictions_dem_WxH.png`` (a new
point measured in N, predicted in F and B at the reference DEM's height with its 95 % ellipse),
``predictions_intersection``, ``predictions_mean_height``, ``predictions_transfer`` (1600 × 1000),
``orient_srtm_1600x1000.png`` (Tools ▸ Orient from reference DEM… with its defaults: the
patches' dock and its verdict), ``editing_new_point.png`` (Edit ▸ New point from coordinates…: the dialog as filled in, drawn
over the window once the point is added and the views are driven to where the model puts it,
1600 × 1000), ``ortho_1600x1000.png`` (Tools ▸ Orthoimage… of N on the reference DEM, its dock
with the GCPs and ICPs at their known positions, checked at them), ``start_page.png`` and ``image_view.png`` (three image views with their loupes
and contrast panels, 1500 × 560, on ``--triplet``: a folder of three images, ``img_0*.tif`` or
``N.tif``, ``F.tif``, ``B.tif``; the demo's by default). Every window picture is checked to be
exactly the size asked for (nothing below the screen's edge).

Two docks' pictures come from their tests instead, on request: ``PRISMSTATION_SCREENSHOTS=1
.venv/bin/python -m pytest tests/gui/tools/test_rectify_tools.py`` writes ``rectification.png``
and ``dsm_validation.png`` (otherwise the tests grab into their own folders: a test run leaves
the tree alone).

With ``--rpc IMG IMG [IMG …]`` (images with RPCs) it makes ``rpc_window_1600x1000.png`` instead
(:func:`screenshots_rpc.rpc_window`): the window on a project of those images.

Run: ``.venv/bin/python benchmarks/screenshots.py [--project P] [--out docs] [--triplet DIR]
[--only NAME ...]`` (``--only``: the pictures whose file name starts with one of these)
or ``.venv/bin/python benchmarks/screenshots.py --rpc img_01.tif img_02.tif img_03.tif``
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

SIZES = ((1280, 720), (1600, 1000), (1920, 1080))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--project", help="the demo project (default: made in a temporary folder)")
    ap.add_argument("--out", default=str(Path(__file__).resolve().parents[1] / "docs"))
    ap.add_argument("--triplet", help="three images for image_view.png (default: the demo's)")
    ap.add_argument("--only", nargs="+", default=None, help="make only the pictures named so")
    ap.add_argument("--rpc", nargs="+", metavar="IMG", help="images with RPCs: the RPC picture only")
    args = ap.parse_args(argv)

    def wanted(*names) -> bool:
        return args.only is None or any(n.startswith(o) for n in names for o in args.only)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix="screenshots-"))
    os.environ["PRISMSTATION_SETTINGS_DIR"] = str(tmp / "settings")
    if args.rpc:
        from benchmarks.screenshots_rpc import rpc_window
        return rpc_window([Path(f) for f in args.rpc], out, tmp)
    if args.project:
        project = Path(args.project)
    else:
        from prismstation.cli.demo import ensure_demo
        project = ensure_demo(tmp / "demo")
    import shutil
    work = tmp / "work"
    shutil.copytree(project.parent, work)
    project = work / project.name

    from PySide6.QtCore import QCoreApplication, Qt
    from PySide6.QtTest import QTest

    from prismstation.gui.app import make_app, take_screenshot, wait_settled
    from prismstation.gui.main_window import MainWindow

    make_app()

    def window(open_project=True, dem=True):
        win = MainWindow(interactive=False, demo_maker=lambda progress=None: project)
        win.files.interactive = False
        win.show()
        if open_project:
            assert win.open_project(str(project), recover=False)
            if dem:
                win.load_reference_dem(project.parent / "triplet" / "srtm.tif", wait=True)
            wait_settled(win)
            win.statusBar().clearMessage()  # (the DEM's path in the temporary folder)
        return win

    def save(win, name, size):
        QCoreApplication.processEvents()
        save_image(win.grab(), out / name, size)

    def close(win):
        win.undo_stack.setClean()
        win.close()
        win.deleteLater()
        QCoreApplication.processEvents()

    def lay_out(win, size):
        win.resize(*size)
        win.default_layout()
        wait_settled(win)

    if wanted("start_page"):
        win = window(open_project=False)
        win.resize(1280, 720)
        wait_settled(win)
        save(win, "start_page.png", (1280, 720))
        close(win)

    if wanted("window", "screenshot"):  # the demo as it opens
        win = window()
        for size in SIZES + ((1680, 1050),):
            take_screenshot(win, tmp / "x.png", size=size)
            win.statusBar().clearMessage()  # (the temporary folder's name)
            save(win, "screenshot.png" if size == (1680, 1050) else f"window_{size[0]}x{size[1]}.png", size)
        close(win)

    # editing the known height of G01 in the table, the views at 1:1 on it
    from prismstation.gui.point_table import COLUMNS
    for size in SIZES if wanted("editing_1", "editing_") else ():
        win = window()
        lay_out(win, size)
        win.set_current("G01", drive=True)
        for iv in win.views.views.values():
            iv.set_scale(1.0)
        win.views.drive_to("G01", scale=1.0)
        wait_settled(win)
        t, m = win.table, win.table_model
        idx = m.index(m.row_of("G01"), COLUMNS.index("H (m)"))
        t.scrollTo(idx)
        t.setCurrentIndex(idx)
        t.edit(idx)
        wait_settled(win)
        save(win, f"editing_{size[0]}x{size[1]}.png", size)
        close(win)

    # predictions of a new point measured in N
    def new_point_in_n(win, transfer=False):
        tools = win.tools
        if "transfer" in tools and hasattr(tools["transfer"], "a_auto"):
            tools["transfer"].a_auto.setChecked(transfer)
        g = win.project.measurement("G06", "N")
        x, y = g.x + 32.0, g.y - 26.0
        win.new_point()
        pid = win.current
        for iv in win.views.views.values():
            iv.set_scale(0.125)
        iv = win.views.views["N"]
        iv.center_on(x, y, 0.125)
        wait_settled(win)
        QTest.mouseClick(iv.graphics.viewport(), Qt.MouseButton.LeftButton,
                         Qt.KeyboardModifier.NoModifier, iv.map_to_viewport(x, y).toPoint())
        wait_settled(win)
        return pid, win.project.measurement(pid, "N")

    def point_at(win, m):
        """The mouse over the point in N: the loupes and the linked crosshairs on it."""
        iv = win.views.views["N"]
        QTest.mouseMove(iv.graphics.viewport(), iv.map_to_viewport(m.x, m.y).toPoint())
        wait_settled(win)

    def centre_on_predictions(win, pid, m):
        for v, iv in win.views.views.items():
            xy = win.views.point_position(pid, v)
            if xy is not None:
                iv.center_on(*xy, 0.125)
        wait_settled(win)
        point_at(win, m)

    for size in SIZES if wanted("predictions_dem", "predictions_intersection") else ():
        win = window()
        lay_out(win, size)
        pid, m = new_point_in_n(win)
        centre_on_predictions(win, pid, m)
        win.statusBar().showMessage(f"{pid}: F, B at the DEM's height; dashed: 95 % ellipse")
        save(win, f"predictions_dem_{size[0]}x{size[1]}.png", size)
        if size == (1600, 1000):
            xy = win.views.point_position(pid, "B")  # measured in B too: F from the intersection
            iv = win.views.views["B"]
            QTest.mouseClick(iv.graphics.viewport(), Qt.MouseButton.LeftButton,
                             Qt.KeyboardModifier.NoModifier, iv.map_to_viewport(*xy).toPoint())
            wait_settled(win)
            centre_on_predictions(win, pid, m)
            win.statusBar().showMessage(f"{pid}: measured in N and B; F from the intersection")
            save(win, "predictions_intersection_1600x1000.png", size)
        close(win)

    if wanted("predictions_mean_height"):
        win = window(dem=False)
        lay_out(win, (1600, 1000))
        pid, m = new_point_in_n(win)
        centre_on_predictions(win, pid, m)
        win.statusBar().showMessage(f"{pid}: no DEM: at the mean height, along the parallax")
        save(win, "predictions_mean_height_1600x1000.png", (1600, 1000))
        close(win)

    if wanted("predictions_transfer"):
        win = window()
        lay_out(win, (1600, 1000))
        pid, m = new_point_in_n(win, transfer=True)
        tool = win.tools.get("transfer")
        while getattr(tool, "job", None) is not None and tool.job.isRunning():
            QCoreApplication.processEvents()
        for _ in range(50):
            QCoreApplication.processEvents()
        wait_settled(win)
        point_at(win, m)
        save(win, "predictions_transfer_1600x1000.png", (1600, 1000))
        close(win)

    if wanted("editing_new_point"):
        win = window()
        lay_out(win, (1600, 1000))
        save_image(new_point_picture(win, project), out / "editing_new_point.png", (1600, 1000))
        close(win)

    if wanted("ortho"):
        win = window()
        lay_out(win, (1600, 1000))
        ortho_picture(win, project, tmp)
        save(win, "ortho_1600x1000.png", (1600, 1000))
        close(win)

    if wanted("orient_srtm"):
        win = window()
        lay_out(win, (1600, 1000))
        orient_picture(win, project)
        save(win, "orient_srtm_1600x1000.png", (1600, 1000))
        close(win)

    if wanted("image_view"):
        save_image(image_views_picture(Path(args.triplet) if args.triplet else project.parent / "triplet"),
                   out / "image_view.png", (1500, 560))
    return 0


def save_image(img, path: Path, size) -> None:
    """Save a QImage or QPixmap at ``path``, checked to be exactly ``size``."""
    assert (img.width(), img.height()) == tuple(size), (path.name, img.width(), img.height())
    if not img.save(str(path)):
        raise SystemExit(f"screenshots: cannot write {path}")
    print("wrote", path)


def wait_job(job, timeout_s: float = 600.0):
    """Process events until a tool's Job ends; its result (SystemExit if it fails)."""
    import time

    from PySide6.QtCore import QCoreApplication, QThread
    got = []
    job.result.connect(lambda v: got.append(("result", v)))
    job.failed.connect(lambda m: got.append(("failed", m)))
    job.cancelled.connect(lambda: got.append(("cancelled", None)))
    t0 = time.monotonic()
    while not got and time.monotonic() - t0 < timeout_s:
        QCoreApplication.processEvents()
        QThread.msleep(10)
    if not got or got[0][0] != "result":
        raise SystemExit(f"screenshots: the job ended with {got[0] if got else 'a timeout'}")
    return got[0][1]


def orient_picture(win, project) -> None:
    """Tools ▸ Orient from reference DEM… as its dialog's defaults make it (the demo's reference,
    patches of a quarter of the scene, 50 m per view, the one-pixel target), its dock raised and
    its verdict in view."""
    from prismstation.gui.app import wait_settled
    from prismstation.ops.orientation import default_patch_km

    tool = win.tools["dem_orientation"]
    ref = project.parent / "triplet" / "srtm.tif"
    wait_job(tool.start(str(ref), default_patch_km(win.project.scene) * 1000.0))
    tool.dock.raise_()
    wait_settled(win)
    win.statusBar().showMessage("Orientation from the reference DEM: trusted, applied")


def ortho_picture(win, project, tmp: Path) -> None:
    """Tools ▸ Orthoimage… as the dialog's defaults make it (the reference view on the loaded
    reference DEM), its dock raised, the model panel closed and the right column widened to half
    the window, the ortho checked at the points."""
    from PySide6.QtCore import QCoreApplication, Qt

    from prismstation.gui.app import wait_settled
    from prismstation.ops.ortho import OrthoRequest

    tool = win.tools["ortho"]
    view = win.project.scene.reference_view
    ref = project.parent / "triplet" / "srtm.tif"
    wait_job(tool.start(OrthoRequest(output=str(tmp / "demo_ortho.tif"), views=(view,), dem=str(ref))))
    tool.dock.raise_()
    win.docks["model"].hide()       # the right column for the ortho, wider: as an operator drags it
    win.resizeDocks([tool.dock], [int(win.width() * 0.5)], Qt.Orientation.Horizontal)
    wait_settled(win)
    wait_job(tool.viewer.validate())
    v = tool.viewer.view
    QCoreApplication.processEvents()
    v.fit()
    for _ in range(400):
        QCoreApplication.processEvents()
        if v.tiles_complete():
            break
    win.statusBar().showMessage(tool.message.splitlines()[0].replace(str(tmp) + "/", ""))
    QCoreApplication.processEvents()


def new_point_picture(win, project):
    """Edit ▸ New point from coordinates… with a surveyed point (the ground truth of the demo's
    tie point T10, near the image centre, typed as a GCP with orthometric height): the dialog
    as filled in, drawn over the plots of the window after OK — the point current, the views
    driven to its predictions, the mouse over its prediction in N (the loupes on it)."""
    import json

    from PySide6.QtCore import QCoreApplication, QPoint, QTimer
    from PySide6.QtGui import QColor, QPainter, QPen
    from PySide6.QtTest import QTest
    from PySide6.QtWidgets import QApplication

    from prismstation.gui.app import wait_settled
    from prismstation.gui.point_editor import NewPointDialog

    truth = {p["id"]: p for p in json.loads((project.parent / "triplet" / "truth.json").read_text())["points"]}
    t = truth["T10"]
    shot = {}

    def fill(left=200):
        dlg = QApplication.activeModalWidget()
        if not isinstance(dlg, NewPointDialog):
            if left:
                QTimer.singleShot(20, lambda: fill(left - 1))
            return
        for w, v in ((dlg.e, t["E"]), (dlg.n, t["N"]), (dlg.h, t["H"])):
            w.setText(f"{v:.3f}")
        dlg.height_kind.setCurrentText("orthometric")
        dlg.s_xy.setText("0.05")
        dlg.s_h.setText("0.08")
        dlg.e.selectAll()
        dlg.e.setFocus()
        QCoreApplication.processEvents()
        shot["dialog"] = dlg.grab()
        dlg.accept()
    action = next(a for a in win.findChildren(type(win.tools_menu.menuAction()))
                  if a.text() == "New point from &coordinates…")
    QTimer.singleShot(20, fill)
    action.trigger()
    assert "dialog" in shot, "the New point dialog did not open"
    wait_settled(win)
    iv = win.views.views["N"]
    xy = win.views.point_position(win.current, "N")
    QTest.mouseMove(iv.graphics.viewport(), iv.map_to_viewport(*xy).toPoint())
    wait_settled(win)
    img = win.grab()
    d = shot["dialog"]
    plots = win.plots
    corner = plots.mapTo(win, QPoint(24, max(plots.height() - d.height(), 0) // 2))
    corner.setY(min(corner.y(), img.height() - d.height() - 30))  # above the status bar
    p = QPainter(img)
    p.fillRect(corner.x() + 4, corner.y() + 4, d.width(), d.height(), QColor(0, 0, 0, 90))  # shadow
    p.drawPixmap(corner, d)
    p.setPen(QPen(QColor(90, 90, 90), 1))
    p.drawRect(corner.x(), corner.y(), d.width() - 1, d.height() - 1)
    p.end()
    return img


def image_views_picture(folder: Path):
    """Three image views side by side, each with its loupe and contrast panel, on the three
    images of ``folder``; the middle one zoomed to 2 screen px per image px, a cursor at
    (0.4, 0.45) of each image."""
    from PySide6.QtCore import QCoreApplication, QThread
    from PySide6.QtWidgets import QHBoxLayout, QSplitter, QVBoxLayout, QWidget

    from prismstation.gui.contrast import ContrastPanel
    from prismstation.gui.image_view import ImageView
    from prismstation.gui.loupe import Loupe
    from prismstation.io.raster import RasterSource

    paths = sorted(folder.glob("img_0*.tif")) or [folder / f"{v}.tif" for v in "NFB"]
    win = QWidget()
    split = QSplitter()
    views = []
    for p in paths:
        col = QWidget()
        lay = QVBoxLayout(col)
        v = ImageView()
        v.setMinimumHeight(380)
        lay.addWidget(v, 1)
        row = QHBoxLayout()
        loupe = Loupe(zoom=6, pixels=21)
        panel = ContrastPanel(v)
        row.addWidget(loupe)
        row.addWidget(panel, 1)
        lay.addLayout(row)
        split.addWidget(col)
        views.append((v, loupe, panel, p))
    QHBoxLayout(win).addWidget(split)
    win.resize(1500, 560)
    win.show()
    for i, (v, loupe, panel, p) in enumerate(views):
        v.set_source(RasterSource(p))
        panel.refresh()
        loupe.attach(v)
        if i == 1:
            v.center_on(v.source.width / 2, v.source.height / 2, scale=0.5)
        v.cursor_moved.emit(v.source.width * 0.4, v.source.height * 0.45)
    for _ in range(1000):
        QCoreApplication.processEvents()
        if all(v.tiles_complete() for v, *_ in views):
            break
        QThread.msleep(5)
    for _ in range(10):
        QCoreApplication.processEvents()
    img = win.grab()
    for v, *_ in views:
        v.close()
    win.close()
    win.deleteLater()
    return img


if __name__ == "__main__":
    sys.exit(main())
