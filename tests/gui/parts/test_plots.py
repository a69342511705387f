"""PlotsWidget: the plotted data are the Solution's, items are reused, updates are fast."""
from __future__ import annotations

import math
import time

import numpy as np
import pytest

from prismstation.gui.plot_figures import figure_widget, render_images
from prismstation.core.models.solution import solve
from prismstation.gui.plot_data import blunder_text
from prismstation.gui.plots import PlotData, PlotsWidget
from prismstation.sim.model_triplet import make_points, make_scene
from tests.gui.parts.conftest import BLUNDER_ID


@pytest.fixture
def widget(qtbot):
    w = PlotsWidget()
    qtbot.addWidget(w)
    w.resize(1000, 700)
    return w


def _xy(item):
    x, y = item.getData()
    return (np.zeros(0), np.zeros(0)) if x is None else (np.asarray(x), np.asarray(y))


def test_height_plots_hold_parallax_and_known_heights(widget, fitted):
    scene, pts, sol = fitted
    widget.set_solution(sol)
    truth = {p.id: p.ground for p in pts}
    for kind, item, item5 in (("GCP", widget.h_gcp, widget.d_gcp), ("ICP", widget.h_icp, widget.d_icp)):
        res = [r for r in sol.points if r.kind == kind and r.parallax_px is not None]
        x, y = _xy(item)
        assert len(x) == len(res) > 0
        np.testing.assert_allclose(x, [r.parallax_px for r in res])
        np.testing.assert_allclose(y, [truth[r.id][2] for r in res], atol=1e-6)
        # Fig. 5: minus the theoretical line of eq. 4, computed here from the angles
        v = scene.views
        c1t = v["N"].pixel_size_m / (math.tan(math.radians(26.4)) + math.tan(math.radians(26.8)))
        x5, y5 = _xy(item5)
        np.testing.assert_allclose(x5, x)
        np.testing.assert_allclose(y5, y - c1t * x, atol=1e-6)
    par = sol.model.parallax
    x, y = _xy(widget.fit_line)
    np.testing.assert_allclose(y, par.c0 + par.c1 * x)
    x, y = _xy(widget.theory_line)
    np.testing.assert_allclose(y, par.c1_theory * x)
    x, y = _xy(widget.d_fit_line)
    np.testing.assert_allclose(y, par.c0 + (par.c1 - par.c1_theory) * x)


def test_residual_vectors_start_at_measurement_and_scale(widget, fitted):
    scene, pts, sol = fitted
    widget.set_solution(sol)
    widget.set_exaggeration(250)
    assert widget.exaggeration == 250
    gcps = [p for p in pts if p.kind == "GCP"]
    x, y = _xy(widget.v_gcp_seg)
    assert len(x) == 2 * len(gcps)
    for i, p in enumerate(gcps):
        start = np.array(p.image["N"])
        # residual = measured − the model's projection of the known ground point
        pred = sol.ground_to_image("N", np.array(p.ground[:2]), p.ground[2])
        np.testing.assert_allclose([x[2 * i], y[2 * i]], start, atol=1e-9)
        np.testing.assert_allclose([x[2 * i + 1], y[2 * i + 1]], start + 250 * (start - pred), atol=1e-6)
    widget.set_exaggeration(None)  # back to automatic
    assert widget.auto_box.isChecked() and widget.exaggeration != 250


def test_standardised_residuals_threshold_and_blunder(widget, fitted):
    _, _, sol = fitted
    widget.set_solution(sol)
    gcps = [r for r in sol.points if r.kind == "GCP" and r.std_residual is not None]
    x, y = _xy(widget.std_pts)
    np.testing.assert_allclose(y, [r.std_residual for r in gcps])
    assert widget.threshold_line.value() == pytest.approx(sol.settings.blunder_threshold)
    bx, by = _xy(widget.blunder_pt)
    i = [r.id for r in gcps].index(BLUNDER_ID)
    assert list(bx) == [x[i]] and by[0] == pytest.approx(max(y)) and by[0] > sol.settings.blunder_threshold
    assert widget.blunder_label.textItem.toPlainText() == BLUNDER_ID
    # the same figures from the report dict (what the PDF writer draws)
    from prismstation.io.report import report_dict
    d = PlotData.from_report(report_dict(sol))
    np.testing.assert_allclose(d.std_values, y)
    np.testing.assert_allclose(d.gcp_h, _xy(widget.h_gcp)[1])
    assert d.blunders == (BLUNDER_ID,)
    # the label leans into the plot from its stem: right-aligned in the plot's right half
    left_half = x[i] <= (len(x) + 1) / 2
    assert widget.blunder_label.anchor.x() == (0.0 if left_half else 1.0)


def test_blunder_label_names_the_first_three_and_counts_the_rest():
    assert blunder_text(["T1"]) == "T1"
    assert blunder_text(["T1", "T2", "T3"]) == "T1, T2, T3"
    assert blunder_text(["T1", "T2", "T3", "T4", "T5"]) == "T1, T2, T3 +2"


def test_update_reuses_items_and_is_fast(widget, qtbot):
    sc = make_scene()
    sols = [solve(sc, make_points(sc, n_gcp=40, n_icp=160, noise_px=0.3, seed=s)) for s in (1, 2)]
    widget.show()
    qtbot.waitExposed(widget)
    widget.set_solution(sols[0])
    items = {n: list(pw.getPlotItem().items) for n, pw in widget.plots.items()}
    times = []
    for k in range(12):
        t = time.process_time()  # CPU time: a loaded CI machine does not inflate it
        widget.set_solution(sols[k % 2])
        widget.repaint()
        times.append(time.process_time() - t)
    assert {n: list(pw.getPlotItem().items) for n, pw in widget.plots.items()} == items
    assert len(_xy(widget.h_icp)[0]) == 160
    # the target is a few ms (benchmarks/bench_plots.py); the bound only catches gross slowness
    assert np.median(times) < 0.1, times


def test_empty_solution_clears(widget, fitted):
    widget.set_solution(fitted[2])
    widget.set_solution(None)
    for item in (widget.h_gcp, widget.fit_line, widget.v_gcp_seg, widget.std_pts, widget.blunder_pt):
        assert len(_xy(item)[0]) == 0


def test_point_clicked_signal(widget, fitted, qtbot):
    widget.set_solution(fitted[2])
    spots = widget.std_pts.points()
    with qtbot.waitSignal(widget.point_clicked, timeout=1000) as sig:
        widget.std_pts.sigClicked.emit(widget.std_pts, [spots[2]], None)
    assert sig.args == [spots[2].data()]


def test_tabs_layout_and_report_images(qtbot, fitted):
    w = PlotsWidget(tabs=True)
    qtbot.addWidget(w)
    w.set_solution(fitted[2])
    assert w.tabs.count() == 4 and w.tabs.widget(2) is w.plots["vectors"]
    images = render_images(w, (320, 200))
    assert sorted(images) == sorted(w.plots)
    assert all(im.width() == 320 and im.height() == 200 for im in images.values())
    assert len(_xy(w.h_gcp)[0]) == 12  # the widget itself is untouched by the rendering


def test_live_lines_plain_report_lines_antialiased(qtbot, fitted, monkeypatch):
    """The live plots draw lines without antialiasing (they repaint every click); the report
    figures are drawn by a widget whose lines are antialiased, and the setting is restored."""
    import pyqtgraph as pg
    from prismstation.gui import plots
    from prismstation.gui.app import make_app
    make_app()
    made = []
    init = plots.PlotsWidget.__init__

    def spy(self, *a, **k):
        init(self, *a, **k)
        made.append(self)
    monkeypatch.setattr(plots.PlotsWidget, "__init__", spy)
    w = plots.PlotsWidget()
    qtbot.addWidget(w)
    w.set_solution(fitted[2])
    assert not w.fit_line.opts["antialias"]
    assert sorted(render_images(w, (300, 200))) == sorted(plots.PLOT_NAMES)
    assert made[-1] is not w and made[-1].fit_line.opts["antialias"]
    assert pg.getConfigOption("antialias") is False


def test_a_short_widget_shows_one_plot_per_tab_and_a_tall_one_the_grid(qtbot, fitted):
    w = PlotsWidget(own_exaggeration=False)
    qtbot.addWidget(w)
    w.set_solution(fitted[2])
    w.resize(900, 600)
    w.show()
    qtbot.waitUntil(lambda: w._stack.currentWidget() is w._grid_box)
    assert all(p.isVisible() for p in w.plots.values())
    w.resize(900, 200)  # a 720-line screen leaves the plots about this much
    qtbot.waitUntil(lambda: w._stack.currentWidget() is w.tabs)
    assert w.tabs.count() == 4 and w.plots["height"].isVisible() and w.plots["height"].height() > 100
    w.resize(900, 600)
    qtbot.waitUntil(lambda: w._stack.currentWidget() is w._grid_box)
    assert w.tabs.count() == 0 and all(p.isVisible() for p in w.plots.values())
    assert not w.spin.isVisible()


def test_plot_data_from_columns_equals_the_report_path():
    """The plots' data from the fit's columns equal those from its report (another path
    through the same figures: the PDF writer's)."""
    import dataclasses

    from prismstation.io.report import report_dict
    from tests.core.test_solve_reference import _project
    sc, pts = _project()
    sol = solve(sc, pts)
    a, b = PlotData.from_solution(sol), PlotData.from_report(report_dict(sol))
    for f in dataclasses.fields(PlotData):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            np.testing.assert_allclose(x, y, rtol=0, atol=1e-6, err_msg=f.name)
        elif f.name not in ("image_shape", "c0", "c1", "c1_theory"):  # (the report rounds)
            assert x == y, f.name
    assert a.vec_gcp_ids and a.vec_icp_ids and a.std_ids and a.blunders and len(a.gcp_py)


def test_report_figures_list_what_they_draw_under_the_plot(qtbot, fitted):
    """The figures' legends sat over the data (the PDF's Fig. 2: over the points near the top);
    they go under the axis, and name only what the figure draws (no "TIE" on a triplet)."""
    w = PlotsWidget()
    qtbot.addWidget(w)
    w.set_solution(fitted[2])
    fig = figure_widget(w)
    qtbot.addWidget(fig)
    fig.resize(1200, 800)
    fig.show()
    qtbot.wait(20)
    for name, pw in fig.plots.items():
        pi = pw.getPlotItem()
        assert (pi.legend is not None) == (name != "std_residuals"), name  # (that one needs none)
        if pi.legend is not None:
            assert not pi.legend.sceneBoundingRect().intersects(pi.vb.sceneBoundingRect()), name
    names = {n: [label.text for _, label in pw.getPlotItem().legend.items] for n, pw in fig.plots.items()
             if pw.getPlotItem().legend is not None}
    assert names["vectors"] == ["GCP", "ICP"], names
    assert names["height_minus_theory"] == ["fitted − theoretical", "GCP", "ICP"], names
