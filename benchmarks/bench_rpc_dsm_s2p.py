"""prismstation beside s2p on the real Pléiades triplet, judged against s2p's own DSM.

The triplet is s2p's own test input, so s2p's DSM of it is a held-out reference made by a
peer. Ours through the command line only, each step its own process: ``new --images``
(automatic tie points, the biases fitted) and ``dsm --posting P`` for each posting (exit 3,
heights not fixed by a reference, is expected: the DSM is written). s2p (``s2p`` from a
separate environment: ``--s2p PATH``, default ``s2p-venv/bin/s2p`` beside the checkout or
``s2p`` on the PATH; skipped with a message when there is none; ``--s2p-dsm FILE`` reuses a
DSM it made) as its own triplet test runs it — the nadir image (img_02) as reference, tiles of
300 px, the disparity range from SIFT matches, no erosion of the masks — on the whole images,
at the finest posting, no SRTM (without ``use_srtm`` it takes its height range from the
matches), two processes. Its heights are ellipsoidal, as the RPCs' and ours (s2p 1.0b25
converts nothing to the geoid unless given an exogenous DEM).

Printed: each one's wall and CPU time (the child processes' own, ``RUSAGE_CHILDREN``); per
posting, s2p's DSM resampled onto our grid (bilinear; the mean of its cells on a grid 1.5 ×
coarser or more) and ours − s2p, median and NMAD, over s2p's cells (the share of them we
hold), each of our pair DSMs − s2p, the NMAD by the terrain's slope in s2p's DSM and by the
number of our pairs agreeing; with ``--cars-dsm FILE`` (``bench_rpc_dsm_cars.py --out DIR``
leaves one) CARS − s2p on the same grid.

Run: ``.venv/bin/python benchmarks/bench_rpc_dsm_s2p.py [--postings 0.5 1] [--s2p PATH]
[--s2p-dsm FILE] [--cars-dsm FILE] [--out DIR]``. Times are wall-clock on a shared 2-core
machine.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
import rasterio

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks.bench_rpc_dsm_cars import (DATA, IMAGES, ROOT, on_grid, ours_dsm, ours_new,  # noqa: E402
                                           pair_dsms, stats, timed)

DEFAULT_S2P = ROOT.parent / "s2p-venv" / "bin" / "s2p"


def s2p(out: Path, posting: float, exe: Path):
    """s2p on the triplet as its own test runs it (module docstring): its DSM, wall, CPU (s)."""
    order = [IMAGES[1], IMAGES[0], IMAGES[2]]
    conf = {"out_dir": str(out / "s2p"), "temporary_dir": str(out / "s2p_tmp"),
            "images": [{"img": str(p)} for p in order], "full_img": True,
            "horizontal_margin": 20, "vertical_margin": 5, "tile_size": 300,
            "disp_range_method": "sift", "msk_erosion": 0, "dsm_resolution": posting,
            "max_processes": 2}
    shutil.rmtree(out / "s2p", ignore_errors=True)
    (out / "s2p.json").write_text(json.dumps(conf, indent=1))
    wall, cpu, res = timed([exe, out / "s2p.json"], env=dict(os.environ, OMP_NUM_THREADS="1"))
    if res.returncode:
        sys.exit(f"s2p failed ({res.returncode}):\n{res.stdout[-2000:]}\n{res.stderr[-3000:]}")
    print(f"s2p: {wall:.1f} s wall / {cpu:.1f} s CPU at {posting:g} m ({exe})")
    return out / "s2p" / "dsm.tif", wall, cpu


def slope_deg(h, posting: float):
    """Slope (degrees) of the heights ``h`` (NaN void) by central differences."""
    gy, gx = np.gradient(h, posting)
    return np.degrees(np.arctan(np.hypot(gx, gy)))


def compare(dsm: Path, ref_dsm: Path, proj: Path, cars_dsm: Path | None):
    """Ours (and our pairs, and CARS's) − s2p on our grid, printed (module docstring)."""
    ref = on_grid(ref_dsm, dsm)
    with rasterio.open(dsm) as ds:
        h, agreeing, posting = ds.read(1), ds.read(3), abs(ds.transform.a)
    held = np.isfinite(ref)
    print(f"ours − s2p at {posting:g} m: {stats(h - ref)} "
          f"({np.isfinite(h[held]).mean():.1%} of s2p's {held.sum()} cells on our grid)")
    slope = slope_deg(ref, posting)
    for lo, hi in ((0, 10), (10, 30), (30, 90)):
        sel = (slope >= lo) & (slope < hi)
        print(f"   s2p slope {lo}–{hi}° ({sel.sum() / held.sum():.0%} of its cells): {stats((h - ref)[sel])}")
    for q in (3, 2, 1):
        sel = agreeing == q
        print(f"   {q} of our pairs agreeing: {stats((h - ref)[sel])}")
    for p in pair_dsms(proj, posting, dsm):
        print(f"   our pair {p.pair} − s2p: {stats(p.heights - ref)}")
    if cars_dsm is not None:
        print(f"CARS − s2p at {posting:g} m (both on our grid): {stats(on_grid(cars_dsm, dsm) - ref)}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--postings", type=float, nargs="+", default=[0.5, 1.0])
    ap.add_argument("--s2p", type=Path, help="the s2p executable (default: s2p-venv/bin/s2p beside the checkout, or PATH)")
    ap.add_argument("--s2p-dsm", type=Path, help="a DSM s2p made before (not run again)")
    ap.add_argument("--cars-dsm", type=Path, help="a DSM CARS made of the triplet, compared with s2p's")
    ap.add_argument("--out")
    args = ap.parse_args(argv)
    if not all(p.exists() for p in IMAGES):
        print(f"the Pléiades triplet is not at {DATA}: nothing to measure")
        return 0
    out = Path(args.out or tempfile.mkdtemp(prefix="bench_s2p_"))
    out.mkdir(parents=True, exist_ok=True)
    fine = min(args.postings)
    proj, w0, c0 = ours_new(out)
    dsms, wall, cpu = {}, {}, {}
    for p in args.postings:
        dsms[p] = out / f"ours_{p:g}.tif"
        w, c = ours_dsm(proj, dsms[p], p)
        wall[p], cpu[p] = w0 + w, c0 + c
        print(f"   ours at {p:g} m in all: {wall[p]:.1f} s wall / {cpu[p]:.1f} s CPU")
    ref = args.s2p_dsm
    if ref is None:
        exe = args.s2p or (DEFAULT_S2P if DEFAULT_S2P.exists() else shutil.which("s2p"))
        if not exe:
            print("s2p is not installed (pip install s2p==1.0b25 in a separate environment, then --s2p PATH): "
                  "its run and the comparison are skipped")
            return 0
        ref, swall, scpu = s2p(out, fine, Path(exe))
        print(f"ours / s2p at {fine:g} m: {wall[fine] / swall:.2f} of its wall time, "
              f"{cpu[fine] / scpu:.2f} of its CPU time")
    for p in args.postings:
        compare(dsms[p], ref, proj, args.cars_dsm)
    print(f"(files in {out})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
