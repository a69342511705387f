"""prismstation beside CARS on the real Pléiades triplet: time and the two DSMs' agreement.

Ours through the command line only, each step its own process: ``new --images`` (automatic
tie points, the biases fitted) and ``dsm --posting P``. CARS (``cars`` from a separate
environment: ``--cars PATH``, default ``cars-venv/bin/cars`` beside the checkout or ``cars`` on the PATH;
skipped with a message when there is none) on the same three images, every pair, RPCs from the
TIFF tags, ellipsoidal heights (``geoid: false``), UTM 31N at the same posting, two local
workers. Printed: each one's wall and CPU time (the child processes' own, ``RUSAGE_CHILDREN``),
then CARS's DSM resampled (bilinear) onto our grid and compared: median and NMAD of
ours − CARS over the common cells; the same for each of our pair DSMs (``ops.rpc_dsm.rpc_dsm``
with the project's fitted models, in this process) and between our pairs, the yardsticks of the
comparison where no third DSM exists.

Run: ``.venv/bin/python benchmarks/bench_rpc_dsm_cars.py [--posting 0.5] [--cars PATH]
[--cars-dsm FILE] [--out DIR]`` (``--cars-dsm``: a DSM CARS made before, not run again).
Times are wall-clock on a shared 2-core machine.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import rasterio
from rasterio.warp import Resampling, reproject

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "real" / "pleiades_triplet"
IMAGES = [DATA / f"img_0{i}.tif" for i in (1, 2, 3)]
DEFAULT_CARS = ROOT.parent / "cars-venv" / "bin" / "cars"


def timed(cmd, **kw) -> tuple[float, float, subprocess.CompletedProcess]:
    """Run ``cmd``; its wall time and its (and its children's) CPU time, seconds."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    res = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, **kw)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if res.returncode not in (0, 3):
        sys.exit(f"{cmd[0]} failed ({res.returncode}):\n{res.stdout[-2000:]}\n{res.stderr[-3000:]}")
    return wall, cpu, res


def our_exe() -> list:
    """The prismstation command of this environment."""
    exe = Path(sys.executable).parent / "prismstation"
    if exe.exists():
        return [str(exe)]
    return ["prismstation"] if shutil.which("prismstation") else [sys.executable, "-m", "prismstation.cli"]


def ours_new(out: Path):
    """``new --images`` on the triplet: the project, its wall and CPU time (s)."""
    proj = out / "p.prismproj"
    if proj.exists():
        proj.unlink()
    wall, cpu, res = timed(our_exe() + ["new", proj, "--images", *IMAGES])
    print(f"prismstation new --images: {wall:.1f} s wall / {cpu:.1f} s CPU")
    for line in res.stdout.splitlines():
        if "tie point" in line:
            print("   " + line.strip())
    return proj, wall, cpu


def ours_dsm(proj: Path, dsm: Path, posting: float):
    """``dsm --posting`` of the project (exit 3, heights not fixed by a reference, is
    expected: the DSM is written): its wall and CPU time (s)."""
    if dsm.exists():
        dsm.unlink()
    wall, cpu, res = timed(our_exe() + ["dsm", proj, "-o", dsm, "--posting", str(posting)])
    print(f"prismstation dsm --posting {posting:g}: {wall:.1f} s wall / {cpu:.1f} s CPU")
    for line in res.stdout.splitlines():
        if any(k in line for k in ("wrote", "pairs (")):
            print("   " + line.strip())
    return wall, cpu


def ours(out: Path, posting: float):
    proj, w1, c1 = ours_new(out)
    dsm = out / "ours.tif"
    w2, c2 = ours_dsm(proj, dsm, posting)
    print(f"prismstation total: {w1 + w2:.1f} s wall / {c1 + c2:.1f} s CPU")
    return proj, dsm, w1 + w2, c1 + c2


def cars(out: Path, posting: float, exe: Path):
    conf = {"input": {"sensors": {f"i{k}": {"image": str(p)} for k, p in enumerate(IMAGES)},
                      "pairing": [["i0", "i1"], ["i0", "i2"], ["i1", "i2"]]},
            "output": {"directory": str(out / "cars"), "resolution": posting, "epsg": 32631, "geoid": False},
            "orchestrator": {"mode": "multiprocessing", "nb_workers": 2}}
    shutil.rmtree(out / "cars", ignore_errors=True)
    (out / "cars.json").write_text(json.dumps(conf, indent=1))
    env = dict(os.environ, OMP_NUM_THREADS="1")
    wall, cpu, _ = timed([exe, out / "cars.json"], env=env)
    dsm = out / "cars" / "dsm" / "dsm.tif"
    print(f"CARS: {wall:.1f} s wall / {cpu:.1f} s CPU ({exe})")
    return dsm, wall, cpu


def on_grid(path, like):
    """``path``'s band 1 resampled onto ``like``'s grid (float32, NaN no data): bilinear, or
    the mean of the cells each target cell covers when that grid is 1.5 × coarser or more."""
    with rasterio.open(like) as ref, rasterio.open(path) as src:
        out = np.full((ref.height, ref.width), np.nan, np.float32)
        coarser = abs(ref.transform.a) >= 1.5 * abs(src.transform.a)
        reproject(rasterio.band(src, 1), out, src_transform=src.transform, src_crs=src.crs,
                  src_nodata=src.nodata, dst_transform=ref.transform, dst_crs=ref.crs, dst_nodata=np.nan,
                  resampling=Resampling.average if coarser else Resampling.bilinear)
    return out


def stats(d) -> str:
    d = d[np.isfinite(d)]
    if not d.size:
        return "no common cell"
    med = float(np.median(d))
    return f"median {med:+.2f} m, NMAD {1.4826 * float(np.median(np.abs(d - med))):.2f} m over {d.size} cells"


def pair_dsms(proj: Path, posting: float, like: Path):
    """Our pair DSMs of the project's fitted models on the written DSM's grid."""
    sys.path.insert(0, str(ROOT / "src"))
    from prismstation.io.project import load_project
    from prismstation.ops.fit import solve_project
    from prismstation.ops.rpc_dsm import Grid, rpc_dsm
    from prismstation.ops.rpc_project import height_range, images_and_models, tie_points
    p = load_project(proj)
    sol = solve_project(p)
    paths, models = images_and_models(sol, p)
    pts = tie_points(sol, p)
    with rasterio.open(like) as ds:
        grid = Grid(ds.crs.to_string(), tuple(ds.transform)[:6], (ds.height, ds.width))
    _, pairs = rpc_dsm(paths, models, grid=grid, points=pts, height_range=height_range(pts, None),
                       keep_pairs=True)
    return pairs


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--posting", type=float, default=0.5)
    ap.add_argument("--cars", type=Path, help="the cars executable (default: cars-venv/bin/cars beside the checkout, or PATH)")
    ap.add_argument("--cars-dsm", type=Path, help="a DSM CARS made before (not run again)")
    ap.add_argument("--out")
    args = ap.parse_args(argv)
    if not all(p.exists() for p in IMAGES):
        print(f"the Pléiades triplet is not at {DATA}: nothing to measure")
        return 0
    out = Path(args.out or tempfile.mkdtemp(prefix="bench_cars_"))
    out.mkdir(parents=True, exist_ok=True)
    proj, dsm, wall, cpu = ours(out, args.posting)
    exe = args.cars or (DEFAULT_CARS if DEFAULT_CARS.exists() else shutil.which("cars"))
    cars_dsm = args.cars_dsm
    if cars_dsm is None and exe:
        cars_dsm, cwall, ccpu = cars(out, args.posting, Path(exe))
        print(f"ours / CARS: {wall / cwall:.2f} of its wall time, {cpu / ccpu:.2f} of its CPU time")
    if cars_dsm is None:
        print("CARS is not installed (pip install cars==1.3.0 in a separate environment, then --cars PATH): "
              "its run and the comparison are skipped")
        return 0
    theirs = on_grid(cars_dsm, dsm)
    with rasterio.open(dsm) as ds:
        h = ds.read(1)
    print(f"ours − CARS (fused): {stats(h - theirs)}")
    pairs = pair_dsms(proj, args.posting, dsm)
    for p in pairs:
        print(f"   our pair {p.pair} − CARS: {stats(p.heights - theirs)}")
    for i in range(len(pairs)):
        for j in range(i + 1, len(pairs)):
            print(f"   our pair {pairs[i].pair} − pair {pairs[j].pair}: {stats(pairs[i].heights - pairs[j].heights)}")
    print(f"(files in {out})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
