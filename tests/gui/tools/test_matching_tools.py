"""Point transfer and automatic tie points in the real window, against the simulator's truth."""
from __future__ import annotations

import numpy as np
import rasterio
from PySide6.QtCore import Qt


def _settle(qtbot, win):
    qtbot.waitUntil(lambda: not win.solver.busy(), timeout=20000)
    qtbot.wait(20)


def test_placed_point_is_transferred_and_accepted(qtbot, window, truth):
    tool = window.tools["transfer"]
    assert tool.a_auto.isChecked()
    p = window.project
    # a ground point of the simulator, placed at its exact N position as a new tie point
    pid0 = next(k for k, t in truth.items() if t["kind"] == "ICP")
    xy_true = truth[pid0]["image"]
    window.set_current(None)
    window.measure_mode.set_mode("create")  # a click makes a new tie point
    window.views.place_requested.emit("N", *xy_true["N"])
    pid = window.current
    assert pid is not None and pid != pid0 and p.measurement(pid, "F") is None
    qtbot.waitUntil(lambda: bool(tool.candidates), timeout=10000)
    assert set(tool.candidates) == {"F", "B"}
    for v, t in tool.candidates.items():
        assert t.ok and 0.6 <= t.match.score <= 1.0 and 0 < t.match.sigma_x < 0.5
    assert tool.panel.table.rowCount() == 2 and "NCC" in window.statusBar().currentMessage()
    assert len(tool._items) == 4  # a circle and a score in F and in B
    tool_scores = {v: (t.match.score, t.match.sigma_x) for v, t in tool.candidates.items()}
    depth = window.undo_stack.count()
    window.activateWindow()
    qtbot.keyClick(window.views.views["N"].graphics, Qt.Key.Key_Return)   # Enter accepts
    assert not tool.candidates, "Enter did not accept the transfer"
    assert window.undo_stack.count() == depth + 1
    for v in ("F", "B"):
        m = p.measurement(pid, v)
        err = np.hypot(m.x - xy_true[v][0], m.y - xy_true[v][1])
        print(f"transfer to {v}: error {err:.3f} px, NCC {tool_scores[v][0]:.3f}, σ {tool_scores[v][1]:.3f} px")
        assert err < 0.5, (v, err)
    assert not tool.candidates and not tool._items
    window.undo_stack.undo()     # one step removes both transferred measurements
    assert p.measurement(pid, "F") is None and p.measurement(pid, "B") is None
    assert p.measurement(pid, "N") is not None


def test_correcting_by_click_and_switching_off(qtbot, window, truth):
    tool = window.tools["transfer"]
    t = next(t for t in truth.values() if t["kind"] == "ICP")
    window.set_current(None)
    window.measure_mode.set_mode("create")  # a click makes a new tie point
    window.views.place_requested.emit("N", *t["image"]["N"])
    pid = window.current
    qtbot.waitUntil(lambda: bool(tool.candidates), timeout=10000)
    window.views.place_requested.emit("F", t["image"]["F"][0] + 0.3, t["image"]["F"][1])  # a correction
    assert set(tool.candidates) == {"B"}
    assert window.project.measurement(pid, "F").x == t["image"]["F"][0] + 0.3
    tool.a_reject.trigger()
    assert not tool.candidates
    tool.a_auto.setChecked(False)
    window.set_current(None)
    window.measure_mode.set_mode("create")  # a click makes a new tie point
    window.views.place_requested.emit("N", *t["image"]["N"])
    qtbot.wait(300)
    assert not tool.candidates and (tool.job is None or not tool.job.isRunning())


def test_automatic_tie_points_one_undo_step(qtbot, window, sim):
    tool = window.tools["transfer"]
    p = window.project
    before = set(p.points)
    depth = window.undo_stack.count()
    added = []
    job = tool.start_ties(grid=5)
    job.result.connect(added.append)
    qtbot.waitUntil(lambda: window.undo_stack.count() == depth + 1, timeout=30000)
    new = sorted(set(p.points) - before)
    assert len(new) == len(added[0][0]) >= 10
    for pid in new:
        assert p.points[pid].kind == "TIE"
        assert all(p.measurement(pid, v) is not None for v in ("N", "F", "B"))
    # independent check: the height each tie point gets from its F−B parallax is that of the
    # simulator's truth terrain at its estimated ground position (a wrong match would not be)
    _settle(qtbot, window)
    sol = window.solver.solution
    est = np.array([sol.point(pid).ground_est for pid in new if sol.point(pid) is not None
                    and sol.point(pid).ground_est is not None])
    assert len(est) == len(new)
    with rasterio.open(sim / "truth_dem.tif") as ds:
        h_true = np.array([v[0] for v in ds.sample(est[:, :2])], float)
    dh = est[:, 2] - h_true
    print(f"{len(new)} automatic ties: |dh| median {np.median(np.abs(dh)):.2f} m, max {np.abs(dh).max():.2f} m")
    assert np.median(np.abs(dh)) < 5.0 and np.mean(np.abs(dh) < 15.0) > 0.9
    window.undo_stack.undo()
    assert set(p.points) == before


def test_tools_menu_and_closing_during_a_search(qtbot, window, truth):
    texts = [a.text() for a in window.tools_menu.actions()]
    for t in ("Automatic &transfer", "Automatic tie &points…", "Orient from reference &DEM…",
              "Back to &GCP orientation", "Export &DSM…"):
        assert t in texts
    t = next(t for t in truth.values() if t["kind"] == "ICP")
    window.set_current(None)
    window.measure_mode.set_mode("create")  # a click makes a new tie point
    window.views.place_requested.emit("N", *t["image"]["N"])
    job = window.tools["transfer"].job
    window.files.maybe_save = lambda *a, **k: True
    window.close()               # the search ends after the window: nothing happens, no error
    job.wait(10000)
    qtbot.wait(50)
