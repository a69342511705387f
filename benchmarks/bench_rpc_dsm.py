"""The RPC DSM on the real Pléiades triplet (Aubagne, three ~1,024 px crops, 0.5 m pixels).

Printed:

1. tie points (SIFT + NCC/LSM) and the shift-bias fit with image 1 held fixed, as
   ``bench_rpc_bias.py`` makes them (reference heights: the raw RPCs' intersection + 2 m noise,
   σ 2 m — no DEM covering these crops is among the samples); time;
2. the DSM (``ops.rpc_dsm.rpc_dsm``) at each posting, with the fitted biases and with the raw
   RPCs: time, peak memory, fill, and per pair of pair DSMs the median and NMAD of their
   difference and that NMAD in units of the formal σ; the tiles' largest epipolar error;
3. the peer, in the same process: each pair orthorectified by GDAL's RPC transformer
   (``rasterio.warp.reproject`` with the RPCs, the fitted shift folded into the RPC offsets) at
   the tie points' mean height on a 0.5 m grid turned so that the pair's parallax runs along
   its rows, the same StereoSGBM and subpixel refinement (``core.matching.sgm``), heights from the
   parallax rate, binned to the same 1 m grid: time and the same agreement figures;
4. orientation from a reference DEM: SRTM's N44E005 tile (the only one among the samples)
   does not reach Aubagne (43.26° N), so the reference is the triplet's own fitted DSM
   (averaged to 4 m cells), and the block is moved by a known ground shift through the RPCs'
   ground offsets; the shift found and each image's bias error against the truth (px);
5. with ``--out``: the fused DSM's shaded relief as a JPEG;
6. the Giza pair (``.geom`` RPCs) and the Réunion pair (high terrain): the bias fit as above,
   the pair DSM with fitted and raw RPCs, its fill and its heights against the tie points'
   (fitted) heights.

Run: ``.venv/bin/python benchmarks/bench_rpc_dsm.py [--postings 1 0.5] [--out docs/x.jpg]``.
Times are wall-clock on a shared, busy 2-core machine: indicative only.
"""
from __future__ import annotations

import argparse
import resource
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import rasterio
from rasterio.rpc import RPC
from rasterio.warp import reproject, Resampling

from prismstation.core.matching import sgm
from prismstation.core.surfaces.dsmstats import hillshade
from prismstation.core.models.rpc_adjust import adjust_snooping
from prismstation.core.models.rpc_bias import intersect_points, metres_per_degree
from prismstation.core.surfaces.rpc_epipolar import grid_heights
from prismstation.core.matching.rpc_tiepoints import match_tie_points
from prismstation.core.adjustment.stats import nmad
from prismstation.io.dem import write_dem
from prismstation.io.raster import gdal_env
from prismstation.io.rpc import read_rpc
from prismstation.io.rpc_scene import to_lonlat, to_map
from prismstation.ops.rpc_dsm import PairDsm, footprint_grid, image_shape, pair_agreement, rpc_dsm
from prismstation.ops.rpc_orient import orient_from_reference

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real"
FILES = [DATA / "pleiades_triplet" / f"img_0{i}.tif" for i in (1, 2, 3)]
CRS = "EPSG:32631"
H_SIGMA = 2.0


def peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def agreement_rows(pairs, label):
    for key, v in pair_agreement(pairs).items():
        print(f"   {label:10s} {key:16s} median {v['median_m']:+6.2f} m  NMAD {v['nmad_m']:5.2f} m  "
              f"({v['nmad_in_sigma']:4.2f} σ)  cells {v['cells']}")


def bias_fit(rpcs, images):
    t0 = time.perf_counter()
    tp = match_tie_points(images)
    t_match = time.perf_counter() - t0
    before = intersect_points(rpcs, tp.point, tp.image, tp.xy, tp.sigma, tp.n_points)
    href = before.h + np.random.default_rng(0).normal(0, H_SIGMA, tp.n_points)
    t0 = time.perf_counter()
    fit, kept = adjust_snooping(rpcs, tp.point, tp.image, tp.xy, tp.sigma, bias="shift",
                                height_point=np.arange(tp.n_points), height=href, height_sigma=H_SIGMA)
    t_fit = time.perf_counter() - t0
    print(f"1. {tp.n_points} tie points in {t_match:.1f} s, {int((~kept).sum())} rejected; shift-bias fit "
          f"{t_fit * 1000:.0f} ms, σ0 {fit.sigma0:.2f}; heights {fit.h.min():.0f}–{fit.h.max():.0f} m")
    for k, m in enumerate(fit.models):
        b = "held fixed" if k in fit.fixed else f"x {m.params[0]:+.2f} ± {fit.bias_std(k)[0]:.2f}, " \
                                                f"y {m.params[1]:+.2f} ± {fit.bias_std(k)[1]:.2f} px"
        print(f"   image {k + 1}: {b}")
    return fit


def gdal_peer(fit, grid, pair, h0, height_range):
    """One pair by GDAL orthorectification at ``h0`` + StereoSGBM (module docstring)."""
    i, j = pair
    t0 = time.perf_counter()
    models = [fit.models[i], fit.models[j]]
    # relief displacement per metre of height of each view on the ground (E, N), at the centre
    ce, cn = grid.cell_centres()
    e0, n0 = float(ce.mean()), float(cn.mean())
    lon0, lat0 = to_lonlat(CRS)(e0, n0)
    r = []
    for m in models:
        x, y = m.project(lon0, lat0, h0)
        pts = [to_map(CRS)(*m.localize(x, y, h)) for h in (h0, h0 + 100.0)]
        r.append((np.array(pts[1]) - np.array(pts[0])) / 100.0)
    # a ray lifted by dh moves on the ground by dh·r: a point at height h lies in the view's
    # ortho (at h0) at X − (h − h0)·r, so the second view's ortho, matched against the first
    # (left = second), has the parallax (h − h0)·(r_1 − r_2) along t = (r_1 − r_2)/k
    dr = r[0] - r[1]
    k = float(np.hypot(*dr))
    t = dr / k
    u = np.array([-t[1], t[0]])
    g = 0.5
    half = 0.5 * np.hypot(grid.shape[0], grid.shape[1]) * grid.posting + 40.0
    n = int(2 * half / g)
    origin = np.array([e0, n0]) - half * (t + u)
    transform = rasterio.Affine(g * t[0], g * u[0], origin[0], g * t[1], g * u[1], origin[1])
    orthos = []
    for idx, m in zip(pair, models):
        rpc = m.rpc.shifted(*m.params[:2])
        with rasterio.open(FILES[idx]) as ds:
            src = ds.read(1).astype(np.float32)
        dst = np.full((n, n), np.nan, np.float32)
        reproject(src, dst, rpcs=RPC.from_gdal(rpc.to_gdal_dict()), src_crs="EPSG:4326", dst_crs=CRS,
                  dst_transform=transform, dst_nodata=np.nan, resampling=Resampling.cubic,
                  RPC_HEIGHT=h0)
        orthos.append(dst)
    valid = [np.isfinite(o) for o in orthos]
    orthos, valid, r = orthos[::-1], valid[::-1], r[::-1]
    u8 = [sgm.to_uint8(o, v) for o, v in zip(orthos, valid)]
    lo = int(np.floor((height_range[0] - h0) * k / g)) - 3
    num = int(np.ceil(((height_range[1] - h0) * k / g + 3 - lo) / 16)) * 16
    d = sgm.sgbm(u8[0], u8[1], lo, num)
    d = sgm.refine_subpixel(*[np.where(v, o, 0).astype(np.float32) for o, v in zip(orthos, valid)], d)
    bad = cv2.dilate((~(valid[0] & valid[1])).astype(np.uint8), np.ones((10, 10), np.uint8)) > 0
    d[bad] = np.nan
    dh = d * g / k
    h = h0 + dh
    cols, rows = np.meshgrid(np.arange(n) + 0.5, np.arange(n) + 0.5)
    E = transform.c + transform.a * cols + transform.b * rows + dh * r[0][0]
    N = transform.f + transform.d * cols + transform.e * rows + dh * r[0][1]
    hm, cnt, _ = grid_heights(E, N, h, grid.transform, grid.shape)
    sigma = sgm.SIGMA_DISPARITY_PX * g / k / np.sqrt(np.maximum(cnt, 1))
    out = PairDsm(tuple(pair), hm, cnt, sigma.astype(np.float32))
    out.seconds = time.perf_counter() - t0
    return out


def orientation(fit, dsm, paths, points, h_range):
    shift = np.array([6.0, -4.0, 3.0])
    ke, kn = metres_per_degree(43.26)
    moved = [replace(m, rpc=replace(m.rpc, lon_off=m.rpc.lon_off - shift[0] / ke,
                                    lat_off=m.rpc.lat_off - shift[1] / kn, h_off=m.rpc.h_off - shift[2]))
             for m in fit.models]
    with tempfile.TemporaryDirectory() as d:
        ref = Path(d) / "reference.tif"
        write_dem(ref, dsm.heights, dsm.crs, dsm.transform)
        t0 = time.perf_counter()
        lon, lat = to_lonlat(CRS)(points[0] - shift[0], points[1] - shift[1])
        moved_pts = (lon, lat, points[2] - shift[2])
        mdsm, _ = rpc_dsm(paths, moved, posting=dsm.posting_m, pairs=[(0, 2)], points=moved_pts,
                          height_range=h_range, crs=CRS)
        o = orient_from_reference(moved, mdsm.heights, mdsm.transform, mdsm.crs, ref, cell_m=4.0)
        dt = time.perf_counter() - t0
    s, sg = np.array(o.shift_m), np.array(o.sigma_m)
    print(f"4. orientation from a reference DEM: SRTM N44E005 covers 44–45° N, the triplet lies at 43.26° N: "
          f"not covered. Reference = the fitted DSM at 4 m cells; block moved by ({shift[0]:+.0f}, {shift[1]:+.0f}, "
          f"{shift[2]:+.0f}) m (E, N, U)")
    print(f"   found ({s[0]:+.2f} ± {sg[0]:.2f}, {s[1]:+.2f} ± {sg[1]:.2f}, {s[2]:+.2f} ± {sg[2]:.2f}) m, "
          f"{o.coreg.count} cells, NMAD after {o.coreg.nmad_after:.2f} m; pair DSM + orientation {dt:.1f} s")
    lon, lat = to_lonlat(CRS)(*points[:2])
    for k, (m_true, m_new) in enumerate(zip(fit.models, o.models)):
        x0, y0 = m_true.project(lon, lat, points[2])
        x1, y1 = m_new.project(lon, lat, points[2])
        xb, yb = moved[k].project(lon, lat, points[2])
        print(f"   image {k + 1}: off by {np.hypot(xb - x0, yb - y0).mean():.2f} px before, after x "
              f"{np.mean(x1 - x0):+.3f} y {np.mean(y1 - y0):+.3f} px (σ {o.bias_sigma[k][0]:.3f}, "
              f"{o.bias_sigma[k][1]:.3f})")


PAIRS = {"Giza (.geom)": ["pleiades_pair_gizeh/img1.tif", "pleiades_pair_gizeh/img2.tif"],
         "Réunion": ["pleiades_pair_reunion/img_01.tif", "pleiades_pair_reunion/img_02.tif"]}


def other_pairs(posting):
    """The two real pairs: bias fit, then the pair DSM, checked against the tie points."""
    print(f"6. the two other real pairs at {posting:g} m (tie points' heights ± 100 m a priori)")
    for name, files in PAIRS.items():
        paths = [DATA / f for f in files]
        if not all(p.is_file() for p in paths):
            print(f"   {name}: absent")
            continue
        rpcs = [read_rpc(p) for p in paths]
        images = []
        for p in paths:
            with rasterio.open(p) as ds:
                images.append(ds.read(1))
        tp = match_tie_points(images)
        before = intersect_points(rpcs, tp.point, tp.image, tp.xy, tp.sigma, tp.n_points)
        href = before.h + np.random.default_rng(0).normal(0, H_SIGMA, tp.n_points)
        fit, _ = adjust_snooping(rpcs, tp.point, tp.image, tp.xy, tp.sigma, bias="shift",
                                 height_point=np.arange(tp.n_points), height=href, height_sigma=H_SIGMA)
        crs = None
        for label, models in (("fitted", fit.models), ("raw RPCs", rpcs)):
            t0 = time.perf_counter()
            dsm, pairs = rpc_dsm(paths, models, posting=posting, height_range=(fit.h.min() - 100, fit.h.max() + 100),
                                 points=None, crs=crs)
            dt = time.perf_counter() - t0
            crs = dsm.crs
            e, n = to_map(dsm.crs)(fit.lon, fit.lat)
            a, _, c, _, ee, f = dsm.transform
            col, row = ((np.asarray(e) - c) / a).astype(int), ((np.asarray(n) - f) / ee).astype(int)
            ok = (col >= 0) & (col < dsm.heights.shape[1]) & (row >= 0) & (row < dsm.heights.shape[0])
            dh = dsm.heights[row[ok], col[ok]] - fit.h[ok]
            print(f"   {name}, {label}: {tp.n_points} tie points, heights {fit.h.min():.0f}–{fit.h.max():.0f} m; "
                  f"{dsm.heights.shape[1]} × {dsm.heights.shape[0]} cells in {dt:.1f} s, fill "
                  f"{100 * dsm.valid_fraction:.1f} %, DSM − tie points median {np.nanmedian(dh):+.2f} m, "
                  f"NMAD {nmad(dh):.2f} m ({int(np.isfinite(dh).sum())} points), epipolar error ≤ "
                  f"{dsm.info['epipolar_error_px']:.4f} px")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--postings", type=float, nargs="+", default=[1.0])
    ap.add_argument("--out", type=Path, help="shaded relief JPEG of the fused DSM at the first posting")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    if not all(f.is_file() for f in FILES):
        print(f"no Pléiades triplet at {DATA}")
        return 1
    rpcs = [read_rpc(f) for f in FILES]
    images = []
    for f in FILES:
        with rasterio.open(f) as ds:
            images.append(ds.read(1))
    print(f"Pléiades triplet, Aubagne: {', '.join(f'{im.shape[1]} × {im.shape[0]}' for im in images)} px; "
          f"RPC height domain {rpcs[0].h_off - rpcs[0].h_scale:.0f}–{rpcs[0].h_off + rpcs[0].h_scale:.0f} m")
    fit = bias_fit(rpcs, images)
    del images
    e, n = to_map(CRS)(fit.lon, fit.lat)
    points = (np.asarray(e), np.asarray(n), fit.h)
    h_range = (float(fit.h.min()) - 100.0, float(fit.h.max()) + 100.0)
    print(f"2. DSM: a-priori heights {h_range[0]:.0f}–{h_range[1]:.0f} m (tie points ± 100 m), per tile the "
          "tie points near it ± max(20 m, 25 %); ellipsoidal heights, UTM 31N")
    first = None
    for posting in args.postings:
        for label, models in (("fitted", fit.models), ("raw RPCs", rpcs)):
            t0, c0 = time.perf_counter(), time.process_time()
            dsm, pairs = rpc_dsm(FILES, models, posting=posting, points=(fit.lon, fit.lat, fit.h),
                                 height_range=h_range,
                                 crs=CRS, workers=args.workers)
            dt, cpu = time.perf_counter() - t0, time.process_time() - c0
            print(f"   {posting:g} m, {label}: {dsm.heights.shape[1]} × {dsm.heights.shape[0]} cells, "
                  f"{dt:.1f} s wall, {cpu:.1f} s CPU, peak RSS {peak_mb():.0f} MB, fill {100 * dsm.valid_fraction:.1f} % "
                  f"(pairs {', '.join(f'{100 * f:.1f}' for f in dsm.info['pair_fill'])} %), "
                  f"3 pairs agree on {100 * np.mean(dsm.quality[np.isfinite(dsm.heights)] == 3):.0f} % of cells, "
                  f"epipolar error ≤ {dsm.info['epipolar_error_px']:.4f} px")
            agreement_rows(pairs, label)
            if first is None:
                first = (dsm, pairs, dt, cpu)
    dsm, pairs = first[:2]
    grid = footprint_grid(fit.models, [image_shape(f) for f in FILES],
                          dsm.posting_m, 0.5 * sum(h_range), CRS)
    h0 = float(np.median(fit.h))
    peer = []
    cv2.setNumThreads(1)          # as in our tiles (each a Dask task on one OpenCV thread)
    t0, c0 = time.perf_counter(), time.process_time()
    for pr in ((0, 1), (0, 2), (1, 2)):
        peer.append(gdal_peer(fit, grid, pr, h0, h_range))
    t_peer, c_peer = time.perf_counter() - t0, time.process_time() - c0
    print(f"3. peer: GDAL RPC orthorectification at {h0:.0f} m + the same StereoSGBM, three pairs one "
          f"after the other: {t_peer:.1f} s wall, {c_peer:.1f} s CPU (ours at {dsm.posting_m:g} m, "
          f"fitted: {first[2]:.1f} s wall, {first[3]:.1f} s CPU, two Dask workers, fusion included)")
    agreement_rows(peer, "GDAL+SGBM")
    for p, q in zip(peer, pairs):
        dd = p.heights - q.heights
        print(f"   pair {p.pair}: peer − ours median {np.nanmedian(dd):+.2f} m, NMAD {nmad(dd):.2f} m; "
              f"fill {100 * np.isfinite(p.heights[dsm.seen]).mean():.1f} % vs {100 * np.isfinite(q.heights[dsm.seen]).mean():.1f} %")
    orientation(fit, dsm, FILES, points, h_range)
    if args.out:
        z = np.where(dsm.seen, dsm.heights, np.nan)
        shade = hillshade(z, dsm.posting_m)
        rgb = np.dstack([np.nan_to_num(shade, nan=0.0)] * 3) * 255
        void = dsm.seen & ~np.isfinite(dsm.heights)
        rgb[void] = (220, 40, 40)
        rgb[~dsm.seen] = 255
        cv2.imwrite(str(args.out), cv2.cvtColor(rgb.astype(np.uint8), cv2.COLOR_RGB2BGR),
                    [cv2.IMWRITE_JPEG_QUALITY, 85])
        print(f"5. shaded relief → {args.out} ({args.out.stat().st_size / 1024:.0f} kB)")
    other_pairs(dsm.posting_m)
    return 0


if __name__ == "__main__":
    with gdal_env():
        sys.exit(main())
