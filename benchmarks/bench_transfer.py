"""Point transfer N → F and N → B on every terrain and on a real triplet: ours (shape-aware
least-squares matching through the fitted model, ``ops.transfer.transfer``) beside OpenCV's
``cv2.matchTemplate`` with a parabola fit on the same points, in one run.

Simulated triplets (``prismstation simulate``): the fractal relief, smooth rolling hills and a
real DEM's relief (an SRTM tile, steep places of it), each with an SRTM-like reference DEM made
from its truth (90 m, 2 m noise, voids). The model is fitted to the scene's 9 GCPs; every
ground point and tie point of the scene is transferred from its exact N position, and its F and
B results are compared with the simulator's exact image positions. Ours runs with the
reference DEM (the terrain slope gives the predicted shape) and without (a level plane at the
predicted height). The peer searches the same band (the same prediction, the same ranges along
and across the parallax direction) with the same 25 × 25 template; it finds a point when its
correlation peak reaches 0.6 inside the band, not at its end.

Real Pléiades triplet (three crops of one pass, RPCs in the TIFF tags, rasterio's
``RPCTransformer`` for image ↔ ground): a grid of points of image 1 transferred to images 2
and 3, predicted through the RPCs at the RPC's height offset ± its height scale (the search
range), the shape from the RPCs on a level plane. No truth: a point found in both images is
intersected (least squares on longitude, latitude, height, each image's RPC corrected first by
an affine of image position fitted to the tie points: the crops' RPCs are off by 0.1 px across
the parallax in a pattern of that kind); it is wrong when a residual exceeds 1 px in either image.

Columns: found (a match the method stands by), wrong (found but more than 1 px from the truth
or, on the real triplet, from the intersection), flagged (a failure, with its reason), RMS of
the found-and-right ones, and the σ check (RMS of error/σ along and across the parallax, the
share inside the 95 % ellipse: honest σ gives about 1, 1 and 95 %). ms per point is wall-clock
for both views and the consistency test (CPU time beside it: the machine may be shared); under
it, "reading": the CPU ms per point of it spent reading the images' pixels (a compressed file's
tiles are inflated on the first read that touches them, so the first method pays for them).
Under each of ours, the F and B errors along their parallaxes at the points right in both:
their correlation, and the RMS of their mean and of half their difference (a common part is a
height error the three rays cannot see).

    python benchmarks/bench_transfer.py                       # judged set, 4,000 px scenes
    python benchmarks/bench_transfer.py --set tuning
    python benchmarks/bench_transfer.py --size 2000 --work /tmp/bt --no-pleiades
    python benchmarks/bench_transfer.py --set options --no-pleiades \
        --foreign ../shared/data/foreign/smooth_hills_10km

``--set options``: the simulator's options for what another renderer's triplet differs by
(tuning scenes); ``--foreign``: another simulator's triplets with their exact image positions
(judged on, never tuned on).

Scenes are cached in ``--work`` (default a folder in the system's temporary directory).
"""
from __future__ import annotations

import argparse
import inspect
import json
import sys
import tempfile
import time
import warnings
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from prismstation.ops.project import create  # noqa: E402
from prismstation.core.matching.lsm_search import match  # noqa: E402
from prismstation.core.matching.lsm_kernel import compile_kernels  # noqa: E402
from prismstation.io.project import load_project  # noqa: E402
from prismstation.io.windows import ImageWindows  # noqa: E402
from prismstation.ops.fit import solve_project  # noqa: E402
from prismstation.ops.reference_heights import load_for_scene  # noqa: E402
from prismstation.ops.transfer import (FREE_SHAPE_CHANGE, MAX_SIGMA_PX, local_shape,  # noqa: E402
                                       search_height, search_sigmas, transfer)
from prismstation.ops.transfer_rays import model_sigma_m  # noqa: E402
from prismstation.sim import simulate  # noqa: E402
from prismstation.io.geoid import GridGeoid, find_grid  # noqa: E402
from prismstation.sim.reference import make_geographic_reference, make_reference_dem  # noqa: E402
from prismstation.core.matching.coarse import search_radius_px  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "real"
SRTM = DATA / "srtm" / "N44E005.hgt"
PLEIADES = DATA / "pleiades_triplet"
HALF = 12
PEER_MIN = 0.6
#: ours' template half size (``--half``; None: ``transfer``'s own choice)
HALF_WINDOW = None

from transfer_sets import SETS  # noqa: E402  (the scenes: tuned on, judged on)


# ---------------------------------------------------------------------------- the peer
def peer(ref, xy, win, pred, d, along, across):
    """``cv2.matchTemplate`` (TM_CCOEFF_NORMED) of the ``(2·HALF+1)²`` template at ``xy`` of
    ``ref`` over the band around ``pred`` of ``win``, parabola per axis: ``(x, y)`` or None."""
    i0, j0 = int(np.floor(xy[0])), int(np.floor(xy[1]))
    if not (HALF <= j0 < ref.shape[0] - HALF and HALF <= i0 < ref.shape[1] - HALF):
        return None
    tpl = ref[j0 - HALF:j0 + HALF + 1, i0 - HALF:i0 + HALF + 1].astype(np.float32)
    ox, oy = xy[0] - (i0 + 0.5), xy[1] - (j0 + 0.5)
    d = np.asarray(d, float) / np.hypot(*d)
    c = np.array([-d[1], d[0]])
    ext = np.abs(d) * along + np.abs(c) * across
    c0 = int(np.floor(pred[0] - ox - ext[0])) - HALF - 2
    r0 = int(np.floor(pred[1] - oy - ext[1])) - HALF - 2
    c1 = int(np.ceil(pred[0] - ox + ext[0])) + HALF + 3
    r1 = int(np.ceil(pred[1] - oy + ext[1])) + HALF + 3
    if c0 < 0 or r0 < 0 or c1 > win.shape[1] or r1 > win.shape[0]:
        return None
    ncc = cv2.matchTemplate(win[r0:r1, c0:c1].astype(np.float32), tpl, cv2.TM_CCOEFF_NORMED)
    vv, uu = np.mgrid[0:ncc.shape[0], 0:ncc.shape[1]]
    cx = c0 + uu + HALF + 0.5 + ox - pred[0]
    cy = r0 + vv + HALF + 0.5 + oy - pred[1]
    a, b = cx * d[0] + cy * d[1], cx * c[0] + cy * c[1]
    band = (np.abs(a) <= along + 0.5) & (np.abs(b) <= across + 0.5)
    masked = np.where(band & np.isfinite(ncc), ncc, -np.inf)
    v, u = np.unravel_index(int(np.argmax(masked)), masked.shape)
    if masked[v, u] < PEER_MIN or abs(a[v, u]) > along - 0.5 or not (0 < u < ncc.shape[1] - 1 and 0 < v < ncc.shape[0] - 1):
        return None

    def par(m1, m0, p1):
        den = m1 - 2 * m0 + p1
        return 0.0 if den >= 0 else float(np.clip(0.5 * (m1 - p1) / den, -0.5, 0.5))
    su, sv = par(*ncc[v, u - 1:u + 2]), par(*ncc[v - 1:v + 2, u])
    return c0 + u + su + HALF + 0.5 + ox, r0 + v + sv + HALF + 0.5 + oy


# ---------------------------------------------------------------------------- tables
class Tally:
    """Found / wrong / flagged, the errors of the right ones and the σ check of one method in
    one view."""

    def __init__(self):
        self.n, self.found, self.wrong, self.flagged = 0, 0, 0, 0
        self.errors, self.z, self.reasons = [], [], {}

    def add(self, err, found: bool, cov=None, d=None, status=None):
        self.n += 1
        if not found:
            self.flagged += 1
            if status:
                self.reasons[status] = self.reasons.get(status, 0) + 1
            return
        self.found += 1
        e = float(np.hypot(*err))
        if e > 1.0:
            self.wrong += 1
            return
        self.errors.append(e)
        if cov is not None and d is not None:
            d = np.asarray(d, float) / np.hypot(*d)
            P = np.array([d, [-d[1], d[0]]])
            e2, C = P @ np.asarray(err, float), P @ cov @ P.T
            self.z.append((e2[0] / np.sqrt(C[0, 0]), e2[1] / np.sqrt(C[1, 1]), e2 @ np.linalg.solve(C, e2)))

    def row(self) -> str:
        rms = np.sqrt(np.mean(np.square(self.errors))) if self.errors else np.nan
        s = f"{self.found:3d}/{self.n:<3d} {self.wrong:3d} {self.flagged:4d} {rms:7.3f}"
        if self.z:
            z = np.array(self.z)
            s += (f"   {np.sqrt(np.mean(z[:, 0] ** 2)):4.2f} {np.sqrt(np.mean(z[:, 1] ** 2)):4.2f}"
                  f" {100 * np.mean(z[:, 2] < 5.991):4.0f} %")
        else:
            s += " " * 18
        return s


def common_along(pairs) -> str:
    """A note on the F and B errors along their parallaxes at the points right in both (at least
    two): their correlation, the RMS of their mean and of half their difference (px). Relief
    within a template moves both views' matches to one wrong height: a common part the rays
    cannot see."""
    a = np.asarray(pairs, float)
    r = float(np.corrcoef(a[:, 0], a[:, 1])[0, 1])
    common, half = (a[:, 0] + a[:, 1]) / 2, (a[:, 0] - a[:, 1]) / 2
    return (f"{'':<57} F, B along the parallax at {len(a)} points: correlation {r:+.2f}, "
            f"mean {np.sqrt(np.mean(common ** 2)):.3f} px, half difference {np.sqrt(np.mean(half ** 2)):.3f} px RMS")


def header(first: str) -> str:
    cols = "found  wrong flag  RMS px   z∥   z⊥   in95"
    return f"{first:<34} {'method':<22} {'view':<4} {cols}   ms/pt (cpu)"


def print_rows(name, method, tallies, ms, cpu, views=("F", "B"), reading=None):
    """A method's rows, one per view; ``reading``: CPU ms per point of it spent reading the
    images' pixels (shown on the second row)."""
    for v in views:
        t = tallies[v]
        extra = f"   {ms:6.1f} ({cpu:5.1f})" if v == views[0] else ""
        if v != views[0] and reading is not None:
            extra = f"   reading ({reading:4.1f})"
        reasons = ", ".join(f"{k} {n}" for k, n in sorted(t.reasons.items()))
        print(f"{name:<34} {method:<22} {v:<4} {t.row()}{extra}   {reasons}")
        name = method = ""


# ---------------------------------------------------------------------------- simulated scenes
def scene(work: Path, terrain: str, seed: int, centre, size: int, options=None) -> tuple[Path, Path]:
    """The scene's folder (simulated once) and its reference DEM: SRTM-like on the scene's own
    grid, or with ``options["reference"] == "geographic"`` on a 3″ EPSG:4326 grid with EGM96
    heights and 4 m of noise."""
    options = dict(options or {})
    geographic = options.pop("reference", "projected") == "geographic"
    tag = (f"{terrain}_s{seed}_{size}" + (f"_{centre[0]:g}_{centre[1]:g}" if centre else "")
           + "".join(f"_{k}{v}" for k, v in sorted(options.items())))
    d = work / tag
    if not (d / "truth.json").exists():
        kw = dict(terrain=terrain, **(options or {}))
        if terrain == "dem":
            kw.update(terrain_dem=str(SRTM), terrain_centre=centre)
        print(f"  simulating {tag} …", flush=True)
        simulate(d, size=size, seed=seed, **kw)
    if not (d / "srtm.tif").exists():
        make_reference_dem(d / "truth_dem.tif", d / "srtm.tif", seed=seed)
    if geographic and not (d / "srtm_geo.tif").exists():
        make_geographic_reference(d / "truth_dem.tif", d / "srtm_geo.tif", GridGeoid(find_grid()), seed=seed)
    if not (d / "p.prismproj").exists():
        create(d / "p.prismproj", d / "scene.json", d / "points.csv", d / "measurements.csv")
    return d, d / ("srtm_geo.tif" if geographic else "srtm.tif")


def foreign_scene(d: Path, work: Path) -> tuple[Path, list, Path]:
    """Another simulator's triplet: its project (made once in ``work``), its points' exact
    image positions, its SRTM-like reference."""
    proj = work / f"foreign_{d.name}.prismproj"
    if not proj.exists():
        create(proj, d / "scene.json", d / "points.csv", d / "measurements.csv", geoid="auto")
    exact = json.loads((d / "truth_image.json").read_text())
    return proj, [{"image": v} for v in exact.values()], d / "srtm_like.tif"


class TimedWindows(ImageWindows):
    """:class:`ImageWindows` that counts the CPU seconds of its reads (``cpu``): the files'
    own cost (a compressed tile is inflated once, on the first read that touches it)."""

    cpu = 0.0

    def read(self, *args, **kw):
        c0 = time.process_time()
        try:
            return super().read(*args, **kw)
        finally:
            self.cpu += time.process_time() - c0


def run_scene(d: Path, foreign_work: Path | None = None, ref: Path | None = None) -> None:
    if foreign_work is not None:
        proj, pts, ref = foreign_scene(d, foreign_work)
        project = load_project(proj)
        name = f"foreign {d.name} (judged)"
    else:
        project = load_project(d / "p.prismproj")
        truth = json.loads((d / "truth.json").read_text())
        st = truth.get("terrain", {}).get("statistics", {})
        args = truth["arguments"]
        defaults = inspect.signature(simulate).parameters
        opts = "".join(f", {k} {args[k]}" for k in ("texture", "psf_px", "noise_dn", "jpeg_quality")
                       if k in args and args[k] != defaults[k].default)
        name = (f"{truth.get('terrain', {}).get('kind', 'fractal')} seed {args['seed']}, "
                f"slope {st.get('mean_slope_pct', float('nan')):.0f} %{opts}")
        if ref is not None and ref.name == "srtm_geo.tif":
            name += ", 3″ geographic reference"
        ref, pts = ref or d / "srtm.tif", truth["points"]
    sol = solve_project(project)
    dem = load_for_scene(ref, project)
    with TimedWindows(project.scene) as im:
        for label, height_of in (("ours, reference DEM", dem), ("ours, no DEM", None)):
            tal = {v: Tally() for v in "FB"}
            along = []          # (F, B) errors along each view's parallax where both are right
            t0, c0, r0 = time.perf_counter(), time.process_time(), im.cpu
            # as the window: the σ of the DEM and of the mean height measured once
            sigma_dem, sigma_mean = search_sigmas(sol, height_of)
            for p in pts:
                tr = transfer(sol, im, "N", p["image"]["N"], height_of=height_of, sigma_dem=sigma_dem,
                              sigma_mean=sigma_mean, half_window=HALF_WINDOW)
                pair = {}
                for v in "FB":
                    t = tr.get(v)
                    if t is None:
                        tal[v].add(None, False, status="outside")
                        continue
                    err = np.subtract((t.x, t.y), p["image"][v])
                    tal[v].add(err, t.ok, t.match.cov, t.match.extra.get("d"), t.match.status)
                    if t.ok and np.hypot(*err) <= 1.0 and t.match.extra.get("d") is not None:
                        d = np.asarray(t.match.extra["d"], float)
                        pair[v] = float(err @ d / np.hypot(*d))
                if len(pair) == 2:
                    along.append((pair["F"], pair["B"]))
            ms = (time.perf_counter() - t0) / len(pts) * 1e3
            cpu = (time.process_time() - c0) / len(pts) * 1e3
            print_rows(name, label, tal, ms, cpu, reading=(im.cpu - r0) / len(pts) * 1e3)
            if len(along) >= 10:
                print(common_along(along))
            name = ""
        # the peer on the same points, the same prediction and the same band as ours with the DEM
        tal = {v: Tally() for v in "FB"}
        radius = search_radius_px(model_sigma_m(sol) * np.sqrt(2), project.scene.views["N"].pixel_size_m)
        spent, spent_cpu = 0.0, 0.0
        for p in pts:
            xy = np.asarray(p["image"]["N"], float)
            h, h_range = search_height(sol, "N", xy, height_of=dem)
            _, _, shapes = local_shape(sol, "N", xy, "FB", h=h, height_of=dem)
            ref, rc0, rr0 = im.around("N", xy[0], xy[1], HALF + 8)
            for v in "FB":
                s = shapes[v]
                along = radius + float(np.hypot(*s.dh)) * h_range
                win, c0_, r0_ = im.around(v, s.pred[0], s.pred[1], int(along + radius) + HALF + 12)
                t0, c0 = time.perf_counter(), time.process_time()
                q = peer(ref, xy - [rc0, rr0], win, s.pred - [c0_, r0_], s.dh, along, radius)
                spent += time.perf_counter() - t0
                spent_cpu += time.process_time() - c0
                if q is None:
                    tal[v].add(None, False, status="below 0.6 or at the end")
                else:
                    tal[v].add(np.subtract(np.add(q, (c0_, r0_)), p["image"][v]), True)
        print_rows("", "cv2.matchTemplate", tal, spent / len(pts) * 1e3, spent_cpu / len(pts) * 1e3)


# ---------------------------------------------------------------------------- the real triplet
def pleiades(n_side: int = 12) -> None:
    import rasterio
    from rasterio.transform import RPCTransformer
    ims, rpcs = [], []
    for k in (1, 2, 3):
        with warnings.catch_warnings(), rasterio.open(PLEIADES / f"img_0{k}.tif") as ds:
            warnings.simplefilter("ignore")
            ims.append(ds.read(1).astype(np.float32))
            rpcs.append(ds.rpcs)
    tr = [RPCTransformer(r) for r in rpcs]
    h0, h_range = float(rpcs[0].height_off), float(rpcs[0].height_scale)

    def ground(k, xy, h):
        lon, lat = tr[k].xy(np.atleast_1d(xy[..., 1]), np.atleast_1d(xy[..., 0]), zs=np.atleast_1d(h), offset="ul")
        return np.column_stack([lon, lat])

    def image(k, ll, h):
        r, c = tr[k].rowcol(ll[:, 0], ll[:, 1], zs=np.broadcast_to(h, ll[:, 0].shape), op=lambda a: a)
        return np.column_stack([c, r]).astype(float)

    def predict(xy, k, step=float(HALF)):
        pts = xy + np.array([[0, 0], [step, 0], [-step, 0], [0, step], [0, -step]])
        q = image(k, ground(0, pts, np.full(5, h0)), h0)
        up = image(k, ground(0, xy[None], np.array([h0 + 1.0])), h0 + 1.0)[0]
        A = np.column_stack([(q[1] - q[2]) / (2 * step), (q[3] - q[4]) / (2 * step)])
        return q[0], A, up - q[0]

    g = np.linspace(90, 930, n_side)
    points = [np.array([x, y]) for y in g for x in g]
    across = 10.0                     # ± px: the images' relative RPC bias (one pass)
    found = {"ours": {}, "cv2.matchTemplate": {}}
    status = {"ours": {1: {}, 2: {}}, "cv2.matchTemplate": {1: {}, 2: {}}}
    spent = {m: [0.0, 0.0] for m in found}
    for i, xy in enumerate(points):
        for k in (1, 2):
            pred, A, dh = predict(xy, k)
            along = abs(float(np.hypot(*dh))) * h_range
            t0, c0 = time.perf_counter(), time.process_time()
            r = match(ims[0], *xy, ims[k], pred, A, dh, along=along, across=across, half=HALF,
                      max_shape_change=FREE_SHAPE_CHANGE, coarse=1.5, rival=6.0, parallax=dh,
                      max_sigma=MAX_SIGMA_PX)
            spent["ours"][0] += time.perf_counter() - t0
            spent["ours"][1] += time.process_time() - c0
            if r.ok:
                found["ours"].setdefault(i, {})[k] = (np.array([r.x, r.y]), r.cov)
            else:
                status["ours"][k][r.status] = status["ours"][k].get(r.status, 0) + 1
            t0, c0 = time.perf_counter(), time.process_time()
            q = peer(ims[0], xy, ims[k], pred, dh, along, across)
            spent["cv2.matchTemplate"][0] += time.perf_counter() - t0
            spent["cv2.matchTemplate"][1] += time.process_time() - c0
            if q is not None:
                found["cv2.matchTemplate"].setdefault(i, {})[k] = (np.array(q), None)
            else:
                s = status["cv2.matchTemplate"][k]
                s["below 0.6 or at the end"] = s.get("below 0.6 or at the end", 0) + 1

    def intersect(xy, obs):
        """Least squares (lon, lat, h) of image 1's ``xy`` and ``obs`` {k: xy}; residuals (px)."""
        ll = ground(0, xy[None], np.array([h0]))[0]
        p = np.array([ll[0], ll[1], h0])
        steps = np.array([1e-6, 1e-6, 1.0])
        allobs = {0: xy, **obs}
        for _ in range(6):
            rows, res = [], []
            for k, o in allobs.items():
                f0 = image(k, p[None, :2], p[2])[0]
                J = np.column_stack([(image(k, (p + e)[None, :2], (p + e)[2])[0] - f0) / s
                                     for e, s in zip(np.diag(steps), steps)])
                rows.append(J)
                res.append(o - f0)
            dp = np.linalg.lstsq(np.vstack(rows), np.concatenate(res), rcond=None)[0]
            p = p + dp
            if abs(dp[2]) < 1e-3:
                break
        return {k: o - image(k, p[None, :2], p[2])[0] for k, o in allobs.items()}

    def check(both):
        """Intersection residuals ``{i: {k: (2,)}}`` of the tie points ``both`` ({i: {k: xy}}),
        each image's RPC corrected by an affine of image position fitted to the tie points
        themselves (robustly: the points within 3 NMAD, at least 0.3 px, of the last fit)."""
        corr = {1: np.zeros((3, 2)), 2: np.zeros((3, 2))}
        keep = dict.fromkeys(both, True)
        for _ in range(20):     # slow: a common shift of images 2 and 3 is nearly a ground shift
            rs = {i: intersect(points[i], {k: o[k] - np.r_[1.0, o[k] / 1000] @ corr[k] for k in (1, 2)})
                  for i, o in both.items()}
            for k in (1, 2):
                use = [i for i in both if keep[i]]
                X = np.array([np.r_[1.0, both[i][k] / 1000] for i in use])
                corr[k] = corr[k] + np.linalg.lstsq(X, np.array([rs[i][k] for i in use]), rcond=None)[0]
            e = np.array([max(np.hypot(*rs[i][1]), np.hypot(*rs[i][2])) for i in both])
            lim = max(3 * 1.4826 * np.median(e), 0.3)
            keep = {i: bool(v <= lim) for i, v in zip(both, e)}
        return rs

    print(f"\nReal Pléiades triplet (Aubagne, 0.5 m): {len(points)} points of image 1 → images 2 and 3, "
          f"height {h0:.0f} ± {h_range:.0f} m (the RPC's), ±{across:g} px across")
    print(header("triplet") + "   χ²/3 with the stated σ")
    for m, res in found.items():
        both = {i: o for i, o in res.items() if len(o) == 2}
        rs = check({i: {k: o[k][0] for k in (1, 2)} for i, o in both.items()})
        tal = {k: Tally() for k in (1, 2)}
        chi = []
        for i in range(len(points)):
            for k in (1, 2):
                if i not in res or k not in res[i]:
                    tal[k].add(None, False, status=None)
                elif i not in rs:
                    tal[k].add(None, False, status="the other image failed")
                else:
                    tal[k].add(rs[i][k], True)
            if i in rs and all(np.hypot(*rs[i][k]) <= 1 for k in (1, 2)) and m == "ours":
                W = [np.linalg.inv(both[i][k][1]) for k in (1, 2)]
                chi.append(sum(rs[i][k] @ W[j] @ rs[i][k] for j, k in enumerate((1, 2))) / 3)
        for k in (1, 2):
            tal[k].reasons = status[m][k]
        name = f"{m}"
        ms = spent[m][0] / len(points) * 1e3
        cpu = spent[m][1] / len(points) * 1e3
        extra = f"   median {np.median(chi):.2f}, mean {np.mean(chi):.2f}" if chi else ""
        for k in (1, 2):
            t = tal[k]
            reasons = ", ".join(f"{a} {n}" for a, n in sorted(t.reasons.items()))
            tail = f"   {ms:6.1f} ({cpu:5.1f})" + extra if k == 1 else ""
            print(f"{'Pléiades img 1 → ' + str(k + 1):<34} {name:<22} {k + 1:<4} {t.row()}{tail}   {reasons}")
            name = ""
    print("  (found here: in both images; wrong / RMS: the intersection residual in that image, each image's RPC\n"
          "   corrected by an affine fitted to the tie points; the χ² uses the stated covariances)")


def reference_ms() -> float:
    """CPU ms of a fixed numpy workload (the normal equations of 200 patches of 625 pixels and
    11 parameters): the machine's speed when the figures were taken, for comparing runs."""
    rng = np.random.default_rng(0)
    J = rng.standard_normal((625, 11))
    r = rng.standard_normal(625)
    c0 = time.process_time()
    for _ in range(200):
        np.linalg.solve(J.T @ J, J.T @ r)
    return (time.process_time() - c0) * 1e3


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--set", choices=sorted(SETS), default="judged")
    ap.add_argument("--size", type=int, default=4000)
    ap.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "prismstation-bench-transfer")
    ap.add_argument("--no-pleiades", action="store_true")
    ap.add_argument("--no-sim", action="store_true")
    ap.add_argument("--foreign", type=Path, nargs="*", default=[],
                    help="folders of another simulator's triplets (scene.json, points.csv, "
                         "measurements.csv, truth_image.json, srtm_like.tif): judged, never tuned on")
    ap.add_argument("--orient-cells", action="store_true",
                    help="also measure orient-dem's relative DEM cells against least squares (steep scenes)")
    ap.add_argument("--half", type=int, default=None,
                    help="ours' template half size, px (default: transfer's own choice)")
    args = ap.parse_args(argv)
    global HALF_WINDOW
    HALF_WINDOW = args.half
    args.work.mkdir(parents=True, exist_ok=True)
    print("Point transfer N → F / N → B: found, wrong (> 1 px), flagged, RMS of the right ones (px),\n"
          "σ check (RMS z along / across the parallax, share in the 95 % ellipse), ms per point (CPU)\n"
          "(timings from a shared machine)\n")
    print(f"machine reference (a fixed numpy workload): {reference_ms():.1f} ms CPU")
    c0 = time.process_time()
    compile_kernels()
    print(f"matching's compiled loops loaded (or compiled), once per process: "
          f"{(time.process_time() - c0) * 1e3:.0f} ms CPU\n")
    if not args.no_sim:
        print(header("scene") + "   failures")
        for terrain, seed, centre, *options in SETS[args.set]:
            d, ref = scene(args.work, terrain, seed, centre, args.size, *options)
            run_scene(d, ref=ref)
    if args.foreign:
        print(header("another simulator's scene") + "   failures")
        for d in args.foreign:
            run_scene(d, foreign_work=args.work)
    if args.orient_cells:
        from bench_transfer_cells import orient_cells
        for terrain, seed, centre, *_ in SETS[args.set]:
            if terrain == "dem":
                orient_cells(scene(args.work, terrain, seed, centre, args.size)[0])
    if not args.no_pleiades and PLEIADES.is_dir():
        pleiades()
    print(f"\nmachine reference at the end: {reference_ms():.1f} ms CPU")


if __name__ == "__main__":
    main()
