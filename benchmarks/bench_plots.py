"""Time the live plots and the report writer on synthetic Solutions.

Prints the median time of ``PlotsWidget.set_solution`` plus the repaint it causes (events
processed, so the four views really paint) for 53 and 200 points, wall-clock and process CPU
time (the CPU figure is the one to read on a loaded machine), and the time to write the
HTML and PDF reports. ``--screenshot PATH`` saves the widget (docs/plots.png).

    .venv/bin/python benchmarks/bench_plots.py [--screenshot docs/plots.png]
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
from PySide6.QtWidgets import QApplication  # noqa: E402

from prismstation.core.models.solution import solve  # noqa: E402
from prismstation.gui.plots import PlotsWidget  # noqa: E402
from prismstation.gui.report_writer import write_document  # noqa: E402
from prismstation.io.report import report_dict  # noqa: E402
from prismstation.sim.model_triplet import make_points, make_scene  # noqa: E402


def solutions(n_gcp, n_icp, seeds=(1, 2)):
    """Fits of the synthetic triplet, GCP P4 of each moved 6 px in N (a blunder)."""
    sc = make_scene()
    out = []
    for s in seeds:
        pts = make_points(sc, n_gcp=n_gcp, n_icp=n_icp, noise_px=0.3, seed=s)
        img = dict(pts[4].image)
        img["N"] = (img["N"][0] + 6.0, img["N"][1] - 3.0)
        pts[4] = replace(pts[4], image=img)
        out.append(solve(sc, pts))
    return out


def time_updates(app, w, repeat, sizes):
    """Print the median set_solution and set_solution + repaint times of ``w``."""
    for n_gcp, n_icp in sizes:
        sols = solutions(n_gcp, n_icp)
        w.set_solution(sols[0])
        app.processEvents()
        t_set, t_all, c_set, c_all = [], [], [], []
        for k in range(repeat):
            t0, c0 = time.perf_counter(), time.process_time()
            w.set_solution(sols[k % 2])
            t1, c1 = time.perf_counter(), time.process_time()
            app.processEvents()  # the views paint here
            t_all.append(time.perf_counter() - t0)
            c_all.append(time.process_time() - c0)
            t_set.append(t1 - t0)
            c_set.append(c1 - c0)
        ms = lambda v: f"{1e3 * np.median(v):.1f}"  # noqa: E731
        print(f"  {n_gcp + n_icp:4d} points: set_solution {ms(t_set)} ms wall / {ms(c_set)} ms CPU; "
              f"with repaint {ms(t_all)} ms wall / {ms(c_all)} ms CPU (medians of {repeat})")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--screenshot")
    ap.add_argument("--repeat", type=int, default=40)
    args = ap.parse_args()
    app = QApplication.instance() or QApplication([])
    for tabs in (True, False):
        w = PlotsWidget(tabs=tabs)
        w.resize(1200, 820)
        w.show()
        app.processEvents()
        print("tabs, one plot visible:" if tabs else "2 x 2 grid, 1200 x 820 px:")
        time_updates(app, w, args.repeat, ((40, 160),) if tabs else ((12, 41), (40, 160)))
        if tabs:
            w.close()
    rep = report_dict(solutions(12, 41)[0], project_path="synthetic.prismproj")
    with tempfile.TemporaryDirectory() as tmp:
        for ext in ("html", "pdf"):
            t0 = time.perf_counter()
            write_document(rep, Path(tmp) / f"r.{ext}")
            dt = time.perf_counter() - t0
            size = (Path(tmp) / f"r.{ext}").stat().st_size
            print(f"report .{ext}: {dt:.2f} s, {size / 1024:.0f} KiB (53 points, figures drawn from the dict)")
    if args.screenshot:
        w.set_solution(solutions(12, 41)[0])
        app.processEvents()
        w.grab().save(args.screenshot)
        print(f"wrote {args.screenshot}")


if __name__ == "__main__":
    main()
