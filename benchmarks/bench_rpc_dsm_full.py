"""The RPC DSM of a large simulated scene, written tile by tile: time and peak memory.

A triplet of ``--size`` × ``--size`` images of ``--gsd`` m pixels (forward, nadir, backward
looking ``±--tan`` along the track — by default 0.5 m and 0.15, a Pléiades-like B/H of 0.15 and
0.3; ``--gsd 2.5 --tan 0.44 --size 14000`` is a PRISM triplet's size and geometry, as JAXA ships
it with RPC files —, the synthetic world and cubic RPCs of ``prismstation.sim.rpc_synth``:
rolling hills 250–600 m, a random ground texture of one-pixel cells), rendered strip by strip into tiled uint16
GeoTIFFs with their RPCs in the tags (kept in ``--out`` and not rendered again). Then, in a
child process per run, ``ops.rpc_dsm_export.write_rpc_dsm`` — what ``prismstation dsm`` runs
on a project of images with RPCs — at ``--posting``, every pair, first over a centred
``--windows`` crop of the first image each, then over the images' whole common footprint,
and with ``--fill`` once more on the smallest crop. Printed per run: grid, tiles, wall and
CPU time, the child's peak resident memory (``VmHWM``: ``ru_maxrss`` would keep the forking
parent's), fill, the heights against the true terrain (median, NMAD, every 4th cell) and the
pairs' agreement.

Run: ``.venv/bin/python benchmarks/bench_rpc_dsm_full.py [--size 8000] [--windows 2000 4000] [--fill]
[--gsd 0.5] [--tan 0.15] [--posting 0.5] [--workers 2] [--out DIR]``. Times are wall-clock on a shared machine.
"""
from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import rasterio
from rasterio.rpc import RPC
from scipy import ndimage

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from prismstation.sim.rpc_synth import World, analytic_terrain, make_rpc  # noqa: E402

LON0, LAT0 = 5.27, 44.17
H_OFF, H_SCALE = 400.0, 500.0


def render_strips(path, rpc, world, size: int, strip: int = 512, step: int = 8) -> None:
    """The image of ``rpc`` over ``world`` written strip by strip (rays lifted on a lattice
    every ``step`` px at three heights, quadratic in height, met with the terrain by fixed-point
    iteration: ``rpc_synth.render``'s method), uint16 (1000 + 200 × texture)."""
    profile = dict(driver="GTiff", width=size, height=size, count=1, dtype="uint16", tiled=True,
                   blockxsize=256, blockysize=256, rpcs=RPC.from_gdal(rpc.to_gdal_dict()))
    hs = rpc.h_off + rpc.h_scale * np.array([-1.0, 0.0, 1.0])
    with rasterio.open(path, "w", **profile) as ds:
        for r0 in range(0, size, strip):
            rows = min(strip, size - r0)
            gy0 = (r0 // step) * step
            ny, nx = (r0 + rows - gy0) // step + 2, size // step + 2
            gx, gy = np.meshgrid(np.arange(nx) * step + 0.5, gy0 + np.arange(ny) * step + 0.5)
            nodes = [rpc.localize(gx, gy, np.full(gx.shape, h)) for h in hs]
            ix, iy = np.meshgrid(np.arange(size) / step, (r0 + np.arange(rows) - gy0) / step)
            ray = [[ndimage.map_coordinates(v, [iy, ix], order=1) for v in node] for node in nodes]
            q = [(v[1], 0.5 * (v[2] - v[0]), 0.5 * (v[2] + v[0]) - v[1]) for v in zip(*ray)]
            h = np.full((rows, size), rpc.h_off)
            for _ in range(10):
                t = (h - hs[1]) / rpc.h_scale
                lon, lat = (c0 + c1 * t + c2 * t * t for c0, c1, c2 in q)
                h = world.height(lon, lat)
            img = np.clip(1000.0 + 200.0 * world.texture(lon, lat), 0, 65535).astype(np.uint16)
            ds.write(img, 1, window=rasterio.windows.Window(0, r0, size, rows))


class LeanWorld(World):
    """:class:`World` with its texture made in float32 (a 45 km world of 2.5 m cells is 330 M
    cells: float64 temporaries would take ~10 GB)."""

    def __init__(self, lon0, lat0, height, extent_m, texture_cell_m, seed=0):
        super().__init__(lon0, lat0, height, extent_m=1.0, texture_cell_m=1.0, seed=seed)
        rng = np.random.default_rng(seed)
        n = int(extent_m / texture_cell_m)
        t = ndimage.gaussian_filter(rng.standard_normal((n, n), dtype=np.float32), 1.2)
        t += 3.0 * ndimage.gaussian_filter(rng.standard_normal((n, n), dtype=np.float32), 6.0)
        self.tex, self.cell, self.half = t, texture_cell_m, extent_m / 2


def make_scene(out: Path, size: int, gsd: float, tan: float):
    world = LeanWorld(LON0, LAT0, analytic_terrain, extent_m=size * gsd * 1.3, texture_cell_m=gsd)
    paths = []
    t0 = time.perf_counter()
    for k, t in enumerate((tan, 0.0, -tan)):
        rpc = make_rpc(LON0, LAT0, gsd=gsd, size=size, tan_along=t, h_off=H_OFF, h_scale=H_SCALE, seed=k + 1)
        p = out / f"img{k}.tif"
        if not p.exists():
            render_strips(p, rpc, world, size)
        paths.append(p)
    print(f"scene: 3 images of {size} × {size} px at {gsd} m ({size * gsd / 1000:.1f} km, tan ±{tan}), "
          f"rendered in {time.perf_counter() - t0:.0f} s, in {out}")
    return paths


CHILD = r"""
import json, sys, time
import numpy as np, rasterio
sys.path.insert(0, {src!r})
from prismstation.io.rpc import read_rpc
from prismstation.core.adjustment.stats import nmad
from prismstation.io.rpc_scene import to_lonlat
from prismstation.ops.rpc_dsm_export import write_rpc_dsm
from prismstation.sim.rpc_synth import World, analytic_terrain
args = json.loads(sys.argv[1])
models = [read_rpc(p) for p in args["paths"]]
t0, c0 = time.perf_counter(), time.process_time()
dsm = write_rpc_dsm(args["output"], args["paths"], models, posting=args["posting"], window=args["window"],
                    fill=args["fill"], height_range=(200.0, 700.0), workers=args["workers"])
wall, cpu = time.perf_counter() - t0, time.process_time() - c0
# the process's own high-water mark (ru_maxrss would keep the forking parent's after exec)
peak = next(int(l.split()[1]) for l in open("/proc/self/status") if l.startswith("VmHWM")) / 1024
world = World({lon0}, {lat0}, analytic_terrain, extent_m=10.0, texture_cell_m=1.0)
d = []
with rasterio.open(args["output"]) as ds:
    for _, w in ds.block_windows(1):
        h = ds.read(1, window=w)[::4, ::4]
        t = ds.window_transform(w)
        E, N = np.meshgrid(t.c + t.a * (np.arange(0, w.width, 4) + 0.5), t.f + t.e * (np.arange(0, w.height, 4) + 0.5))
        lon, lat = to_lonlat(ds.crs.to_wkt())(E, N)
        dd = h - world.height(lon, lat)
        d.append(dd[np.isfinite(dd)])
d = np.concatenate(d)
print(json.dumps({{"wall": wall, "cpu": cpu, "peak_mb": peak, "shape": dsm.shape, "tiles": dsm.info["tiles"],
                  "fill": dsm.fill_fraction, "filled": dsm.counts["filled"], "seen": dsm.counts["seen"],
                  "median": float(np.median(d)), "nmad": nmad(d), "checked": int(d.size),
                  "agreement": {{k: [v["median_m"], v["nmad_m"]] for k, v in dsm.info["pair_agreement"].items()}}}}))
"""


def run_child(paths, output, posting, window, fill, workers) -> dict:
    code = CHILD.format(src=str(ROOT / "src"), lon0=LON0, lat0=LAT0)
    arg = json.dumps({"paths": [str(p) for p in paths], "output": str(output), "posting": posting,
                      "window": window, "fill": fill, "workers": workers})
    res = subprocess.run([sys.executable, "-W", "ignore", "-c", code, arg], capture_output=True, text=True)
    if res.returncode:
        sys.exit(res.stderr[-3000:])
    return json.loads(res.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=6000, help="image side, px")
    ap.add_argument("--gsd", type=float, default=0.5, help="pixel size, m")
    ap.add_argument("--tan", type=float, default=0.15, help="forward and backward views' tangent along track")
    ap.add_argument("--windows", type=int, nargs="*", default=[2000], help="also crops of this side (px)")
    ap.add_argument("--posting", type=float, default=0.5)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--fill", action="store_true", help="once more with --fill on the smallest crop")
    ap.add_argument("--out")
    args = ap.parse_args(argv)
    out = Path(args.out or tempfile.mkdtemp(prefix="bench_rpc_dsm_full_"))
    out.mkdir(parents=True, exist_ok=True)
    paths = make_scene(out, args.size, args.gsd, args.tan)
    runs = [(w, False) for w in sorted(args.windows)] + [(None, False)]
    if args.fill:
        runs.append((min(args.windows) if args.windows else None, True))
    for side, fill in runs:
        window = None if side is None else [(args.size - side) // 2] * 2 + [side, side]
        r = run_child(paths, out / f"dsm_{side or 'all'}{'_fill' if fill else ''}.tif", args.posting, window, fill,
                      args.workers)
        rows, cols = r["shape"]
        what = "whole footprint" if side is None else f"window of {side} px"
        filled = f", {r['filled']} filled" if fill else ""
        print(f"{what}{' + fill' if fill else ''}: {cols} × {rows} cells at {args.posting:g} m "
              f"({rows * cols / 1e6:.1f} M cells, {r['tiles']} tiles); {r['wall']:.0f} s wall, {r['cpu']:.0f} s CPU "
              f"(this process), peak RSS {r['peak_mb']:.0f} MB; {100 * r['fill']:.1f} % of {r['seen']} seen cells "
              f"matched{filled}; "
              f"− truth: median {r['median']:+.2f} m, NMAD {r['nmad']:.2f} m over {r['checked']} cells")
        print("   pairs: " + "; ".join(f"{k} {m:+.2f} / {n:.2f} m" for k, (m, n) in r["agreement"].items()))
    print(f"(parent peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB: the rendering)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
