"""Full-scale simulation benchmark: ``prismstation simulate`` at 14000 px (35 km) per image.

Prints the wall time of each phase, the peak resident memory and the sizes of the files.
Usage: ``python benchmarks/simulate_full.py [--size 14000] [--out DIR] [--seed 0]``
(without ``--out`` a temporary folder is used and removed).

Measured 2026-11-22 on the 2-core build machine while other jobs ran (load 6-8): 1339 s wall,
766 s CPU (terrain 19 s, texture 233 s, then 307 / 384 / 397 s for N / F / B), peak RSS
1.59 GB, three 291 MB GeoTIFFs with overviews 2-32, a 43 MB truth DEM (10 m).
"""
from __future__ import annotations

import argparse
import resource
import shutil
import sys
import tempfile
import time
from pathlib import Path

from prismstation.sim import simulate


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=14000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out")
    args = ap.parse_args(argv)
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="prism_sim_"))
    marks = []
    t0 = time.perf_counter()

    def progress(f):
        for level in (0.03, 0.15, 0.15 + 0.8 / 3, 0.15 + 1.6 / 3, 0.95, 1.0):
            if f >= level and level not in (m[0] for m in marks):
                marks.append((level, time.perf_counter() - t0))

    try:
        paths = simulate(out, size=args.size, seed=args.seed, progress=progress)
        total = time.perf_counter() - t0
        usage = resource.getrusage(resource.RUSAGE_SELF)
        peak_mb = usage.ru_maxrss / 1024
        cpu = usage.ru_utime + usage.ru_stime
        print(f"simulate size={args.size} seed={args.seed}: {total:.1f} s wall, "
              f"{cpu:.1f} s CPU, peak RSS {peak_mb:.0f} MB")
        names = ["terrain", "texture", "N rendered", "F rendered", "B rendered", "tables"]
        prev = 0.0
        for (level, t), name in zip(marks, names):
            print(f"  {name:<11s} done at {t:7.1f} s (+{t - prev:.1f} s)")
            prev = t
        mpix = 3 * args.size ** 2 / 1e6
        print(f"  {mpix:.0f} Mpixel rendered: {mpix / total:.2f} Mpixel/s overall")
        for key, p in sorted(paths.items()):
            print(f"  {p.name:<17s} {p.stat().st_size / 1e6:9.1f} MB")
    finally:
        if not args.out:
            shutil.rmtree(out, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
