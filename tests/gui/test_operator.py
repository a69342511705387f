"""The real window driven as an operator would: mouse clicks on the views, keys, the table."""
from __future__ import annotations

import math

import numpy as np
import pytest
from PySide6.QtCore import QPoint, QPointF, Qt

from prismstation.io.project import load_project
from prismstation.ops.fit import solve_project


def settle(qtbot, win):
    qtbot.waitUntil(lambda: not win.solver.busy() and win.solver.solution is not None
                    and win.solver.solution.revision == win.project.revision, timeout=10000)


def click_image(qtbot, win, view, x, y, modifier=Qt.KeyboardModifier.NoModifier):
    """Left click on the viewport where image (x, y) of ``view`` is displayed; returns the
    image position actually under the click (viewport positions are whole pixels)."""
    iv = win.views.views[view]
    pos = iv.map_to_viewport(x, y).toPoint()
    qtbot.mouseClick(iv.graphics.viewport(), Qt.MouseButton.LeftButton, modifier, pos)
    return iv.map_from_viewport(QPointF(pos))


def click_row(qtbot, win, pid):
    t = win.table
    idx = t.source_model.index(t.source_model.row_of(pid), 0)
    t.scrollTo(idx)
    qtbot.mouseClick(t.viewport(), Qt.MouseButton.LeftButton, pos=t.visualRect(idx).center())


def key(qtbot, win, seq: str):
    from PySide6.QtGui import QKeySequence
    ks = QKeySequence(seq)[0]
    qtbot.keyClick(win, ks.key(), ks.keyboardModifiers())


def gcp_stats_n(win):
    return win.solver.solution.stats["image"]["N"]["GCP"]["px"].n


def test_measure_a_gcp_by_clicks_undo_redo_save_reopen(qtbot, window):
    win, demo = window, window.demo
    model = win.table_model
    assert model.cell("G9", "Views") == "· · ·"
    assert model.cell("G9", "vx (px)") == ""
    assert gcp_stats_n(win) == 8
    assert "Table 1 — image residuals, view N (m)" in win.panel.plain_text()

    click_row(qtbot, win, "G9")                   # select in the table: drive-to
    assert win.current == "G9"
    for v, (x, y) in demo.truth["G9"].items():    # the hollow predicted marker is close to truth
        px, py = win.views.point_position("G9", v)
        assert math.hypot(px - x, py - y) < 3.0
        cx, cy = win.views.views[v].center()
        assert math.hypot(cx - px, cy - py) < 1.0

    placed = {}
    for v in ("N", "F", "B"):
        placed[v] = click_image(qtbot, win, v, *demo.truth["G9"][v])
    settle(qtbot, win)
    for v in ("N", "F", "B"):
        m = win.project.measurement("G9", v)
        scale = win.views.views[v].scale()
        assert math.hypot(m.x - demo.truth["G9"][v][0], m.y - demo.truth["G9"][v][1]) <= 0.75 * scale + 1e-6
        assert math.hypot(m.x - placed[v][0], m.y - placed[v][1]) < 1e-6
    assert model.cell("G9", "Views") == "N F B"
    assert gcp_stats_n(win) == 9
    assert win.isWindowModified()

    # independent reference: the engine on a project loaded from disk plus these measurements
    ref = load_project(demo.path)
    for v in ("N", "F", "B"):
        ref.set_measurement(win.project.measurement("G9", v))
    rsol = solve_project(ref)
    vx = rsol.point("G9").residual_px["N"][0]
    assert float(model.cell("G9", "vx (px)")) == round(vx, 3) or abs(float(model.cell("G9", "vx (px)")) - vx) < 6e-4
    assert abs(win.solver.solution.stats["image"]["N"]["GCP"]["m"].x.rms
               - rsol.stats["image"]["N"]["GCP"]["m"].x.rms) < 1e-9

    # undo three clicks with the keyboard, redo them
    for _ in range(3):
        key(qtbot, win, "Ctrl+Z")
    settle(qtbot, win)
    assert model.cell("G9", "Views") == "· · ·" and gcp_stats_n(win) == 8
    for _ in range(3):
        key(qtbot, win, "Ctrl+Shift+Z")
    settle(qtbot, win)
    assert model.cell("G9", "Views") == "N F B" and gcp_stats_n(win) == 9

    key(qtbot, win, "Ctrl+S")
    assert win.undo_stack.isClean() and not win.isWindowModified()
    before = {k: (m.x, m.y) for k, m in win.project.measurements.items()}
    table_before = [model.cell(pid, c) for pid in model.ids for c in ("Views", "vx (px)", "h est (m)")]

    assert win.open_project(demo.path, recover=False)
    settle(qtbot, win)
    assert {k: (m.x, m.y) for k, m in win.project.measurements.items()} == before
    assert [model.cell(pid, c) for pid in model.ids for c in ("Views", "vx (px)", "h est (m)")] == table_before


def test_click_in_create_mode_creates_a_tie_point_and_drag_moves_it(qtbot, window):
    win = window
    win.set_current(None)
    key(qtbot, win, "C")
    n0 = len(win.project.points)
    iv = win.views.views["N"]
    iv.set_scale(1.0)
    iv.center_on(400, 400)
    # a spot away from any marker
    xy = next((x, y) for x in range(100, 700, 37) for y in range(100, 700, 41)
              if win.views.overlays["N"].nearest(x, y, 30) is None)
    iv.center_on(*xy)
    got = click_image(qtbot, win, "N", *xy)
    assert len(win.project.points) == n0 + 1
    pid = win.current
    assert win.project.points[pid].kind == "TIE"
    settle(qtbot, win)
    # the new point has its own row in the table, and it is the row selected
    row = win.table_model.row_of(pid)
    assert row >= 0 and win.table_model.cell(pid, "ID") == pid
    assert win.table_model.rowCount() == n0 + 1
    assert [i.row() for i in win.table.selectionModel().selectedRows()] == [row]
    assert win.table_model.cell(pid, "Views") == "N · ·"
    assert win.table_model.cell(pid, "Kind") == "TIE"

    # drag the marker by 24 screen pixels right, 12 down, with real mouse events
    vp = iv.graphics.viewport()
    # grab the marker a few pixels off its centre (inside the pick tolerance), so that the
    # press is not taken for the second half of a double click on the placing click
    start = iv.map_to_viewport(*got).toPoint() + QPoint(5, 4)
    steps = [start + QPoint(3 * i, int(1.5 * i)) for i in range(1, 9)]
    count = win.undo_stack.count()

    qtbot.wait(600)  # longer than a double-click interval after the click
    qtbot.mousePress(vp, Qt.MouseButton.LeftButton, pos=start)
    for p in steps:
        qtbot.wait(25)  # pyqtgraph drops mouse moves closer than its rate limit
        qtbot.mouseMove(vp, p)
    qtbot.mouseRelease(vp, Qt.MouseButton.LeftButton, pos=steps[-1])
    m = win.project.measurement(pid, "N")
    end = iv.map_from_viewport(QPointF(steps[-1]))
    grab = iv.map_from_viewport(QPointF(start))          # the marker keeps its grab offset
    assert math.hypot(m.x - (end[0] + got[0] - grab[0]), m.y - (end[1] + got[1] - grab[1])) < 1e-6
    assert win.undo_stack.count() == count + 1          # the whole drag is one step
    win.undo_stack.undo()
    m = win.project.measurement(pid, "N")
    assert (m.x, m.y) == got
    win.undo_stack.undo()                                # the click: the tie point goes
    assert pid not in win.project.points


def test_drive_to_and_next_point(qtbot, window):
    win = window
    click_row(qtbot, win, "I3")
    scales = [iv.scale() for iv in win.views.views.values()]
    assert max(scales) - min(scales) < 1e-6 and scales[0] <= 1.0 + 1e-9
    for v, iv in win.views.views.items():
        m = win.project.measurement("I3", v)
        cx, cy = iv.center()
        assert math.hypot(cx - m.x, cy - m.y) < 0.01
    ids = win.table.ordered_ids()
    key(qtbot, win, "PgDown")
    nxt = ids[(ids.index("I3") + 1) % len(ids)]
    assert win.current == nxt and win.table.current_id() == nxt
    for v, iv in win.views.views.items():
        xy = win.views.point_position(nxt, v)
        assert math.hypot(iv.center()[0] - xy[0], iv.center()[1] - xy[1]) < 0.01
    key(qtbot, win, "PgUp")
    assert win.current == "I3"


def test_linked_cursor_lands_where_the_model_says(qtbot, window):
    win, demo = window, window.demo
    sol = win.solver.solution
    # over a GCP: the point's height is used, so the crosshair lands on the same ground point
    iv = win.views.views["N"]
    iv.set_scale(1.0)
    m = win.project.measurement("G2", "N")
    iv.center_on(m.x, m.y)
    pos = iv.map_to_viewport(m.x, m.y).toPoint()
    with qtbot.waitSignal(win.views.cursor_info, timeout=2000) as sig:
        qtbot.mouseMove(iv.graphics.viewport(), pos)
    view, x, y, linked, ground = sig.args
    assert view == "N"
    for v in ("F", "B"):
        ch = win.views.overlays[v].crosshair
        assert ch.isVisible()
        (cx,), (cy,) = ch.getData()
        assert (cx, cy) == linked[v]
        tx, ty = demo.truth["G2"][v]
        assert math.hypot(cx - tx, cy - ty) < 2.0        # truth of the simulated geometry
    assert not win.views.overlays["N"].crosshair.isVisible()
    assert abs(ground[2] - sol.point("G2").ground_est[2]) < 1e-9
    assert f"E {ground[0]:.1f}" in win.status_ground.text()
    assert win.status_xy["F"].text().startswith("F  x")
    # away from points: the mean scene height, and back again gives the same pixel
    lk, g = win.views.linked("N", 123.0, 456.0)
    assert g[2] == sol.mean_height
    back = sol.ground_to_image("N", sol.image_to_ground("F", np.array(lk["F"]), g[2]), g[2])
    assert np.allclose(back, (123.0, 456.0), atol=1e-3)


def test_kind_switch_delete_and_settings_are_undoable(qtbot, window):
    win = window
    click_row(qtbot, win, "I1")
    key(qtbot, win, "Ctrl+1")
    settle(qtbot, win)
    assert win.project.points["I1"].kind == "GCP" and win.table_model.cell("I1", "Kind") == "GCP"
    assert gcp_stats_n(win) == 9
    win.undo_stack.undo()
    settle(qtbot, win)
    assert win.table_model.cell("I1", "Kind") == "ICP"
    n_meas = len(win.project.measurements)
    key(qtbot, win, "Shift+Del")
    settle(qtbot, win)
    assert "I1" not in win.project.points and win.table_model.row_of("I1") < 0
    assert len(win.project.measurements) == n_meas - 3
    win.undo_stack.undo()
    settle(qtbot, win)
    assert len(win.project.measurements) == n_meas and win.table_model.row_of("I1") >= 0
    # bias model from the model panel
    combo = win.panel.bias
    combo.setCurrentText("shift")
    combo.activated.emit(combo.currentIndex())
    settle(qtbot, win)
    assert win.solver.solution.bias["N"].model == "shift"
    assert "Bias N (shift)" in win.panel.plain_text()
    win.undo_stack.undo()
    settle(qtbot, win)
    assert win.solver.solution.bias["N"].model == "affine" and combo.currentText() == "affine"


def test_blunder_is_highlighted(qtbot, window):
    win = window
    m = win.project.measurement("G3", "N")
    win.move("G3", "N", m.x + 25.0, m.y - 20.0, True)
    # a strict threshold typed into the model panel makes the engine flag one GCP
    win.panel.threshold.setValue(1.2)
    win.panel.threshold.editingFinished.emit()
    settle(qtbot, win)
    sol = win.solver.solution
    assert sol.settings.blunder_threshold == 1.2
    flagged = [r.id for r in sol.points if r.blunder]
    assert flagged == [r.id for r in sol.points if r.std_residual is not None and r.std_residual > 1.2]
    assert "G3" in flagged
    pid = "G3"
    assert win.table_model.is_blunder(pid)
    idx = win.table_model.index(win.table_model.row_of(pid), 0)
    from prismstation.gui.point_table import BLUNDER_BG

    def bg(i):
        b = win.table_model.data(i, Qt.ItemDataRole.BackgroundRole)
        return None if b is None else b.color()
    assert bg(idx) == BLUNDER_BG
    others = [r for r in win.table_model.ids if r not in flagged]
    assert all(bg(win.table_model.index(win.table_model.row_of(o), 0)) != BLUNDER_BG for o in others)
    assert f"Blunder: {pid}" in win.panel.plain_text()
    for v, ov in win.views.overlays.items():  # drawn over its marker in every view it is in
        m = win.project.measurement(pid, v)
        if m is not None:
            assert (m.x, m.y) in list(zip(*ov.blunders.getData())), v


def test_autosave_and_recovery(qtbot, window, demo):
    from prismstation.gui.project_io import autosave_path
    win = window
    key(qtbot, win, "C")                          # create mode: the click makes a tie point
    click_image(qtbot, win, "N", 200.0, 200.0, Qt.KeyboardModifier.ShiftModifier)
    pid = win.current
    assert win.files.autosave()
    side = autosave_path(demo.path)
    assert side.is_file()
    assert win.open_project(demo.path, recover=True, check_unsaved=False)
    assert pid in win.project.points and not win.undo_stack.isClean()
    assert win.open_project(demo.path, recover=False, check_unsaved=False)
    assert pid not in win.project.points
    win.files.save()
    assert not side.exists()


def test_import_csv_with_an_error_line_is_named_and_one_step(qtbot, window, tmp_path):
    from prismstation.gui.import_dialog import ImportDialog
    win = window
    csv = tmp_path / "more.csv"
    rows = ["id,view,x,y", "T90,N,100.5,200.5", "T90,F,110.5,190.5", "T91,N,300,oops", "T92,B,50,60"]
    csv.write_text("\n".join(rows) + "\n")
    dlg = ImportDialog(list(win.project.scene.views), win.project.scene.crs, win)
    qtbot.addWidget(dlg)
    dlg.set_path(str(csv))
    qtbot.waitUntil(lambda: bool(dlg.errors()), timeout=3000)
    assert any("line 4" in e and "more.csv" in e for e in dlg.errors())
    assert dlg.result() == ([], [])
    fixed = tmp_path / "more_fixed.csv"  # the operator fixes line 4 and picks the file again
    fixed.write_text("\n".join(rows).replace("oops", "400") + "\n")
    dlg.set_path(str(fixed))
    qtbot.waitUntil(lambda: not dlg.errors() and bool(dlg.result()[1]), timeout=3000)
    points, ms = dlg.result()
    n = win.undo_stack.count()
    win.push_import(points, ms)
    settle(qtbot, win)
    assert win.undo_stack.count() == n + 1
    assert win.table_model.cell("T90", "Views") == "N F ·"
    win.undo_stack.undo()
    settle(qtbot, win)
    assert "T90" not in win.project.points and win.table_model.row_of("T90") < 0


def test_layout_and_recent_files_persist(qtbot, window, demo):
    from prismstation.gui import settings as st
    from prismstation.gui.main_window import MainWindow
    win = window
    assert st.value(st.Key.RECENT_FILES)[0] == str(demo.path.resolve())
    win.docks["plots"].hide()
    win.resize(1234, 876)
    win.save_layout()
    w2 = MainWindow(interactive=False)
    qtbot.addWidget(w2)
    w2.show()
    assert w2.central.currentWidget() is w2.start_page  # no project: the start page
    assert w2.files.new_project(str(demo.path.parent / "scene.json"))
    assert w2.docks["plots"].isHidden() and not w2.docks["points"].isHidden()
    assert w2.recent_menu.actions()[0].text() == str(demo.path.resolve())
    w2.close()


def test_gui_command_screenshot_writes_the_window(demo, tmp_path):
    from PySide6.QtGui import QImage
    from prismstation.cli import main
    png = tmp_path / "shot.png"
    assert main(["gui", str(demo.path), "--screenshot", str(png)]) == 0
    img = QImage(str(png))
    assert img.width() >= 1600 and img.height() >= 1000


def test_unsaved_changes_prompt_and_relocated_images(qtbot, window, demo, tmp_path):
    from PySide6.QtWidgets import QMessageBox
    B = QMessageBox.StandardButton
    win = window
    win.measure_mode.set_mode("create")
    win.place("N", 300.0, 300.0)
    assert win.isWindowModified()
    answers = []
    win.files.ask = lambda *a, **k: answers.pop(0)
    answers.append(B.Cancel)                       # close → "Save?" → Cancel: the window stays
    assert not win.files.maybe_save() and win.project is not None
    answers.append(B.Discard)                      # open another project, discarding the edit
    moved = tmp_path / "moved"
    moved.mkdir()
    for v in ("N", "F", "B"):                      # the images move away from the scene
        (demo.path.parent / f"{v}.tif").rename(moved / f"{v}.tif")
    answers.append(B.Yes)                          # "Images not found: choose the folder?" → yes
    win.files.choose_dir = lambda title: str(moved)
    assert win.open_project(demo.path, recover=False)
    assert win.files.stack.isClean() and not answers
    assert {v: view.image for v, view in win.project.scene.views.items()} == \
        {v: str((moved / f"{v}.tif").resolve()) for v in ("N", "F", "B")}
    assert win.views.wait_loaded() and all(iv.source is not None for iv in win.views.views.values())
    win.files.save()                               # the relocation is kept in the project
    assert win.open_project(demo.path, recover=False)
    assert win.project.scene.views["F"].image == str((moved / "F.tif").resolve())


def test_export_report_csv_json_html(window, tmp_path):
    import csv
    import json
    win = window
    assert win.export_report(str(tmp_path / "r.csv"))
    rows = list(csv.DictReader(open(tmp_path / "r.csv")))
    sol = win.solver.solution
    assert {r["id"] for r in rows} == {p.id for p in sol.points}
    assert sum(1 for r in rows if r["view"]) == len(win.project.measurements)
    assert win.export_report(str(tmp_path / "r.json"))
    rep = json.loads((tmp_path / "r.json").read_text())
    assert len(rep["points"]) == len(sol.points)
    assert win.export_report(str(tmp_path / "r.html"))
    assert "G1" in (tmp_path / "r.html").read_text(encoding="utf-8")


def test_residual_vectors_keep_their_screen_length(qtbot, window):
    win = window
    sol = win.solver.solution
    win.exaggeration.setValue(30)
    r = sol.point("G2")
    x, y = r.measured["F"]
    vx, vy = r.residual_px["F"]
    iv, ov = win.views.views["F"], win.views.overlays["F"]
    for scale in (4.0, 0.5):
        iv.center_on(x, y, scale)
        ends = ov.vector_ends()
        i = int(np.argmin(np.hypot(ends[:, 0] - x, ends[:, 1] - y)))
        a, b = iv.map_to_viewport(*ends[i, :2]), iv.map_to_viewport(*ends[i, 2:])
        assert math.hypot(b.x() - a.x(), b.y() - a.y()) == pytest.approx(30 * math.hypot(vx, vy), rel=1e-3)


def test_reference_dem_heights_for_the_linked_cursor(qtbot, window, tmp_path):
    import rasterio
    from prismstation.ops.reference_heights import scene_grid
    win = window
    transform, shape = scene_grid(win.project.scene, spacing=100.0)
    transform = rasterio.transform.Affine(*transform)
    dem = tmp_path / "dem.tif"
    rows, cols = shape
    # a plane: h = 900 m + 0.01 · (column): its height under the cursor is known exactly
    h = (900.0 + 0.01 * np.arange(cols)[None, :] * np.ones((rows, 1))).astype("float32")
    with rasterio.open(dem, "w", driver="GTiff", width=cols, height=rows, count=1, dtype="float32",
                       crs=win.project.scene.crs, transform=transform) as ds:
        ds.write(h, 1)
    win.load_reference_dem(dem, wait=True)
    settle(qtbot, win)
    assert win.views.height_of is not None and win.solver.height_of is win.views.height_of
    sol = win.solver.solution
    linked, ground = win.views.linked("N", 123.0, 456.0)
    col, _ = ~transform * (ground[0], ground[1])
    assert ground[2] == pytest.approx(900.0 + 0.01 * (col - 0.5), abs=0.05)
    en = sol.image_to_ground("N", np.array([123.0, 456.0]), ground[2])
    assert np.allclose(linked["F"], sol.ground_to_image("F", en, ground[2]), atol=1e-6)


def test_untitled_project_autosave_is_recovered(qtbot, window, demo):
    from prismstation.gui.main_window import MainWindow
    from prismstation.gui.project_io import autosave_path
    win = window
    assert win.files.new_project(str(demo.scene_path), )
    win.measure_mode.set_mode("create")
    win.place("N", 111.0, 222.0)
    pid = win.current
    assert win.files.autosave() and autosave_path(None).is_file()
    w2 = MainWindow(interactive=False)
    qtbot.addWidget(w2)
    assert w2.files.recover_untitled(recover=True)
    assert w2.project.measurement(pid, "N").x == 111.0 and not w2.undo_stack.isClean()
    w2.files.save_as(str(demo.path.parent / "saved.prismproj"))
    assert not autosave_path(None).exists()
    w2.close()
