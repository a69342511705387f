"""Where the least-squares misfit has several minima: each found transfer matched again from
starts 0.6 px away along and across its parallax, and the farthest end from the match.

On a scene (``bench_transfer``'s sets and their cached scenes, or another simulator's triplet
with ``--foreign``): every point of the scene transferred as ``bench_transfer`` transfers it
(fitted model, reference DEM), and each found match refined again at the same size and shape
from four starts ``±0.6 px`` along and across the parallax. Printed: the matches, how many end
more than 0.3 px (and 0.5 px) from the match, and how many of the matches more than 0.5 px (and
1 px) off the truth are among them.

``--pairs``: the texture alone — two point-sampled views of ``simulate``'s parcel textures
(``sim.texture.ParcelTexture``; a random sub-pixel shift and a 1 % affine, 2 DN of noise,
65 px templates), each matched from near the truth and again from ±0.6 px; and the same with
both images low-passed (``--lowpass`` σ px, ``refine``'s ``smooth``) before the fit.

    python benchmarks/bench_transfer_minima.py --set options
    python benchmarks/bench_transfer_minima.py --no-sim --foreign ../shared/data/foreign/smooth_hills_10km
    python benchmarks/bench_transfer_minima.py --pairs --lowpass 0 0.5 0.8 1.2
"""
from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np

import bench_transfer as bt
from prismstation.core.matching.lsm import refine
from prismstation.io.project import load_project
from prismstation.io.windows import ImageWindows
from prismstation.ops.fit import solve_project
from prismstation.ops.reference_heights import load_for_scene
from prismstation.ops.transfer import search_sigmas, transfer
from prismstation.sim.texture import MOTTLED, ParcelTexture

OFF = 0.6        # px: the restarts' distance from the match
OFF_ENDS = (0.3, 0.5)


def restart_spread(ref, xy, win, origin, m, d) -> float:
    """Farthest end (px) of the match ``m`` refined again from ``±OFF`` along and across ``d``."""
    c = np.array([-d[1], d[0]])
    ends = []
    for off in (OFF * d, -OFF * d, OFF * c, -OFF * c):
        r = refine(ref, xy[0], xy[1], win, np.array([m.x, m.y]) + off - origin, m.shape, parallax=d,
                   half=int(m.extra["half"]), max_sigma=5.0)
        if r.ok or r.status == "texture":
            ends.append(np.hypot(r.x + origin[0] - m.x, r.y + origin[1] - m.y))
    return max(ends, default=np.nan)


def scene_spreads(project, pts, ref_dem) -> tuple[np.ndarray, np.ndarray]:
    """``(spread, error)`` px of every found match of the scene's points, F and B."""
    sol = solve_project(project)
    dem = load_for_scene(ref_dem, project)
    spread, error = [], []
    with ImageWindows(project.scene) as im:
        sigma_dem, sigma_mean = search_sigmas(sol, dem)
        for p in pts:
            xy = np.asarray(p["image"]["N"], float)
            tr = transfer(sol, im, "N", xy, height_of=dem, sigma_dem=sigma_dem, sigma_mean=sigma_mean)
            for v in "FB":
                t = tr.get(v)
                if t is None or not t.ok:
                    continue
                d = np.asarray(t.match.extra["d"], float)
                d /= np.hypot(*d)
                half = int(t.match.extra["half"])
                ref, rc0, rr0 = im.around("N", xy[0], xy[1], half + 8)
                win, c0, r0 = im.around(v, t.x, t.y, 2 * half + 12)
                spread.append(restart_spread(ref, xy - (rc0, rr0), win, np.array([c0, r0]), t.match, d))
                error.append(np.hypot(t.x - p["image"][v][0], t.y - p["image"][v][1]))
    return np.array(spread), np.array(error)


def print_row(name: str, spread, error) -> None:
    far = [int(np.sum(spread > e)) for e in OFF_ENDS]
    off = [f"{int(np.sum((spread > OFF_ENDS[0]) & (error > e)))} of {int(np.sum(error > e))}" for e in (0.5, 1.0)]
    print(f"{name:<64} {len(spread):5d} {far[0]:6d} {far[1]:6d}   {off[0]:>9} {off[1]:>9}")


def pairs(kind: str, lowpass: float, n: int = 60, seed: int = 1) -> tuple[float, float]:
    """``(share of restarts ending > 0.3 px away, RMS error px)`` on ``n`` synthetic pairs."""
    rng = np.random.default_rng(seed)
    tex = ParcelTexture(np.random.default_rng(5), (0.0, 0.0), **(MOTTLED if kind == "mottled" else {}))
    size, gsd = 161, 2.5
    yy, xx = np.mgrid[0:size, 0:size] + 0.5
    far, err = [], []
    for _ in range(n):
        c = rng.uniform(1000, 9000, 2)
        a = tex(c[0] + gsd * xx, c[1] - gsd * yy) + rng.normal(0, 2, xx.shape)
        A = np.eye(2) + rng.normal(0, 0.01, (2, 2))
        t = rng.uniform(-0.5, 0.5, 2)
        q = np.einsum("ij,jkl->ikl", A, np.stack([xx - t[0], yy - t[1]]))
        b = tex(c[0] + gsd * q[0], c[1] - gsd * q[1]) + rng.normal(0, 2, xx.shape)
        p = np.array([80.5, 80.5])
        Ai = np.linalg.inv(A)
        truth = Ai @ p + t
        m = refine(a, p[0], p[1], b, truth + rng.normal(0, 0.3, 2), Ai, half=32, max_sigma=5.0, smooth=lowpass)
        if not m.ok:
            continue
        ends = []
        for off in ([OFF, 0], [-OFF, 0], [0, OFF], [0, -OFF]):
            r = refine(a, p[0], p[1], b, np.array([m.x, m.y]) + off, Ai, half=32, max_sigma=5.0, smooth=lowpass)
            if r.ok or r.status == "texture":
                ends.append(np.hypot(r.x - m.x, r.y - m.y))
        far.append(max(ends, default=0.0) > OFF_ENDS[0])
        err.append(np.hypot(m.x - truth[0], m.y - truth[1]))
    return float(np.mean(far)), float(np.sqrt(np.mean(np.square(err))))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--set", choices=sorted(bt.SETS), default="options")
    ap.add_argument("--size", type=int, default=4000)
    ap.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "prismstation-bench-transfer")
    ap.add_argument("--no-sim", action="store_true")
    ap.add_argument("--foreign", type=Path, nargs="*", default=[])
    ap.add_argument("--pairs", action="store_true", help="the textures alone, on synthetic pairs")
    ap.add_argument("--lowpass", type=float, nargs="+", default=[0.0, 0.8],
                    help="σ (px) of the Gaussian both images are low-passed by in --pairs")
    args = ap.parse_args(argv)
    if args.pairs:
        print(f"{'texture':<10} {'low-pass px':>11} {'restarts > 0.3 px':>18} {'RMS error px':>13}")
        for kind in ("parcels", "mottled"):
            for lp in args.lowpass:
                share, rms = pairs(kind, lp)
                print(f"{kind:<10} {lp:11.1f} {share:17.0%} {rms:13.3f}")
        return
    args.work.mkdir(parents=True, exist_ok=True)
    print(f"{'scene':<64} {'found':>5} {'> 0.3':>6} {'> 0.5':>6}   {'of > 0.5 off':>9} {'of > 1 off':>9}")
    if not args.no_sim:
        for terrain, seed, centre, *options in bt.SETS[args.set]:
            d, ref = bt.scene(args.work, terrain, seed, centre, args.size, *options)
            opts = dict(options[0]) if options else {}
            name = (f"{terrain} seed {seed}" + "".join(f", {k} {v}" for k, v in opts.items() if k != "reference")
                    + (", 3″ geographic reference" if opts.get("reference") == "geographic" else ""))
            pts = json.loads((d / "truth.json").read_text())["points"]
            print_row(name[:64], *scene_spreads(load_project(d / "p.prismproj"), pts, ref))
    for d in args.foreign:
        proj, pts, ref = bt.foreign_scene(d, args.work)
        print_row(f"foreign {d.name} (judged)", *scene_spreads(load_project(proj), pts, ref))


if __name__ == "__main__":
    main()
