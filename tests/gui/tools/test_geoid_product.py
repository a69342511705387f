"""Tools ▸ Geoid… and File ▸ New project from product… in the real window."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtWidgets import QDialog

N0 = 30.0  # the constant undulation the project starts with


@pytest.fixture()
def ortho_window(qtbot, sim):
    """The simulated project with its ground heights made orthometric (H = h − N0) and the
    constant geoid N0: the fit is the simulation's own."""
    from prismstation.gui.app import make_app, wait_settled
    from prismstation.gui.main_window import MainWindow
    from prismstation.gui.workers import collect_everything

    path = sim / "p.prismproj"
    doc = json.loads(path.read_text())
    for p in doc["points"]:
        if p.get("H") is not None:
            p["H"] -= N0
            p["height"] = "orthometric"
    doc["geoid"] = {"kind": "constant", "value": N0}
    path.write_text(json.dumps(doc))
    make_app()
    collect_everything()
    win = MainWindow(interactive=False)
    win.files.interactive = False
    qtbot.addWidget(win)
    win.show()
    qtbot.waitExposed(win)
    assert win.open_project(path, recover=False)
    assert wait_settled(win)
    yield win
    win.undo_stack.setClean()
    win.close()
    win.deleteLater()
    qtbot.wait(10)
    collect_everything()


def _settle(win):
    from prismstation.gui.app import wait_settled
    assert wait_settled(win)
    sol = win.solver.solution
    assert sol is not None and sol.revision == win.project.revision
    return sol


def test_constant_geoid_is_one_undo_step_and_heights_refit(ortho_window):
    from prismstation.gui.tools.geoid_tool import apply_geoid
    win = ortho_window
    assert "constant 30 m" in win.panel.plain_text().splitlines()[0]
    c0 = win.solver.solution.model.parallax.c0
    steps = win.undo_stack.count()
    assert apply_geoid(win.tool_context, {"kind": "constant", "value": N0 + 10.0})
    sol = _settle(win)
    # every ellipsoidal height is 10 m higher: the parallax line moves by exactly 10 m
    assert sol.model.parallax.c0 == pytest.approx(c0 + 10.0, abs=1e-6)
    assert win.panel.geoid.text() == "constant 40 m"
    assert win.undo_stack.count() == steps + 1
    win.undo_stack.undo()
    sol = _settle(win)
    assert sol.model.parallax.c0 == pytest.approx(c0, abs=1e-6)
    assert win.project.geoid == {"kind": "constant", "value": N0}
    assert win.panel.geoid.text() == "constant 30 m"


def test_found_grid_listed_chosen_and_fitted_like_the_solver(ortho_window, monkeypatch):
    from prismstation.gui.tools import geoid_tool as gt
    from prismstation.io import geoid as geoid_mod
    from prismstation.ops.fit import solve_project
    grid = geoid_mod.find_grid()
    if grid is None:
        pytest.skip("no geoid grid installed")
    win = ortho_window
    grids = gt.found_grids()
    assert grid.resolve() in [g.resolve() for g in grids]
    dlg = gt.GeoidDialog(win.project.geoid, grids, win)
    assert dlg.r_const.isChecked()
    dlg.grids.setCurrentRow([g.resolve() for g in grids].index(grid.resolve()))
    assert dlg.setting() == {"kind": "grid", "path": str(grid.resolve())}
    monkeypatch.setattr(dlg, "exec", lambda: QDialog.DialogCode.Accepted)
    assert gt.choose_geoid(win.tool_context, dialog_cls=lambda *a: dlg)
    sol = _settle(win)
    assert win.panel.geoid.text() == f"grid {grid.name}"
    assert "Geoid: grid" in win.panel.plain_text()
    # the same fit as the io layer's on the same setting (an independent call, no window)
    ref = solve_project(win.project)
    assert sol.model.parallax.c0 == pytest.approx(ref.model.parallax.c0, abs=1e-9)
    # the dialog reopened on this project shows the grid chosen
    again = gt.GeoidDialog(win.project.geoid, grids, win)
    assert again.r_found.isChecked() and again.setting() == win.project.geoid


def test_unreadable_grid_is_a_clear_message_and_changes_nothing(ortho_window, tmp_path):
    from prismstation.gui.tools.geoid_tool import apply_geoid, check_setting
    win = ortho_window
    bad = tmp_path / "broken.gtx"
    bad.write_bytes(b"this is not a grid\n" * 10)
    said = []
    win.files.warn = lambda title, text: said.append(text)
    before, steps = dict(win.project.geoid), win.undo_stack.count()
    assert not apply_geoid(win.tool_context, {"kind": "grid", "path": str(bad)})
    assert not apply_geoid(win.tool_context, {"kind": "grid", "path": str(tmp_path / "missing.gtx")})
    assert len(said) == 2 and "broken.gtx" in said[0] and "cannot" in said[0]
    assert "missing.gtx" in said[1] and "does not exist" in said[1]
    assert win.project.geoid == before and win.undo_stack.count() == steps
    assert check_setting({"kind": "constant", "value": 3}) is None


def test_other_grid_file_through_the_dialog(ortho_window, tmp_path):
    """A grid anywhere (here a constant 12 m GTiff made for the test) is used as chosen."""
    import rasterio
    from rasterio.transform import from_origin
    from prismstation.gui.tools.geoid_tool import GeoidDialog, apply_geoid
    win = ortho_window
    g = tmp_path / "flat12.tif"
    with rasterio.open(g, "w", driver="GTiff", width=360, height=180, count=1, dtype="float32",
                       crs="EPSG:4326", transform=from_origin(-180, 90, 1, 1)) as ds:
        ds.write(np.full((1, 180, 360), 12.0, np.float32))
    c0 = win.solver.solution.model.parallax.c0
    dlg = GeoidDialog(win.project.geoid, [], win)
    dlg.file.setText(str(g))
    dlg.file.textEdited.emit(str(g))
    assert dlg.r_file.isChecked()
    assert apply_geoid(win.tool_context, dlg.setting())
    sol = _settle(win)
    assert win.panel.geoid.text() == "grid flat12.tif"
    assert sol.model.parallax.c0 == pytest.approx(c0 + (12.0 - N0), abs=1e-4)


def test_new_project_from_a_ceos_product(window, tmp_path):
    import rasterio
    from prismstation.gui.app import wait_settled
    from prismstation.io.project import load_project
    from tests.io.formats.fixtures import ceos_builder as cb
    win = window
    truth = cb.build_triplet(tmp_path / "delivery")
    assert "New project from &product…" in [a.text() for a in win.menuBar().actions()[0].menu().actions()]
    assert win.files.new_project_from_product(str(tmp_path / "delivery"))
    assert wait_settled(win)
    assert set(win.project.scene.views) == {"N", "F", "B"}
    for letter, t in truth.items():
        v = win.project.scene.views[letter]
        assert Path(v.image).name.startswith(f"IMG-{t.scene_id}-{t.product_id}")
        with rasterio.open(v.image) as ds:  # the pixels the product holds, as the window shows
            assert np.array_equal(ds.read(1), t.image)
    assert win.files.path is None and win.windowTitle().startswith("untitled")
    # Save As asks where; the scene goes beside the project
    win.files.choose_save = lambda: str(tmp_path / "work" / "mine.prismproj")
    (tmp_path / "work").mkdir()
    win.measure_mode.set_mode("create")  # a click makes a new point only in Create mode
    win.place("N", 20.0, 15.0)
    assert win.files.save_as()
    assert (tmp_path / "work" / "scene.json").is_file()
    back = load_project(tmp_path / "work" / "mine.prismproj")
    assert back.scene_path == str((tmp_path / "work" / "scene.json").resolve())
    assert back.measurement(win.current, "N").x == 20.0
    assert set(back.scene.views) == {"N", "F", "B"}
    assert all(Path(v.image).is_file() for v in back.scene.views.values())


def test_a_folder_that_is_not_a_product_is_a_message(window, tmp_path):
    win = window
    said = []
    win.files.warn = lambda title, text: said.append(text)
    (tmp_path / "empty").mkdir()
    before = win.project
    assert not win.files.new_project_from_product(str(tmp_path / "empty"))
    assert len(said) == 1 and "not a JAXA PRISM product" in said[0]
    assert win.project is before


def test_a_new_project_on_a_scene_without_an_undulation_takes_the_grid(window, foreign_data):
    """File ▸ New project… on a scene that states no geoid undulation (the other simulator's):
    the project's geoid is ``auto`` — the EGM96 grid found, in which SRTM-like references hold
    their heights — and the model panel names it (a constant 0 m before)."""
    from prismstation.gui.app import wait_settled
    from prismstation.io import geoid as geoid_mod
    grid = geoid_mod.find_grid()
    if grid is None:
        pytest.skip("no geoid grid installed")
    win = window
    win.files.choose_open = lambda *a, **k: str(foreign_data / "smooth_hills_10km" / "scene.json")
    win.a_new.trigger()
    assert wait_settled(win)
    assert win.project.geoid == {"kind": "auto", "value": 0.0}
    assert win.panel.geoid.text() == f"automatic: grid {grid.name}"
