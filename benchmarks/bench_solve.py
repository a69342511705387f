"""Time of one fit of a project: ``prismstation.ops.fit.solve_project`` (the refit after
each click of the operator in the workstation window).

Triplet projects made by ``prismstation.sim.small_project.make_project`` (no images) with 10 % GCPs
and 90 % ICPs, all measured in N, F and B. Between two fits one GCP's N measurement moves by
a pixel, as a click moves it (the fit reuses what the click cannot have changed: the other
views' bias fits, the parallax line, the heights — kept in a ``FitMemo`` as the window's
solver keeps them). Printed per project size: median, p10 and
p90 of the wall time of one ``solve_project`` in milliseconds.

Run: ``.venv/bin/python benchmarks/bench_solve.py [--rounds 200] [--points 50 200 1000]``.
Target: median ≤ 5 ms at 200 points on the 2-core development machine.

Figures on that machine, median / p10 / p90 ms, original and optimised code run alternately
while other engineers' tests kept the load average at 2.3–2.8 (spread of the medians between
runs: about ±0.3 ms at 200 points; the 1000-point p90 is dominated by the load):

======  ===================  ===================
points  before (993c60a)     after (this commit)
======  ===================  ===================
50      3.80 / 3.67 / 4.33   2.18 / 2.10 / 2.39
200     7.18 / 7.04 / 11.3   4.13 / 3.99 / 4.66
1000    27.9 / 25.8 / 57.5   14.1 / 13.4 / 29.7
======  ===================  ===================

On the idle machine, 200 points, 300 rounds, alternately: before 7.13 / 7.03 / 7.25, after
3.95 / 3.89 / 4.06.

Results are the same to the last bit (floats; the ground residuals are now Python floats
instead of numpy float64).
"""
from __future__ import annotations

import argparse
import statistics
from dataclasses import replace
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=200)
    ap.add_argument("--points", type=int, nargs="+", default=[50, 200, 1000])
    args = ap.parse_args(argv)

    from prismstation.io.project import load_project
    from prismstation.ops.fit import FitMemo, solve_project
    from prismstation.sim.small_project import make_project

    tmp = Path(tempfile.mkdtemp(prefix="bench-solve-"))
    print(f"{'points':>6}  {'GCP':>4}  {'median':>8}  {'p10':>8}  {'p90':>8}  (ms per solve_project)")
    for n in args.points:
        n_gcp = max(n // 10, 3)
        demo = make_project(tmp / f"p{n}", n_gcp=n_gcp, n_icp=n - n_gcp, size=1500, p=20.0,
                            seed=9, images=False)
        project = load_project(demo.path)
        memo = FitMemo()  # what the window's solver keeps between its fits
        for _ in range(10):  # warm up (imports, caches)
            solve_project(project, memo=memo)
        gcp = next(p for p in project.points.values() if p.kind == "GCP").id
        m = project.measurement(gcp, "N")
        times = []
        for i in range(args.rounds):
            project.set_measurement(replace(m, x=m.x + (i % 2)))  # a click
            t0 = time.perf_counter()
            solve_project(project, memo=memo)
            times.append((time.perf_counter() - t0) * 1e3)
        q = statistics.quantiles(times, n=10)
        print(f"{n:>6}  {n_gcp:>4}  {statistics.median(times):8.2f}  {q[0]:8.2f}  {q[-1]:8.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
