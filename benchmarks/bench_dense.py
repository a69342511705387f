"""The DSM engine against the simulated truth, beside one raw OpenCV StereoSGBM pass.

A triplet of ``--size`` pixels is simulated (``prismstation simulate``, kept in ``--dir`` and
reused), its project made and fitted. Then, timed in the same run:

* one plain StereoSGBM pass (128 disparities, block 5, OpenCV's default mode) over the N and F
  images as they are (no rectification: the yardstick of the targets, not a DSM); run twice, the
  faster counts (the ratios below are then the less flattering);
* the whole DSM (``prismstation.ops.dsm.make_dsm``: three pairs, coarse to fine, refinement,
  fusion) at postings of 20, 10 and 5 m.

Printed per posting: wall and CPU seconds (all threads), N-image Mpix/s, the wall and CPU
ratios to the plain pass (the CPU ratio does not depend on what else the machine runs), fill (matched
share of the cells all three images see), and NMAD, RMSE, bias of DSM − truth (metres, over
matched cells), then at the finest posting the same per slope class of the truth (degrees),
and the peak resident memory of the process (the plain pass runs in a child process and is
not in it).

Run: ``python benchmarks/bench_dense.py --size 3000`` (6000 and 14000 for the targets of docs/benchmarks.md);
``--scene DIR`` uses a triplet simulated beforehand (``benchmarks/simulate_full.py --out DIR``);
``--exact-control`` orients it with its GCPs' true ground and image coordinates instead of the
surveyed ones (σ 0.5 m / 1 m and 0.3 px), to tell the matcher's error from the control's;
``--gcps N`` with N surveyed GCPs (the simulator's 9 sit on an inner 3 × 3 grid: the heights
they give tilt with their survey error, more so towards the edges they do not reach).
"""
from __future__ import annotations

import argparse
import csv
import json
import resource
import time
from pathlib import Path

import cv2
import numpy as np
import rasterio

from prismstation.ops.project import create
from prismstation.core.adjustment.stats import nmad
from prismstation.io.dem import read_dem
from prismstation.io.raster import gdal_env
from prismstation.io.project import load_project
from prismstation.ops.fit import solve_project
from prismstation.ops.dsm import make_dsm
from prismstation.sim import simulate

SLOPE_CLASSES_DEG = ((0, 5), (5, 15), (15, 30), (30, 90))


def scene(folder: Path, size: int, seed: int):
    project = folder / "p.prismproj"
    if not project.exists():
        if not (folder / "scene.json").exists():
            simulate(folder, size=size, seed=seed)
        create(project, folder / "scene.json", folder / "points.csv", folder / "measurements.csv", force=True)
    return project


def _tables(folder: Path):
    with open(folder / "points.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    with open(folder / "measurements.csv", newline="") as f:
        meas = list(csv.DictReader(f))
    return rows, meas


def _project_with(folder: Path, name: str, rows, meas) -> Path:
    out = folder / name
    out.mkdir(exist_ok=True)
    for file, table in (("points.csv", rows), ("measurements.csv", meas)):
        with open(out / file, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(table[0]))
            w.writeheader()
            w.writerows(table)
    create(out / "p.prismproj", folder / "scene.json", out / "points.csv", out / "measurements.csv", force=True)
    return out / "p.prismproj"


def exact_control(folder: Path) -> Path:
    """A project beside ``folder``'s whose GCPs carry the simulator's true ground and image
    coordinates (check and tie points as surveyed and measured)."""
    truth = {p["id"]: p for p in json.loads((folder / "truth.json").read_text())["points"]}
    rows, meas = _tables(folder)
    for r in rows:
        if r["kind"] == "GCP":
            t = truth[r["id"]]
            r.update(E=f"{t['E']:.4f}", N=f"{t['N']:.4f}", H=f"{t['H']:.4f}", sigma_xy_m="0.01", sigma_h_m="0.01")
    for m in meas:
        t = truth.get(m["id"])
        if t is not None and t["kind"] == "GCP":
            m.update(x=f"{t['image'][m['view']][0]:.4f}", y=f"{t['image'][m['view']][1]:.4f}")
    return _project_with(folder, "exact-control", rows, meas)


def more_gcps(folder: Path, n: int) -> Path:
    """A project beside ``folder``'s with ``n`` GCPs, all as surveyed: its GCPs and then the
    check point farthest (in N) from those already chosen, one at a time, so the control
    spreads to the scene's edges as a survey for a DSM would."""
    rows, meas = _tables(folder)
    xy = {m["id"]: (float(m["x"]), float(m["y"])) for m in meas if m["view"] == "N"}
    cand = [r for r in rows if r["kind"] in ("GCP", "ICP") and r["id"] in xy]
    at = np.array([xy[r["id"]] for r in cand])
    chosen = [i for i, r in enumerate(cand) if r["kind"] == "GCP"]
    if not chosen or len(cand) < n:
        raise SystemExit(f"--gcps {n}: the scene has {len(cand)} ground points")
    while len(chosen) < n:
        chosen.append(int(np.argmax(np.min(np.linalg.norm(at[:, None] - at[chosen][None], axis=2), axis=1))))
    for i in chosen:
        cand[i]["kind"] = "GCP"
    return _project_with(folder, f"gcps-{n}", rows, meas)


def plain_sgbm(folder: Path) -> tuple[float, float, float]:
    """The plain pass in a child process, so that the peak memory printed at the end is the
    DSM's own: (best wall s, Mpix per image, best CPU s)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        return pool.submit(_plain_sgbm, folder).result()


def _plain_sgbm(folder: Path) -> tuple[float, float, float]:
    """One StereoSGBM pass over N and F, twice (the faster counts). Images over 50 Mpix are
    matched once, in strips of 2,048 rows overlapping by 32 (OpenCV's full-image SGBM cannot
    hold the cost volume of a 14,000 × 16,000 pair: its buffer size overflows)."""
    with rasterio.open(folder / "N.tif") as a, rasterio.open(folder / "F.tif") as b:
        n, f = a.read(1), b.read(1)
    m = cv2.StereoSGBM_create(minDisparity=-64, numDisparities=128, blockSize=5, P1=200, P2=800,
                              disp12MaxDiff=1, uniquenessRatio=5, speckleWindowSize=64, speckleRange=2)
    rows = n.shape[0]
    step = rows if n.size <= 50_000_000 else 2048
    runs = []
    for _ in range(2 if step == rows else 1):
        t0, c0 = time.perf_counter(), time.process_time()
        for r0 in range(0, rows, step):
            a0, a1 = max(r0 - 32, 0), min(r0 + step + 32, rows)
            m.compute(f[a0:a1], n[a0:a1])
        runs.append((time.perf_counter() - t0, time.process_time() - c0))
    del n, f
    return min(r[0] for r in runs), a.width * a.height / 1e6, min(r[1] for r in runs)


def stats(e: np.ndarray) -> tuple[float, float, float, int]:
    e = e[np.isfinite(e)]
    if e.size == 0:
        return np.nan, np.nan, np.nan, 0
    return nmad(e), float(np.sqrt(np.mean(e ** 2))), float(e.mean()), e.size


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--dir", default="/tmp/prismstation-bench-dense")
    ap.add_argument("--scene", help="a simulated triplet's folder (its project is made there if missing)")
    ap.add_argument("--postings", type=float, nargs="+", default=[20.0, 10.0, 5.0])
    ap.add_argument("--scheduler", help="dask.distributed scheduler address (default threads)")
    ap.add_argument("--workers", type=int)
    ap.add_argument("--exact-control", action="store_true",
                    help="orient with the GCPs' true coordinates (the matcher's error alone)")
    ap.add_argument("--gcps", type=int, help="orient with this many surveyed GCPs (check points "
                    "promoted, spread to the scene's edges) instead of the simulator's 9")
    args = ap.parse_args()
    folder = Path(args.scene) if args.scene else Path(args.dir) / f"s{args.size}-{args.seed}"
    project = scene(folder, args.size, args.seed)
    if args.exact_control:
        project = exact_control(folder)
    elif args.gcps:
        project = more_gcps(folder, args.gcps)
    project = load_project(project)
    sol = solve_project(project)
    t_plain, mpix, cpu_plain = plain_sgbm(folder)
    rows, cols = sol.scene.views["N"].shape
    print(f"triplet {cols} × {rows} px ({mpix:.1f} Mpix per image), {folder}; control: "
          f"{'the GCPs true (--exact-control)' if args.exact_control else 'the GCPs as surveyed'}"
          f"{f', {args.gcps} of them' if args.gcps and not args.exact_control else ''}")
    print(f"plain StereoSGBM N–F, 128 disparities: {t_plain:6.1f} s wall, {cpu_plain:6.1f} s CPU, "
          f"{mpix / t_plain:6.2f} Mpix/s")
    print(f"{'posting':>8} {'wall s':>7} {'cpu s':>7} {'Mpix/s':>7} {'×plain':>7} {'×cpu':>7} {'fill %':>7} "
          f"{'NMAD m':>7} {'RMSE m':>7} {'bias m':>7} {'cells':>9}")
    last = None
    for posting in args.postings:
        last = None                  # the previous posting's arrays are not part of this run
        t0, c0 = time.perf_counter(), time.process_time()
        d = make_dsm(sol, posting_m=posting, scheduler=args.scheduler, workers=args.workers)
        dt, cpu = time.perf_counter() - t0, time.process_time() - c0
        peak_dsm = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        truth = read_dem(folder / "truth_dem.tif", d.crs, d.transform, d.heights.shape, resampling="bilinear").heights
        e = np.where(d.seen, d.heights - truth, np.nan)
        nmad, rmse, bias, n = stats(e)
        print(f"{posting:8g} {dt:7.1f} {cpu:7.1f} {mpix / dt:7.2f} {dt / t_plain:7.2f} {cpu / cpu_plain:7.2f} "
              f"{100 * d.fill_fraction:7.2f} "
              f"{nmad:7.2f} {rmse:7.2f} {bias:7.2f} {n:9d}")
        last = (d, truth, e)
    d, truth, e = last
    gy, gx = np.gradient(truth, d.posting_m)
    slope = np.degrees(np.arctan(np.hypot(gx, gy)))
    print(f"per slope class at {d.posting_m:g} m (truth slope, degrees):")
    for lo, hi in SLOPE_CLASSES_DEG:
        cls = (slope >= lo) & (slope < hi) & d.seen
        nmad, rmse, bias, n = stats(np.where(cls, e, np.nan))
        fill = float((d.mask[cls] == 1).mean()) if cls.any() else np.nan
        print(f"  {lo:2d}–{hi:2d}°  cells {int(cls.sum()):8d}  fill {100 * fill:6.2f} %  NMAD {nmad:5.2f}  RMSE {rmse:5.2f}  bias {bias:5.2f}")
    for q in (1, 2, 3):
        sel = (d.quality == q) & d.seen
        nmad, rmse, bias, n = stats(np.where(sel, e, np.nan))
        print(f"  pairs agreeing {q}: {100 * sel.sum() / max(d.seen.sum(), 1):6.2f} % of seen cells, NMAD {nmad:5.2f}, RMSE {rmse:5.2f}")
    print(f"peak RSS {peak_dsm:.0f} MB at the end of the last DSM run (the whole process: "
          f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB with this evaluation)")


if __name__ == "__main__":
    with gdal_env():     # an entry point: GDAL's cache bounded as the command line bounds it
        main()
