"""Resident memory of the workstation window through the demo's tools: at rest after each, and
its peak while it runs.

The real main window (offscreen unless a display is set, 1600 × 1000) on the demo project as
``prismstation demo`` makes it (2000 px triplet, or ``--project``), its reference DEM loaded,
then each tool as the Tools menu runs it, one after the other: automatic tie points,
orientation from the reference DEM (``--orient-runs`` times, each result applied as the window
applies it), the DSM of the whole image (``--dsm-runs`` times), its validation against the
demo's true DEM, the report exported as PDF and as HTML, an affine rectification of N, the
space resection. Printed for each step: the resident memory (VmRSS) at rest — the window idle
for :data:`REST_S` seconds after the step, as an operator reads its result — and the step's
peak (VmHWM, reset before it), then what a garbage collection and glibc's ``malloc_trim``
would still give back (memory the window holds for nothing), beside the targets: ≤ 500 MB at
rest after any tool, ≤ 700 MB at the peak. The window runs as ``prismstation gui`` runs it:
under :func:`prismstation.io.raster.gdal_env` (GDAL's block cache bounded; without it GDAL
keeps 5 % of the RAM of decoded blocks), its idle loop deleting what was ``deleteLater``-ed.

Run: ``.venv/bin/python benchmarks/bench_memory.py [--project P] [--dsm-runs 2] [--orient-runs 4]
[--trace]`` (``--trace``: tracemalloc's largest Python allocations still held at the end).
"""
from __future__ import annotations

import argparse
import gc
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

TARGET_MB = 500.0  # at rest after any tool
PEAK_TARGET_MB = 700.0
REST_S = 6.0


def peak_mb() -> float:
    """The resident memory's high-water mark (VmHWM) since the last :func:`reset_peak`."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def reset_peak() -> None:
    """Start a new high-water mark at the memory resident now (Linux ≥ 4.0)."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:
        pass


def rss_mb() -> float:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def smaps_summary() -> list:
    """``[(kind, MB)]`` of the resident memory: anonymous (heaps, arenas, Python and numpy
    data) and each large file mapping (shared libraries' pages), largest first."""
    out: dict = {}
    name = None
    with open("/proc/self/smaps") as f:
        for line in f:
            parts = line.split()
            if "-" in parts[0] and len(parts) >= 5 and ":" not in parts[0]:
                path = parts[5] if len(parts) > 5 else ""
                name = ("anonymous (heaps, arenas, Python and numpy data)" if not path or path.startswith("[")
                        else Path(path).name)
            elif parts[0] == "Rss:" and name is not None:
                out[name] = out.get(name, 0.0) + int(parts[1]) / 1024.0
    top = sorted(out.items(), key=lambda kv: -kv[1])
    rest = sum(mb for _, mb in top[8:])
    return top[:8] + [("other mappings", rest)]


def gdal_cache_mb() -> tuple[float, float]:
    """GDAL's block cache: ``(used, maximum)`` MB (NaN when libgdal cannot be asked)."""
    import ctypes
    try:
        path = next(line.split()[-1] for line in open("/proc/self/maps") if "libgdal" in line)
        lib = ctypes.CDLL(path)
        lib.GDALGetCacheUsed64.restype = lib.GDALGetCacheMax64.restype = ctypes.c_int64
        return lib.GDALGetCacheUsed64() / 2**20, lib.GDALGetCacheMax64() / 2**20
    except (StopIteration, OSError, AttributeError):
        return float("nan"), float("nan")


def trim() -> None:
    """glibc: give the heaps' free memory back to the system."""
    import ctypes
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass


def _referrers_of_large_objects() -> None:
    """The objects holding numpy arrays of 1 MB or more, alive now (what the window keeps)."""
    import numpy as np
    gc.collect()
    seen = 0
    for o in gc.get_objects():
        if type(o).__name__ in ("Dsm", "DsmResult", "ValidationResult", "OrientationResult", "Solution"):
            refs = [type(r).__name__ for r in gc.get_referrers(o)][:6]
            print(f"  alive: {type(o).__name__} held by {refs}")
        if isinstance(o, dict):
            big = [k for k, v in o.items() if isinstance(v, np.ndarray) and v.nbytes >= 2**20]
            if big and seen < 15:
                seen += 1
                holders = [type(r).__name__ for r in gc.get_referrers(o)][:4]
                print(f"  dict with arrays {big[:4]} ({sum(o[k].nbytes for k in big) / 2**20:.0f} MB) held by {holders}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--project", help="a project (default: the demo, made in a temporary folder)")
    ap.add_argument("--dsm-runs", type=int, default=2)
    ap.add_argument("--orient-runs", type=int, default=4)
    ap.add_argument("--posting", type=float, default=5.0, help="DSM posting, metres")
    ap.add_argument("--trace", action="store_true", help="tracemalloc: the largest Python allocations held")
    args = ap.parse_args(argv)
    if args.trace:
        import tracemalloc
        tracemalloc.start(12)

    tmp = Path(tempfile.mkdtemp(prefix="bench-memory-"))
    os.environ["PRISMSTATION_SETTINGS_DIR"] = str(tmp / "settings")
    if args.project:
        project = Path(args.project)
    else:
        from prismstation.cli.demo import ensure_demo
        print("making the demo project…", flush=True)
        project = ensure_demo(tmp / "demo")
    triplet = project.parent / "triplet"

    from prismstation.io.raster import gdal_env
    with gdal_env():  # an entry point: GDAL's block cache bounded as the window's (gui/app.py)
        return _measure(args, tmp, project, triplet)


def _loop(seconds: float) -> None:
    """Run the event loop for ``seconds`` as the application's does between events: posted
    events, timers, and the objects deleted later (``deleteLater``: a script's own
    ``processEvents`` never deletes them, the application's loop does)."""
    from PySide6.QtCore import QCoreApplication, QEvent
    t0 = time.perf_counter()
    while True:
        QCoreApplication.processEvents()
        QCoreApplication.sendPostedEvents(None, QEvent.Type.DeferredDelete)
        if time.perf_counter() - t0 >= seconds:
            return
        time.sleep(0.01)


def _measure(args, tmp, project, triplet) -> int:
    from prismstation.gui.app import make_app, wait_settled
    from prismstation.gui.main_window import MainWindow
    from PySide6.QtCore import QCoreApplication

    make_app()
    rows = [("start (Python, Qt, numpy, GDAL loaded)", rss_mb(), peak_mb())]
    win = MainWindow(interactive=False)
    win.files.interactive = False
    win.resize(1600, 1000)
    win.show()
    reset_peak()
    assert win.open_project(str(project), recover=False)
    win.default_layout()
    if (triplet / "srtm.tif").is_file():
        win.load_reference_dem(triplet / "srtm.tif", wait=True)
    wait_settled(win)

    def rest(name) -> None:
        """The window idle for REST_S seconds: its resident memory then, and the step's peak."""
        _loop(REST_S)
        rows.append((name, rss_mb(), peak_mb()))
        print(f"  {name:52s} {rows[-1][1]:7.0f} MB at rest   {rows[-1][2]:7.0f} MB peak", flush=True)
        reset_peak()
    rest("project open, images shown, fitted")

    def run(job, timeout=1800.0):
        if job is None:
            raise SystemExit("a tool did not start (see the status bar): "
                             f"{win.statusBar().currentMessage()}")
        outcome = []
        job.failed.connect(lambda m: outcome.append(m))
        job.cancelled.connect(lambda: outcome.append("cancelled"))
        t0 = time.perf_counter()
        while job.isRunning():
            _loop(0.0)
            time.sleep(0.01)
            if time.perf_counter() - t0 > timeout:
                raise SystemExit("a tool took too long")
        _loop(0.1)
        wait_settled(win)
        if outcome:
            raise SystemExit(f"a tool failed: {outcome[0]}")

    tools = win.tools
    run(tools["transfer"].start_ties(grid=6))
    rest("automatic tie points (6 × 6)")
    if (triplet / "srtm.tif").is_file():
        for k in range(args.orient_runs):
            run(tools["dem_orientation"].start(triplet / "srtm.tif", patch_m=1250.0))
            rest(f"orientation from the reference DEM, run {k + 1}")
        while win.project.settings.orientation != "gcp" and win.undo_stack.canUndo():
            win.undo_stack.undo()  # back to the GCP orientation
        wait_settled(win)
    from prismstation.gui.tools.dsm_tool import DsmRequest
    dsm = tmp / "dsm.tif"
    for k in range(args.dsm_runs):
        run(tools["dsm"].start(DsmRequest(str(dsm), None, args.posting, False)))
        rest(f"DSM of the whole image at {args.posting:g} m, run {k + 1}")
    if (triplet / "truth_dem.tif").is_file():
        run(tools["dsm_validation"].start(str(dsm), str(triplet / "truth_dem.tif"), progress_dialog=False))
        rest("DSM validated against the true DEM")
    for fmt in ("pdf", "html"):
        assert win.export_report(str(tmp / f"report.{fmt}"))
        rest(f"report exported ({fmt.upper()}, its figures)")
    run(tools["rectify"].start("N", "affine", tmp / "n_rect.tif", progress_dialog=False))
    rest("N rectified (affine)")
    dlg = tools["resection"].open()
    dlg.run()
    dlg.close()
    wait_settled(win)
    rest("space resection")
    held = max(mb for _, mb, _ in rows[1:])
    top = max(pk for _, _, pk in rows[1:])
    if args.trace:
        _referrers_of_large_objects()
    gc.collect()
    QCoreApplication.processEvents()
    trim()
    rows.append(("after a garbage collection and malloc_trim", rss_mb(), peak_mb()))

    print(f"resident memory of the window (VmRSS at rest, {REST_S:g} s idle; VmHWM the step's peak), "
          f"{project.name}, 1600 × 1000")
    for name, mb, pk in rows:
        print(f"  {name:52s} {mb:7.0f} MB at rest   {pk:7.0f} MB peak")
    print(f"  {'at rest after any tool, at most (target ≤ %d MB)' % TARGET_MB:52s} {held:7.0f} MB   "
          + ("target met" if held <= TARGET_MB else "TARGET MISSED"))
    print(f"  {'peak (target ≤ %d MB)' % PEAK_TARGET_MB:52s} {top:7.0f} MB   "
          + ("target met" if top <= PEAK_TARGET_MB else "TARGET MISSED"))
    used, most = gdal_cache_mb()
    print(f"  GDAL block cache: {used:.0f} MB used of {most:.0f} MB")
    print("where the resident memory is (/proc/self/smaps):")
    for kind, mb in smaps_summary():
        print(f"  {kind:52s} {mb:7.0f} MB")
    if args.trace:
        import tracemalloc
        snap = tracemalloc.take_snapshot()
        print("largest Python allocations still held:")
        for stat in snap.statistics("traceback")[:12]:
            print(f"  {stat.size / 2**20:7.1f} MB  {stat.count:7d} blocks  {stat.traceback.format()[-1].strip()}")
    win.undo_stack.setClean()
    win.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
