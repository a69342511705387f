"""The RPC engine on real imagery: reader agreement with GDAL, tie points, the bias fit, and
known offsets found back.

Data: ``../shared/data/real`` (the Pléiades triplet over Aubagne, the Giza pair with OSSIM
``.geom`` RPCs, the Réunion pair, and the RPC format samples). Printed:

1. per sample file, the largest difference between our RPC model and GDAL's RPC transformer
   (rasterio) — ground → image, and image → ground → image through the other — in pixels;
2. per block, the automatic tie points (SIFT + NCC/LSM), the RMS of their image residuals
   before (intersection with the raw RPCs) and after the shift-bias fit with image 1 held fixed
   and reference heights (the raw RPCs' own intersection + 2 m noise, σ 2 m: no DEM covering
   these crops is among the samples), σ0 and each bias with its σ;
3. known answer: the last image's RPC line (sample) offset moved by ``d`` px, the fit on each
   of three disjoint thirds of the tie points; recovered − (unperturbed full fit − d) against
   the formal σ;
4. the same fit by scipy's ``least_squares`` on the same problem (the peer), its time and the
   largest difference of the biases.

Run: ``.venv/bin/python benchmarks/bench_rpc_bias.py``. Times are wall-clock on a shared,
busy 2-core machine: indicative only.
"""
from __future__ import annotations

import shutil
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import rasterio
from rasterio.enums import TransformDirection
from rasterio.rpc import RPC
from rasterio.transform import RPCTransformer
from scipy.optimize import least_squares

from prismstation.core.models.rpc_adjust import adjust, adjust_snooping
from prismstation.core.models.rpc_bias import intersect_points
from prismstation.core.matching.rpc_tiepoints import match_tie_points
from prismstation.io.rpc import read_rpc, read_rpc_file

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real"
PHR = "PHR1B_P_201709281038393_SEN_PRG_FC_178609-001"
SETS = {"triplet": [f"pleiades_triplet/img_0{i}.tif" for i in (1, 2, 3)],
        "gizeh": ["pleiades_pair_gizeh/img1.tif", "pleiades_pair_gizeh/img2.tif"],
        "reunion": ["pleiades_pair_reunion/img_01.tif", "pleiades_pair_reunion/img_02.tif"]}
H_SIGMA = 2.0


def gdal_agreement(rpc, rpcs, shape=None, dx=0.0, dy=0.0, n=2000):
    t = RPCTransformer(rpcs, RPC_PIXEL_ERROR_THRESHOLD=1e-7, RPC_MAX_ITERATIONS=100)
    rng = np.random.default_rng(0)
    if shape is None:
        x = rpc.samp_off + 0.5 + rng.uniform(-0.9, 0.9, n) * rpc.samp_scale
        y = rpc.line_off + 0.5 + rng.uniform(-0.9, 0.9, n) * rpc.line_scale
    else:
        x, y = rng.uniform(0, shape[1], n), rng.uniform(0, shape[0], n)
    h = rpc.h_off + rng.uniform(-0.9, 0.9, n) * rpc.h_scale
    lon, lat = rpc.localize(x, y, h)
    gx, gy = t._transform(lon, lat, h, transform_direction=TransformDirection.reverse)
    mx, my = rpc.project(lon, lat, h)
    g2i = max(np.abs(np.asarray(gx) + dx - mx).max(), np.abs(np.asarray(gy) + dy - my).max())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        glon, glat = t._transform(x - dx, y - dy, h, transform_direction=TransformDirection.forward)
    bx, by = rpc.project(np.asarray(glon), np.asarray(glat), h)
    a = max(np.abs(bx - x).max(), np.abs(by - y).max())
    b = max(np.abs(np.asarray(gx) + dx - x).max(), np.abs(np.asarray(gy) + dy - y).max())
    return g2i, max(a, b)


def readers():
    print("1. RPC model against GDAL's RPC transformer (max |Δ| px over 2,000 points, heights over "
          "the RPC's range)")
    print(f"   {'sample':52s} {'reader':22s} {'ground→image':>13s} {'img→gnd→img':>12s}")
    rows = []
    for name in SETS["triplet"] + SETS["reunion"] + ["rpc_formats/wv3_20.NTF"]:
        with rasterio.open(DATA / name) as ds:
            rows.append((name, "tags/NITF via rasterio", read_rpc(DATA / name), ds.rpcs, ds.shape, 0, 0))
    with rasterio.open(DATA / "rpc_formats" / f"{PHR}.tif") as ds:
        for side, reader in ((f"RPC_{PHR}.XML", "DIMAP XML"), (f"{PHR}.geom", "OSSIM geom")):
            rows.append((f"rpc_formats/{side}"[:52], reader,
                         read_rpc_file(DATA / "rpc_formats" / side), ds.rpcs, ds.shape, 0, 0))
    for img, org in (("img1", (20500, 5000)), ("img2", (20501, 5476))):
        full = read_rpc_file(DATA / "pleiades_pair_gizeh" / f"{img}.geom")
        with rasterio.open(DATA / "pleiades_pair_gizeh" / f"{img}.tif") as ds:
            shape = ds.shape
        rows.append((f"pleiades_pair_gizeh/{img}.geom (crop)", "OSSIM geom + offset",
                     read_rpc(DATA / "pleiades_pair_gizeh" / f"{img}.tif"),
                     RPC.from_gdal(full.to_gdal_dict()), shape, -org[0], -org[1]))
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        shutil.copy(DATA / "rpc_formats" / "RPC-md_alos.txt", d / "RPC-md_alos.txt")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with rasterio.open(d / "IMG-01-md_alos.tif", "w", driver="GTiff", width=8, height=8,
                               count=1, dtype="uint8") as ds:
                ds.write(np.zeros((1, 8, 8), np.uint8))
        (d / "HDR-md_alos.txt").write_text("")
        with rasterio.open(d / "IMG-01-md_alos.tif") as ds:
            rows.append(("rpc_formats/RPC-md_alos.txt", "JAXA fixed-width",
                         read_rpc_file(DATA / "rpc_formats" / "RPC-md_alos.txt"), ds.rpcs, None, 0, 0))
    for name, reader, rpc, rpcs, shape, dx, dy in rows:
        g2i, rt = gdal_agreement(rpc, rpcs, shape, dx, dy)
        print(f"   {name:52s} {reader:22s} {g2i:13.1e} {rt:12.1e}")


def block(name, files):
    rpcs = [read_rpc(DATA / f) for f in files]
    images = []
    for f in files:
        with rasterio.open(DATA / f) as ds:
            images.append(ds.read(1))
    t0 = time.perf_counter()
    tp = match_tie_points(images)
    t_match = time.perf_counter() - t0
    before = intersect_points(rpcs, tp.point, tp.image, tp.xy, tp.sigma, tp.n_points)
    href = before.h + np.random.default_rng(0).normal(0, H_SIGMA, tp.n_points)
    t0 = time.perf_counter()
    fit, kept = adjust_snooping(rpcs, tp.point, tp.image, tp.xy, tp.sigma, bias="shift",
                                height_point=np.arange(tp.n_points), height=href,
                                height_sigma=H_SIGMA)
    t_fit = time.perf_counter() - t0
    print(f"\n2. {name}: {tp.n_points} tie points ({', '.join(str(int(c)) for c in np.bincount(tp.image))} "
          f"observations per image; median σ {np.median(tp.sigma):.2f} px), matched in {t_match:.1f} s; "
          f"fit with data snooping {t_fit * 1000:.0f} ms, {int((~kept).sum())} points rejected (|t| > 4)")
    print(f"   σ0 {fit.sigma0:.3f}, dof {fit.dof}, heights {before.h.min():.0f}–{before.h.max():.0f} m")
    for k in range(len(files)):
        r0 = np.sqrt(np.mean(before.residuals[tp.image == k] ** 2, axis=0))
        r1 = fit.rms_by_image()[k]
        bias = ("held fixed" if k in fit.fixed else
                f"shift x {fit.models[k].params[0]:+.3f} ± {fit.bias_std(k)[0]:.3f}, "
                f"y {fit.models[k].params[1]:+.3f} ± {fit.bias_std(k)[1]:.3f} px")
        print(f"   image {k + 1}: RMS before x {r0[0]:.3f} y {r0[1]:.3f} px, after x {r1[0]:.3f} "
              f"y {r1[1]:.3f} px; {bias}")
    # known answer
    k = len(files) - 1
    z = []
    print(f"3. {name}: image {k + 1}'s offset moved; thirds of the tie points (recovered − true, σ) px")
    points = np.flatnonzero(kept)
    parts = np.array_split(np.random.default_rng(1).permutation(points), 3)
    for c, comp in ((1, "line"), (0, "sample")):
        for d in (30.0, -45.0, 60.0):
            moved = list(rpcs)
            moved[k] = rpcs[k].shifted(**({"dy": d} if c else {"dx": d}))
            truth = fit.models[k].params[c] - d
            out = []
            for part in parts:
                part = np.sort(part)
                sel = np.isin(tp.point, part)
                new = np.full(tp.n_points, -1)
                new[part] = np.arange(len(part))
                res = adjust(moved, new[tp.point[sel]], tp.image[sel], tp.xy[sel], tp.sigma[sel],
                             bias="shift", n_points=len(part), height_point=np.arange(len(part)),
                             height=href[part], height_sigma=H_SIGMA,
                             centres=[(m.x0, m.y0) for m in fit.models])
                err, s = res.models[k].params[c] - truth, res.bias_std(k)[c]
                z.append(err / s)
                out.append(f"{res.models[k].params[c]:+8.3f} ({err:+.3f}, σ {s:.3f})")
            print(f"   {comp:6s} {d:+5.0f}: true {truth:+8.3f}; " + "; ".join(out))
    z = np.array(z)
    print(f"   RMS of (recovered − true)/σ over {z.size} fits: {np.sqrt(np.mean(z * z)):.2f}; "
          f"max |z| {np.abs(z).max():.2f}")
    return rpcs, tp, kept, href, fit


def peer(rpcs, tp, kept, href, fit):
    """scipy's least_squares on the same problem (shift biases, image 1 fixed, heights)."""
    pts = np.flatnonzero(kept)
    sel = np.isin(tp.point, pts)
    new = np.full(tp.n_points, -1)
    new[pts] = np.arange(len(pts))
    P, I, XY, S = new[tp.point[sel]], tp.image[sel], tp.xy[sel], tp.sigma[sel]
    n, ni = len(pts), len(rpcs)
    start = np.column_stack([fit.lon, fit.lat, fit.h]) + np.array([1e-6, 1e-6, 1.0])
    t0 = time.perf_counter()
    ours = adjust(rpcs, P, I, XY, S, bias="shift", n_points=n, height_point=np.arange(n),
                  height=href[pts], height_sigma=H_SIGMA,
                  centres=[(m.x0, m.y0) for m in fit.models])
    t_ours = time.perf_counter() - t0

    def res(zz):
        b, g = zz[:2 * (ni - 1)].reshape(ni - 1, 2), zz[2 * (ni - 1):].reshape(n, 3)
        out = []
        for k in range(ni):
            s = I == k
            x, y = rpcs[k].project(g[P[s], 0], g[P[s], 1], g[P[s], 2])
            d = np.zeros(2) if k == 0 else b[k - 1]
            out += [(XY[s, 0] - d[0] - x) / S[s, 0], (XY[s, 1] - d[1] - y) / S[s, 1]]
        out.append((href[pts] - g[:, 2]) / H_SIGMA)
        return np.concatenate(out)

    # the Jacobian's sparsity (each residual sees one image's bias and one point), so that
    # scipy's finite differences take a few dozen evaluations, not one per unknown
    from scipy.sparse import lil_matrix
    nb = 2 * (ni - 1)
    rows = []
    for k in range(ni):
        s = np.flatnonzero(I == k)
        rows += [(k, P[s]), (k, P[s])]
    sp = lil_matrix((sum(len(r[1]) for r in rows) + n, nb + 3 * n), dtype=int)
    r0 = 0
    for comp, (k, pp) in enumerate(rows):
        i = r0 + np.arange(len(pp))
        if k:
            sp[i, 2 * (k - 1) + comp % 2] = 1
        for c in range(3):
            sp[i, nb + 3 * pp + c] = 1
        r0 += len(pp)
    sp[r0 + np.arange(n), nb + 3 * np.arange(n) + 2] = 1
    t0 = time.perf_counter()
    zz = least_squares(res, np.concatenate([np.zeros(nb), start.ravel()]), jac_sparsity=sp,
                       x_scale="jac", xtol=1e-12, ftol=1e-12, method="trf").x
    t_peer = time.perf_counter() - t0
    diff = max(np.abs(ours.models[k].params - zz[2 * (k - 1):2 * k]).max() for k in range(1, ni))
    print(f"\n4. triplet fit, {n} points: ours {t_ours * 1000:.0f} ms, scipy least_squares "
          f"{t_peer * 1000:.0f} ms; largest bias difference {diff:.1e} px")


def main() -> int:
    if not DATA.is_dir():
        print(f"no real data at {DATA}")
        return 1
    readers()
    first = None
    for name, files in SETS.items():
        out = block(name, files)
        first = first or out
    peer(*first)
    return 0


if __name__ == "__main__":
    sys.exit(main())
