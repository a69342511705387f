"""Orthoimages: speed and memory on a full-size view beside GDAL's RPC warp on the same input
and machine, and the geometry against GDAL's and the truth.

``full --scene DIR``: a triplet from ``prismstation simulate`` (``benchmarks/simulate_full.py
--size 16000 --out DIR`` makes a full-size one; the project ``p.prismproj`` is made in DIR when
absent). Each step runs in a process of its own, which prints its wall time, CPU time and peak
resident memory:

1. ``prismstation ortho`` of N over ``--window`` (default the 14,000 × 16,000 pixels of a PRISM
   scene) onto the true DEM, through the fitted PRISM model, 2 workers: the COG with overviews;
2. an RPC fitted to that model over the window (a terrain-independent fit on a 3-D grid; its
   error printed) and written into a VRT of the image, so that GDAL and prismstation read the
   same input: GDAL's warp (``rasterio.warp.reproject`` with ``RPC_DEM``, bilinear, 2 threads,
   the same grid) into a tiled deflate GeoTIFF, then the same warp into an uncompressed one;
3. ``prismstation ortho`` of the VRT's project (RPC model, no bias) onto the same grid, and the
   two images compared (their shift by least squares over windows, the share of cells equal);
4. with ``--views N F B``: F and B too, each checked at the simulation's true points
   (``validate_ortho``: known ground and exact image positions) and the views' orthos against
   each other (their shift over windows).

``pleiades``: the real Pléiades triplet (``../shared/data/real/pleiades_triplet`` beside the
repository): tie points matched, a project of its images and RPCs, a DEM of the tie points'
heights (2 m, smoothed), then

* no bias: each image's ortho against GDAL's RPC transformer (``RPC_DEM``, exact) at every
  9th cell and against GDAL's warper (which interpolates its transformer to 0.125 px);
* biases fitted (the first image held fixed, the ties), the project's DSM at 1 m
  (``prismstation dsm``) and the three orthos on it: their shift against each other over
  64-cell windows where the DSM is good (all three pairs agree, matched).

Usage: ``python benchmarks/bench_ortho.py full --scene DIR [--window C R W H] [--views N F B]
[--keep]``; ``python benchmarks/bench_ortho.py pleiades [--out DIR]``.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PLEIADES = ROOT.parent / "shared" / "data" / "real" / "pleiades_triplet"
PRISM_WINDOW = (0, 0, 14000, 16000)

#: a measured step: run ``code`` in a new Python, which prints one JSON line of its figures
RUNNER = textwrap.dedent('''
    import json, resource, sys, time
    t0, c0 = time.perf_counter(), time.process_time()
    {code}
    u = resource.getrusage(resource.RUSAGE_SELF)
    print("@@" + json.dumps({{"wall_s": time.perf_counter() - t0, "cpu_s": u.ru_utime + u.ru_stime,
                             "peak_mb": u.ru_maxrss / 1024}}))
''')


def measured(code: str, label: str) -> dict:
    """Run ``code`` in a child Python and return (and print) its wall, CPU and peak memory."""
    out = subprocess.run([sys.executable, "-c", RUNNER.format(code=textwrap.indent(code, "")).strip()],
                         capture_output=True, text=True, cwd=ROOT)
    if out.returncode:
        raise SystemExit(f"{label} failed:\n{out.stdout}\n{out.stderr}")
    fig = json.loads(next(line[2:] for line in out.stdout.splitlines() if line.startswith("@@")))
    print(f"{label}: {fig['wall_s']:.1f} s wall, {fig['cpu_s']:.1f} s CPU, peak {fig['peak_mb']:.0f} MB")
    return fig


def ortho_cli(args) -> str:
    return f"from prismstation.cli import main\nassert main({list(map(str, args))!r}) == 0"


# ---------------------------------------------------------------------------- RPC of a model
def fit_rpc(ground_to_image, to_lonlat, window, h_range, image_to_ground, n: int = 31, levels: int = 7):
    """An RPC00B (:class:`prismstation.core.models.rpc.Rpc`) fitted to a model over an image window
    and a height range: ``image_to_ground(xy, h)`` places a ``n × n × levels`` grid on the
    ground, the 78 coefficients by linear least squares (denominators' constant 1); returns
    the RPC and its largest error (px) at the cells' centres between the grid's points."""
    from prismstation.core.models.rpc import Rpc, _terms

    c0, r0, w, h = window
    lo, hi = h_range

    def grid(k, m):
        u = (np.arange(k) + m) / (k - 1 + 2 * m)
        xs, ys = c0 + w * u, r0 + h * u
        hs = lo + (hi - lo) * (np.arange(levels) + m) / (levels - 1 + 2 * m)
        X, Y, H = np.meshgrid(xs, ys, hs, indexing="ij")
        xy = np.column_stack([X.ravel(), Y.ravel()])
        en = image_to_ground(xy, H.ravel())
        lon, lat = to_lonlat(en[:, 0], en[:, 1])
        back = ground_to_image(en, H.ravel())
        return np.asarray(lon), np.asarray(lat), H.ravel(), back
    lon, lat, hh, xy = grid(n, 0.0)
    off = dict(lon_off=lon.mean(), lat_off=lat.mean(), h_off=0.5 * (lo + hi),
               lon_scale=max(np.ptp(lon) / 2, 1e-6), lat_scale=max(np.ptp(lat) / 2, 1e-6),
               h_scale=max(0.5 * (hi - lo), 1.0), samp_off=c0 + w / 2 - 0.5, line_off=r0 + h / 2 - 0.5,
               samp_scale=w / 2, line_scale=h / 2)
    T = _terms((lon - off["lon_off"]) / off["lon_scale"], (lat - off["lat_off"]) / off["lat_scale"],
               (hh - off["h_off"]) / off["h_scale"])
    coef = {}
    for name, v, o, s in (("samp", xy[:, 0], off["samp_off"], off["samp_scale"]),
                          ("line", xy[:, 1], off["line_off"], off["line_scale"])):
        t = (v - 0.5 - o) / s
        A = np.column_stack([T.T, -t[:, None] * T[1:].T])
        sol = np.linalg.lstsq(A, t, rcond=None)[0]
        coef[f"{name}_num"], coef[f"{name}_den"] = sol[:20], np.r_[1.0, sol[20:]]
    rpc = Rpc(off["line_off"], off["samp_off"], off["lat_off"], off["lon_off"], off["h_off"],
              off["line_scale"], off["samp_scale"], off["lat_scale"], off["lon_scale"], off["h_scale"],
              coef["line_num"], coef["line_den"], coef["samp_num"], coef["samp_den"], source="fitted")
    lon, lat, hh, xy = grid(n - 1, 0.5)          # between the fit's points
    x, y = rpc.project(lon, lat, hh)
    return rpc, float(np.max(np.hypot(x - xy[:, 0], y - xy[:, 1])))


def write_rpc_vrt(path: Path, image: Path, rpc) -> None:
    """A VRT of band 1 of ``image`` carrying ``rpc`` in GDAL's RPC metadata (no geotransform)."""
    import rasterio
    with rasterio.open(image) as ds:
        w, h, dtype = ds.width, ds.height, ds.dtypes[0]
    gdal_type = {"uint8": "Byte", "uint16": "UInt16", "int16": "Int16", "float32": "Float32"}[dtype]
    md = "".join(f'    <MDI key="{k}">{v}</MDI>\n' for k, v in rpc.to_gdal_dict().items())
    path.write_text(f'<VRTDataset rasterXSize="{w}" rasterYSize="{h}">\n  <Metadata domain="RPC">\n{md}  </Metadata>\n'
                    f'  <VRTRasterBand dataType="{gdal_type}" band="1">\n    <SimpleSource>\n'
                    f'      <SourceFilename relativeToVRT="0">{image.resolve()}</SourceFilename>\n'
                    f'      <SourceBand>1</SourceBand>\n    </SimpleSource>\n  </VRTRasterBand>\n</VRTDataset>\n')


# ---------------------------------------------------------------------------- comparisons
def shift_lsq(a, b, r0, c0, n):
    """How far ``b``'s content lies from ``a``'s over a window (cells ``(dx, dy)``, b(x + s) =
    a(x)): least squares on the gradient, ``b`` resampled by cubic convolution."""
    from prismstation.core.surfaces.ortho import resample
    yy, xx = np.mgrid[r0:r0 + n, c0:c0 + n].astype(np.float32)
    ref = a[r0:r0 + n, c0:c0 + n]
    s = np.zeros(2)
    for _ in range(6):
        g = resample(b, xx + np.float32(s[0]), yy + np.float32(s[1]), "cubic")
        gy, gx = np.gradient(g)
        ok = np.isfinite(g) & np.isfinite(gx) & np.isfinite(gy) & np.isfinite(ref)
        if ok.sum() < 0.5 * n * n:
            return None
        A = np.column_stack([gx[ok], gy[ok], np.ones(ok.sum())])
        step = np.linalg.lstsq(A, (ref - g)[ok], rcond=None)[0][:2]
        s += step
        if np.abs(step).max() < 1e-4:
            break
    return s


def common(paths):
    """Orthos on one posting cut to their common grid (float32, NaN no data)."""
    import rasterio
    arrs = []
    for p in paths:
        with rasterio.open(p) as ds:
            arrs.append((np.where(ds.read_masks(1) > 0, ds.read(1).astype(np.float32), np.nan), ds.transform))
    g = arrs[0][1].a
    x0, y0 = max(t.c for _, t in arrs), min(t.f for _, t in arrs)
    x1, y1 = min(t.c + g * a.shape[1] for a, t in arrs), max(t.f - g * a.shape[0] for a, t in arrs)
    w, h = int(round((x1 - x0) / g)), int(round((y0 - y1) / g))
    out = []
    for a, t in arrs:
        c0, r0 = int(round((x0 - t.c) / g)), int(round((t.f - y0) / g))
        out.append(a[r0:r0 + h, c0:c0 + w])
    return out


def window_shifts(a, b, n=256, step=None, good=None):
    """Shifts of ``b`` against ``a`` over windows of ``n`` cells wholly valid (and ``good``)."""
    step = step or n
    out = []
    for r in range(0, a.shape[0] - n, step):
        for c in range(0, a.shape[1] - n, step):
            win = np.s_[r:r + n, c:c + n]
            if np.isfinite(a[win]).all() and np.isfinite(b[win]).all() and (good is None or good[win].mean() > 0.95):
                s = shift_lsq(a, b, r, c, n)
                if s is not None:
                    out.append(s)
    return np.array(out).reshape(-1, 2)


def describe_shifts(label, s):
    if not len(s):
        print(f"{label}: no window")
        return
    med = np.median(s, axis=0)
    nmad = 1.4826 * np.median(np.abs(s - med), axis=0)
    print(f"{label}: {len(s)} windows, median ({med[0]:+.3f}, {med[1]:+.3f}) px, NMAD ({nmad[0]:.3f}, {nmad[1]:.3f}), "
          f"largest |shift| {np.abs(s).max():.3f} px")


# ---------------------------------------------------------------------------- full size
def run_full(args) -> None:
    import rasterio

    from prismstation.io.project import load_project
    from prismstation.ops.fit import solve_project
    from prismstation.ops.project import create
    d = Path(args.scene)
    out = Path(args.out or tempfile.mkdtemp(prefix="bench_ortho_"))
    out.mkdir(parents=True, exist_ok=True)
    if not (d / "p.prismproj").exists():
        create(d / "p.prismproj", d / "scene.json", d / "points.csv", d / "measurements.csv")
    win = tuple(args.window)
    dem = d / "truth_dem.tif"
    print(f"scene {d}, N window {win}, output in {out}")
    ours = out / "ours_N.tif"
    measured(ortho_cli(["ortho", d / "p.prismproj", "-o", ours, "--view", "N", "--dem", dem, "--dem-heights",
                        "ellipsoidal", "--window", *win, "--workers", args.workers]),
             f"prismstation ortho, PRISM model, N {win[2]} × {win[3]} px → COG with overviews")
    with rasterio.open(ours) as ds:
        T, shape, crs = ds.transform, (ds.height, ds.width), ds.crs
        print(f"  grid {shape[1]} × {shape[0]} cells at {T.a:g} m, {float(ds.tags()['ORTHO_VALID_PERCENT']):.1f} % with data, "
              f"{ours.stat().st_size / 1e6:.0f} MB")
    # an RPC of the fitted model over the window: GDAL's input
    p = load_project(d / "p.prismproj")
    sol = solve_project(p)
    with rasterio.open(dem) as ds:
        z = ds.read(1, masked=True)
        h_range = (float(z.min()) - 20.0, float(z.max()) + 20.0)
    from prismstation.io.rpc_scene import LonLatProjection
    proj = LonLatProjection(p.scene.crs)
    vrts = {}
    for v in ("N", "F"):            # an RPC project holds two images or more: N's and F's
        rpc, err = fit_rpc(lambda en, h, v=v: sol.ground_to_image(v, en, h), proj.to_lonlat, win, h_range,
                           lambda xy, h, v=v: sol.image_to_ground(v, xy, h))
        print(f"RPC fitted to the PRISM model of {v} over the window, heights {h_range[0]:.0f}–{h_range[1]:.0f} m: "
              f"largest error {err:.4f} px between its points")
        vrts[v] = out / f"{v}_rpc.vrt"
        write_rpc_vrt(vrts[v], Path(sol.scene.views[v].image), rpc)
    vrt = vrts["N"]
    grid = dict(crs=crs.to_wkt(), transform=tuple(T)[:6], shape=shape)
    for label, opts in (("tiled deflate GeoTIFF", "compress='deflate', tiled=True, blockxsize=256, blockysize=256"),
                        ("tiled uncompressed GeoTIFF", "tiled=True, blockxsize=256, blockysize=256")):
        target = out / f"gdal_{'deflate' if 'deflate' in opts else 'plain'}.tif"
        code = textwrap.dedent(f'''
            import rasterio
            from rasterio.transform import Affine
            from rasterio.warp import reproject, Resampling
            g = {grid!r}
            with rasterio.open({str(vrt)!r}) as src, rasterio.open({str(target)!r}, "w", driver="GTiff",
                    width=g["shape"][1], height=g["shape"][0], count=1, dtype=src.dtypes[0], crs=g["crs"],
                    transform=Affine(*g["transform"]), nodata=0, {opts}) as dst:
                reproject(rasterio.band(src, 1), rasterio.band(dst, 1), rpcs=src.rpcs, src_crs="EPSG:4326",
                          dst_crs=g["crs"], dst_transform=Affine(*g["transform"]), dst_nodata=0,
                          resampling=Resampling.bilinear, RPC_DEM={str(dem)!r}, num_threads=2,
                          warp_mem_limit=256)
        ''')
        measured(code, f"GDAL RPC warp (RPC_DEM, bilinear, 2 threads) → {label}")
    rp = out / "rpc.prismproj"
    if not rp.exists():
        from prismstation.cli import main
        assert main(["new", str(rp), "--images", str(vrts["N"]), str(vrts["F"]), "--no-ties"]) == 0
    ours_rpc = out / "ours_rpc.tif"
    measured(ortho_cli(["ortho", rp, "-o", ours_rpc, "--view", "N_rpc", "--bias", "none", "--dem", dem,
                        "--dem-heights", "ellipsoidal", "--posting", T.a, "--window", *win, "--workers", args.workers]),
             "prismstation ortho, the same RPC input (no bias) → COG with overviews")
    a, b = common([ours_rpc, out / "gdal_plain.tif"])
    both = np.isfinite(a) & np.isfinite(b) & (b > 0)
    print(f"  prismstation − GDAL on the RPC input: {100 * np.mean(a[both] == b[both]):.1f} % of {both.sum():,} cells "
          f"equal, {100 * np.mean(np.abs(a[both] - b[both]) <= 1):.2f} % within 1 DN")
    describe_shifts("  shift of GDAL's ortho against prismstation's (512-cell windows, every 4th)",
                    window_shifts(a, np.where(b > 0, b, np.nan), n=512, step=2048))
    if len(args.views) > 1:
        run_views(args, d, out, sol, p)
    if not args.keep and not args.out:
        import shutil
        shutil.rmtree(out, ignore_errors=True)


def run_views(args, d, out, sol, p) -> None:
    from prismstation.ops.ortho_validate import validate_ortho
    win = tuple(args.window)
    paths = []
    for v in args.views:
        path = out / f"ours_{v}.tif"
        if not path.exists():
            measured(ortho_cli(["ortho", d / "p.prismproj", "-o", path, "--view", v, "--dem", d / "truth_dem.tif",
                                "--dem-heights", "ellipsoidal", "--window", *win, "--workers", args.workers]),
                     f"prismstation ortho of {v}")
        paths.append(path)
    truth = json.loads((d / "truth.json").read_text())["points"]
    for v, path in zip(args.views, paths):
        pts = [(t["id"], t["kind"], (t["E"], t["N"], t["h"]), tuple(t["image"][v])) for t in truth
               if t["kind"] == "ICP"]
        val = validate_ortho(sol, p, path, points=pts)
        s = val.stats.get("ICP", {})
        print(f"view {v} against the truth at {s.get('n', 0)} ICPs: RMSE {s.get('rmse_m', float('nan')):.2f} m "
              f"(E {s.get('rmse_e_m', float('nan')):.2f}, N {s.get('rmse_n_m', float('nan')):.2f}); expected "
              f"{val.expected_sigma_m:.2f} m; not found {s.get('not_found', 0)}")
    arrs = common(paths)
    for i in range(len(arrs)):
        for j in range(i + 1, len(arrs)):
            describe_shifts(f"{args.views[j]} against {args.views[i]} (512-cell windows)",
                            window_shifts(arrs[i], arrs[j], n=512, step=1536))


# ---------------------------------------------------------------------------- Pléiades
def run_pleiades(args) -> None:
    import csv
    from dataclasses import replace

    import rasterio
    from pyproj import Transformer
    from rasterio.transform import RPCTransformer
    from rasterio.warp import Resampling, reproject
    from scipy import ndimage
    from scipy.interpolate import griddata

    from prismstation.cli import main
    from prismstation.core.matching.rpc_tiepoints import match_tie_points
    from prismstation.io.dem import write_dem
    from prismstation.io.project import load_project, save_project
    from prismstation.ops.fit import solve_project
    from prismstation.ops.ortho_tiles import Heights
    from prismstation.core.surfaces import ortho

    if not PLEIADES.is_dir():
        raise SystemExit(f"{PLEIADES} not found")
    d = Path(args.out or tempfile.mkdtemp(prefix="bench_ortho_ple_"))
    d.mkdir(parents=True, exist_ok=True)
    images = [PLEIADES / f"img_0{i}.tif" for i in (1, 2, 3)]
    names = [f.stem for f in images]
    if not (d / "block.prismproj").exists():
        arrays = [rasterio.open(f).read(1) for f in images]
        tp = match_tie_points(arrays, cell=48)
        with open(d / "ties.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["id", "view", "x", "y", "sigma_px"])
            for j, i, xy, s in zip(tp.point, tp.image, tp.xy, tp.sigma):
                w.writerow([f"T{j:04d}", names[i], float(xy[0]), float(xy[1]), float(s[0])])
        assert main(["new", str(d / "block.prismproj"), "--images", *map(str, images), "--no-ties", "--measurements",
                     str(d / "ties.csv")]) == 0
        assert main(["fit", str(d / "block.prismproj"), "--bias", "none", "--json", str(d / "before.json")]) == 0
        r = json.loads((d / "before.json").read_text())
        pts = [q for q in r["points"] if q.get("h_est") is not None]
        en = np.array([(q["E_est"], q["N_est"]) for q in pts])
        h = np.array([q["h_est"] for q in pts])
        x0, y1, g = en.min(0)[0] - 300, en.max(0)[1] + 300, 2.0
        nx, ny = int((en[:, 0].max() + 300 - x0) / g), int((y1 - en[:, 1].min() + 300) / g)
        E, N = np.meshgrid(x0 + g / 2 + g * np.arange(nx), y1 - g / 2 - g * np.arange(ny))
        z = griddata(en, h, (E, N), method="linear")
        z = np.where(np.isfinite(z), z, griddata(en, h, (E, N), method="nearest"))
        write_dem(d / "dem.tif", ndimage.gaussian_filter(z, 3), r["crs"], (g, 0, x0, 0, -g, y1))
        p = load_project(d / "block.prismproj")
        p.set_settings(replace(p.settings, fixed_view=names[0], bias_model="shift"))
        save_project(p, d / "block.prismproj")
    print(f"Pléiades triplet, project and DEM in {d}")
    # no bias: against GDAL
    assert main(["ortho", str(d / "block.prismproj"), "-o", str(d / "nb.tif"), "--view", "all", "--dem",
                 str(d / "dem.tif"), "--dem-heights", "ellipsoidal", "--bias", "none"]) == 0
    p = load_project(d / "block.prismproj")
    p.set_settings(replace(p.settings, bias_model="none", fixed_view=None))
    sol = solve_project(p)
    for name, image in zip(names, images):
        path = d / f"nb_{name}.tif"
        with rasterio.open(path) as o:
            T, shape, crs = o.transform, (o.height, o.width), o.crs
            ours, valid = o.read(1).astype(np.float32), o.read_masks(1) > 0
        hg = Heights(p.scene.crs, "ellipsoidal", str(d / "dem.tif")).on_grid(tuple(T)[:6], shape)
        lat = ortho.fit_lattice(lambda en, hh: sol.model.ground_to_image(name, en, hh), tuple(T)[:6], shape,
                                float(np.nanmin(hg)), float(np.nanmax(hg)))
        mx, my = ortho.positions(lat, hg)
        rows, cols = np.mgrid[0:shape[0]:9, 0:shape[1]:9]
        E, N = T.c + T.a * (cols + 0.5), T.f + T.e * (rows + 0.5)
        lon, la = Transformer.from_crs(crs.to_wkt(), "EPSG:4326", always_xy=True).transform(E, N)
        with rasterio.open(image) as src:
            rpcs, img, (H, W) = src.rpcs, src.read(1).astype(np.float32), src.shape
        with RPCTransformer(rpcs, RPC_DEM=str(d / "dem.tif")) as rt:
            r, c = (np.asarray(v) for v in rt.rowcol(lon.ravel(), la.ravel(), op=lambda v: v))
        inside = (c > 1) & (c < W - 1) & (r > 1) & (r < H - 1)
        e = np.hypot((mx + 0.5)[rows, cols].ravel() - c, (my + 0.5)[rows, cols].ravel() - r)[inside]
        print(f"{name}, no bias: positions − GDAL's RPC transformer (RPC_DEM) at {inside.sum()} cells: "
              f"max {np.nanmax(e):.5f} px, RMS {np.sqrt(np.nanmean(e ** 2)):.5f} px")
        # the warper: the positions through ramps, the image itself
        yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
        gdal = {}
        for key, src in (("x", xx + 0.5), ("y", yy + 0.5), ("image", img)):
            dst = np.full(shape, np.nan, np.float32)
            reproject(src, dst, rpcs=rpcs, src_crs="EPSG:4326", dst_crs=crs, dst_transform=T, src_nodata=np.nan,
                      dst_nodata=np.nan, resampling=Resampling.bilinear, RPC_DEM=str(d / "dem.tif"))
            gdal[key] = dst
        ok = np.isfinite(gdal["x"]) & np.isfinite(mx)
        e = np.hypot(mx + 0.5 - gdal["x"], my + 0.5 - gdal["y"])[ok]
        print(f"  − GDAL's warper (its transformer interpolated to 0.125 px) at {ok.sum()} cells: median "
              f"{np.median(e):.4f}, 99.9 % {np.percentile(e, 99.9):.4f}, max {e.max():.4f} px, RMS "
              f"{np.sqrt(np.mean(e ** 2)):.4f} px")
        both = valid & np.isfinite(gdal["image"])
        s = window_shifts(np.where(valid, ours, np.nan), np.where(both, gdal["image"], np.nan), n=256, step=128)
        describe_shifts("  shift of GDAL's ortho against prismstation's (256-cell windows)", s)
    # biases fitted, on the project's DSM
    if not (d / "dsm.tif").exists():
        assert main(["dsm", str(d / "block.prismproj"), "-o", str(d / "dsm.tif"), "--posting", "1"]) == 0
    assert main(["ortho", str(d / "block.prismproj"), "-o", str(d / "fb.tif"), "--view", "all", "--dem",
                 str(d / "dsm.tif")]) == 0
    arrs = common([d / f"fb_{n}.tif" for n in names])
    with rasterio.open(d / f"fb_{names[0]}.tif") as ds:
        T, shape = ds.transform, arrs[0].shape
    with rasterio.open(d / "dsm.tif") as ds:
        q, m = (np.zeros(shape, np.float32) for _ in range(2))
        for band, arr in ((3, q), (2, m)):
            reproject(rasterio.band(ds, band), arr, dst_transform=T, dst_crs=ds.crs, resampling=Resampling.nearest)
    good = (q == 3) & (m == 1)
    print(f"biases fitted ({names[0]} held fixed), orthos on the project's 1 m DSM; DSM good on {100 * good.mean():.0f} %:")
    for i in range(3):
        for j in range(i + 1, 3):
            describe_shifts(f"  {names[j]} against {names[i]} (64-cell windows where the DSM is good)",
                            window_shifts(arrs[i], arrs[j], n=64, good=good))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="what", required=True)
    f = sub.add_parser("full")
    f.add_argument("--scene", required=True)
    f.add_argument("--window", nargs=4, type=int, default=PRISM_WINDOW)
    f.add_argument("--views", nargs="+", default=["N"])
    f.add_argument("--workers", type=int, default=2)
    f.add_argument("--out")
    f.add_argument("--keep", action="store_true")
    p = sub.add_parser("pleiades")
    p.add_argument("--out")
    args = ap.parse_args(argv)
    (run_full if args.what == "full" else run_pleiades)(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
