"""The pictures of the window in docs/, made from the demo project (offscreen).

``window_WxH.png`` and ``screenshot.png`` (the demo as it opens), ``editing_WxH.png`` (the known
height of G01 typed in the table, the views at 1:1 on it), ``predictions_dem_WxH.png`` (a new
point measured in N, predicted in F and B at the reference DEM's height with its 95 % ellipse),
``predictions_intersection``, ``predictions_mean_height``, ``predictions_transfer`` (1600 × 1000)
and ``start_page.png``. Every picture is checked to be exactly the size asked for (nothing
below the screen's edge).

With ``--rpc IMG IMG [IMG …]`` (images with RPCs) it makes ``rpc_window_1600x1000.png`` instead
(:func:`rpc_window`): the window on a project of those images.

Run: ``.venv/bin/python benchmarks/screenshots.py [--project P] [--out docs]``
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
    ap.add_argument("--rpc", nargs="+", metavar="IMG", help="images with RPCs: the RPC picture only")
    args = ap.parse_args(argv)
    out = Path(args.out)
    tmp = Path(tempfile.mkdtemp(prefix="screenshots-"))
    os.environ["PRISMSTATION_SETTINGS_DIR"] = str(tmp / "settings")
    if args.rpc:
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
        return win

    def save(win, name, size):
        QCoreApplication.processEvents()
        img = win.grab()
        assert (img.width(), img.height()) == tuple(size), (name, img.width(), img.height())
        img.save(str(out / name))
        print("wrote", out / name)

    def close(win):
        win.undo_stack.setClean()
        win.close()
        win.deleteLater()
        QCoreApplication.processEvents()

    def lay_out(win, size):
        win.resize(*size)
        win.default_layout()
        wait_settled(win)

    # the start page
    win = window(open_project=False)
    win.resize(1280, 720)
    wait_settled(win)
    save(win, "start_page.png", (1280, 720))
    close(win)

    # the demo as it opens
    win = window()
    for size in SIZES + ((1680, 1050),):
        take_screenshot(win, tmp / "x.png", size=size)
        win.statusBar().clearMessage()  # (the temporary folder's name)
        save(win, "screenshot.png" if size == (1680, 1050) else f"window_{size[0]}x{size[1]}.png", size)
    close(win)

    # editing the known height of G01 in the table, the views at 1:1 on it
    from prismstation.gui.point_table import COLUMNS
    for size in SIZES:
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

    for size in SIZES:
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

    win = window(dem=False)
    lay_out(win, (1600, 1000))
    pid, m = new_point_in_n(win)
    centre_on_predictions(win, pid, m)
    win.statusBar().showMessage(f"{pid}: no DEM: at the mean height, along the parallax")
    save(win, "predictions_mean_height_1600x1000.png", (1600, 1000))
    close(win)

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
    return 0


def rpc_window(images, out: Path, tmp: Path, size=(1600, 1000), cell: int = 64) -> int:
    """``rpc_window_1600x1000.png``: the window on a project of ``images`` (with RPCs).

    Tie points are matched automatically between the images
    (:func:`prismstation.core.rpc_tiepoints.match_tie_points`, one per ``cell`` px) and given
    to ``new --images``; the reference DEM is the tie points' own heights by the unbiased RPCs
    (``fit --bias none``), gridded at 5 m (no DEM covering such crops is at hand: a DEM with no
    offset to the RPCs). The window opens the project with shift biases, the first image held
    fixed, the DEM loaded; a new point is measured in the first image and predicted in the
    others with its 95 % ellipse, the views at 4:1 on it.
    """
    import csv
    import json

    import numpy as np
    import rasterio
    from PySide6.QtCore import QCoreApplication, Qt
    from PySide6.QtTest import QTest
    from rasterio.transform import from_origin
    from scipy.interpolate import griddata

    from prismstation.cli import main as cli
    from prismstation.core.rpc_tiepoints import match_tie_points
    from prismstation.gui.app import make_app, wait_settled
    from prismstation.gui.main_window import MainWindow

    arrays = []
    for f in images:
        with rasterio.open(f) as ds:
            arrays.append(ds.read(1))
    tp = match_tie_points(arrays, cell=cell)
    with open(tmp / "ties.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["id", "view", "x", "y", "sigma_px"])
        for j, i, xy, s in zip(tp.point, tp.image, tp.xy, tp.sigma):
            w.writerow([f"T{j:04d}", images[i].stem, float(xy[0]), float(xy[1]), float(s[0])])
    project = tmp / "block.prismproj"
    assert cli(["new", str(project), "--images", *map(str, images), "--measurements", str(tmp / "ties.csv")]) == 0
    assert cli(["fit", str(project), "--bias", "none", "--json", str(tmp / "before.json")]) == 0
    report = json.loads((tmp / "before.json").read_text())
    pts = [p for p in report["points"] if p.get("h_est") is not None]
    en = np.array([(p["E_est"], p["N_est"]) for p in pts])
    h = np.array([p["h_est"] for p in pts])
    x0, y1 = en.min(0)[0] - 200, en.max(0)[1] + 200
    nx, ny = int((en[:, 0].max() + 200 - x0) / 5), int((y1 - en[:, 1].min() + 200) / 5)
    E, N = np.meshgrid(x0 + 2.5 + 5 * np.arange(nx), y1 - 2.5 - 5 * np.arange(ny))
    grid = griddata(en, h, (E, N), method="linear")
    grid = np.where(np.isfinite(grid), grid, griddata(en, h, (E, N), method="nearest"))
    with rasterio.open(tmp / "dem.tif", "w", driver="GTiff", width=nx, height=ny, count=1, dtype="float32",
                       crs=report["crs"], transform=from_origin(x0, y1, 5, 5)) as ds:
        ds.write(grid.astype("float32"), 1)

    make_app()
    win = MainWindow(interactive=False)
    win.files.interactive = False
    win.show()
    assert win.open_project(str(project), recover=False)
    win.load_reference_dem(tmp / "dem.tif", wait=True)
    win.resize(*size)
    win.default_layout()
    wait_settled(win)
    first = next(iter(win.views.views))
    tools = win.tools
    if "transfer" in tools and hasattr(tools["transfer"], "a_auto"):
        tools["transfer"].a_auto.setChecked(False)  # the predictions, not a transfer
    x, y = 0.45 * arrays[0].shape[1], 0.55 * arrays[0].shape[0]
    win.new_point()
    pid = win.current
    iv = win.views.views[first]
    iv.center_on(x, y, 1.0)
    wait_settled(win)
    QTest.mouseClick(iv.graphics.viewport(), Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier,
                     iv.map_to_viewport(x, y).toPoint())
    wait_settled(win)
    win.views.drive_to(pid, scale=0.25)  # 4 screen px per image px: the ellipses show
    wait_settled(win)
    QTest.mouseMove(iv.graphics.viewport(), iv.map_to_viewport(x, y).toPoint())
    wait_settled(win)
    win.statusBar().showMessage(f"{pid}: predicted at the DEM's height; dashed: 95 % ellipse")
    QCoreApplication.processEvents()
    img = win.grab()
    assert (img.width(), img.height()) == tuple(size), (img.width(), img.height())
    name = out / f"rpc_window_{size[0]}x{size[1]}.png"
    img.save(str(name))
    print("wrote", name, f"({len(set(tp.point))} tie points)")
    win.undo_stack.setClean()
    win.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
