"""The picture of the window on a project of images with RPCs, ``rpc_window_1600x1000.png``
(``benchmarks/screenshots.py --rpc IMG IMG [IMG …]``, offscreen)."""
from __future__ import annotations

from pathlib import Path


def rpc_window(images, out: Path, tmp: Path, size=(1600, 1000), cell: int = 64) -> int:
    """``rpc_window_1600x1000.png``: the window on a project of ``images`` (with RPCs).

    Tie points are matched automatically between the images
    (:func:`prismstation.core.matching.rpc_tiepoints.match_tie_points`, one per ``cell`` px) and given
    to ``new --images``; the reference DEM is the tie points' own heights by the unbiased RPCs
    (``fit --bias none``), gridded at 5 m (no DEM covering such crops is at hand: a DEM with no
    offset to the RPCs), then ``fit --bias shift`` stored. The window opens the project with shift biases, the first image held
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
    from prismstation.core.matching.rpc_tiepoints import match_tie_points
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
    assert cli(["new", str(project), "--images", *map(str, images), "--no-ties", "--measurements", str(tmp / "ties.csv")]) == 0
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
        ds.update_tags(HEIGHTS="ellipsoidal")    # the tie points' heights: the RPCs' datum
    assert cli(["fit", str(project), "--bias", "shift"]) == 0  # fit keeps its settings: shift again

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
