"""Images to a DSM through the command line only, on the real Pléiades triplet (Aubagne).

Runs, each as its own ``prismstation`` process (no Python API between them):

1. ``new p.prismproj --images img_01.tif img_02.tif img_03.tif [--grid N]``: the scene, the
   map zone, the automatic tie points (the window's matcher) and their fit;
2. ``fit p.prismproj --json fit.json``;
3. ``dsm p.prismproj -o dsm.tif --posting P``.

Printed: each command's wall time and CPU time (its own process, children included), the tie
points' summary and residual lines, the fit's σ0 and tie residuals per view, and the DSM's
fill and pair agreement lines. Times are on a shared, busy 2-core machine: indicative only.

Run: ``.venv/bin/python benchmarks/bench_rpc_cli.py [--grid 8] [--posting 1] [--keep DIR]``.
"""
from __future__ import annotations

import argparse
import json
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TRIPLET = ROOT.parent / "shared" / "data" / "real" / "pleiades_triplet"
PRISMSTATION = Path(sys.executable).with_name("prismstation")


def run(args, cwd) -> tuple[str, float, float]:
    """Run ``prismstation args``; its stdout, wall and CPU seconds (fails on a non-zero exit)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = subprocess.run([str(PRISMSTATION), *args], cwd=cwd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if p.returncode != 0:
        sys.exit(f"prismstation {' '.join(args)}: exit {p.returncode}\n{p.stdout}\n{p.stderr}")
    return p.stdout, wall, cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", type=int, default=8)
    ap.add_argument("--posting", type=float, default=1.0)
    ap.add_argument("--keep", help="keep the project, the fit and the DSM in this folder")
    a = ap.parse_args()
    if not TRIPLET.is_dir():
        sys.exit(f"{TRIPLET} not found")
    d = Path(a.keep or tempfile.mkdtemp())
    d.mkdir(parents=True, exist_ok=True)
    images = [str(TRIPLET / f"img_0{i}.tif") for i in (1, 2, 3)]
    total_wall = total_cpu = 0.0
    steps = [("new --images", ["new", "p.prismproj", "--images", *images, "--grid", str(a.grid), "--force"]),
             ("fit", ["fit", "p.prismproj", "--json", "fit.json"]),
             (f"dsm --posting {a.posting:g}", ["dsm", "p.prismproj", "-o", "dsm.tif", "--posting", str(a.posting)])]
    for name, args in steps:
        out, wall, cpu = run(args, d)
        total_wall, total_cpu = total_wall + wall, total_cpu + cpu
        print(f"{name}: {wall:.1f} s wall, {cpu:.1f} s CPU")
        for line in out.splitlines():
            if line.startswith(("tie points:", "fit (", "wrote", "pairs")):
                print(f"   {line}")
        if name == "fit":
            rep = json.loads((d / "fit.json").read_text())
            for v, s in rep["statistics"]["image"].items():
                t = s["TIE"]["px"]
                print(f"   {v}: {t['x']['n']} tie points, residual RMS x {t['x']['rms']:.3f} px, "
                      f"y {t['y']['rms']:.3f} px")
    print(f"total: {total_wall:.1f} s wall, {total_cpu:.1f} s CPU")
    if not a.keep:
        shutil.rmtree(d, ignore_errors=True)


if __name__ == "__main__":
    main()
