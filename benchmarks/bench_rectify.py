"""Single-image figures: transform noise floor, GDAL agreement, warp speed, deblocking, DSM validation.

Run: ``.venv/bin/python benchmarks/bench_rectify.py`` (uses ../shared/data/real when present).
"""
from __future__ import annotations

import tempfile
import time
import warnings
from pathlib import Path

import cv2
import numpy as np
import rasterio

from prismstation.core.matching.deblock import blockiness, deblock
from prismstation.core.models.rectify import KINDS, fit_transform, n_params
from prismstation.ops.validate import validate_dsm_files
from prismstation.ops.rectify import rectify_raster

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"


def noise_floor(sigma=1.0, npts=30, trials=500):
    rng = np.random.default_rng(0)
    src = rng.uniform(0, 10000, (npts, 2))
    truth = src @ np.array([[2.5, 0.1], [0.05, -2.45]]).T + [512000.0, 4601000.0]
    print(f"noise floor: sigma = {sigma} m per coordinate, {npts} GCPs, {trials} trials")
    print(f"{'kind':<11}{'u':>3}{'GCP ideal':>11}{'GCP':>9}{'ICP ideal':>11}{'ICP':>9}{'ms/fit':>9}")
    for kind in KINDS:
        u, n = n_params(kind), 2 * npts
        g, i = [], []
        t0 = time.perf_counter()
        for _ in range(trials):
            t = fit_transform(kind, src, truth + rng.normal(0, sigma, truth.shape))
            g.append(t.rmse ** 2 / 2)
            i.append(np.mean(t.residuals(src, truth + rng.normal(0, sigma, truth.shape)) ** 2))
        ms = (time.perf_counter() - t0) / trials * 1000
        print(f"{kind:<11}{u:>3}{sigma * np.sqrt(1 - u / n):>11.4f}{np.sqrt(np.mean(g)):>9.4f}"
              f"{sigma * np.sqrt(1 + u / n):>11.4f}{np.sqrt(np.mean(i)):>9.4f}{ms:>9.2f}")


def gdal_agreement():
    from rasterio.control import GroundControlPoint
    from rasterio.transform import GCPTransformer

    rng = np.random.default_rng(1)
    for npts, kind in ((5, "affine"), (8, "poly2"), (50, "poly2")):
        src = rng.uniform(0, 8000, (npts, 2))
        dst = (src @ np.array([[2.5, 0.1], [0.05, -2.45]]).T + [512000.0, 4601000.0]
               + 1e-5 * src[:, :1] ** 2 + rng.normal(0, 2, (npts, 2)))
        q = rng.uniform(0, 8000, (1000, 2))
        gcps = [GroundControlPoint(row=y, col=x, x=X, y=Y) for (x, y), (X, Y) in zip(src, dst)]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with GCPTransformer(gcps) as g:
                xs, ys = g.xy(q[:, 1], q[:, 0], offset="ul")
        d = np.abs(np.column_stack([xs, ys]) - fit_transform(kind, src, dst)(q)).max()
        print(f"GDAL GCP transformer vs {kind:<6} ({npts:>2} GCPs): max |difference| {d:.2e} m")


def warp_speed(size=4000):
    rng = np.random.default_rng(2)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "img.tif"
        img = cv2.GaussianBlur((rng.random((size, size)) * 255).astype(np.uint8), (0, 0), 2)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with rasterio.open(path, "w", driver="GTiff", width=size, height=size, count=1,
                               dtype="uint8", tiled=True) as ds:
                ds.write(img, 1)
        src = rng.uniform(0, size, (20, 2))
        dst = src @ np.array([[2.5, 0.3], [0.2, -2.5]]).T + [512000.0, 4601000.0] + 2e-6 * src ** 2
        for kind in ("affine", "projective", "poly3"):
            t = fit_transform(kind, src, dst)
            t0 = time.perf_counter()
            r = rectify_raster(path, t, Path(tmp) / "out.tif", points_crs="EPSG:32629")
            dt = time.perf_counter() - t0
            print(f"rectify {size}x{size} through {kind:<10}: {r.width}x{r.height} out, {dt:.2f} s "
                  f"({r.width * r.height / dt / 1e6:.1f} Mcell/s)")


def deblocking():
    if not (DATA / "pleiades_triplet").is_dir():
        print("deblocking: no shared data")
        return
    with rasterio.open(DATA / "pleiades_triplet" / "img_01.tif") as ds:
        a = ds.read(1).astype(float)
    lo, hi = np.percentile(a, [1, 99])
    real = np.clip((a - lo) / (hi - lo) * 255, 0, 255).astype(np.uint8)
    smooth = cv2.GaussianBlur(real, (0, 0), 2)
    print(f"{'image':<8}{'q':>4}{'block jpg':>11}{'block out':>11}{'rmse jpg':>10}{'rmse out':>10}{'ms':>7}")
    for name, img in (("real", real), ("smooth", smooth)):
        for q in (10, 20, 40):
            ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, q])
            j = cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)
            t0 = time.perf_counter()
            o = deblock(j)
            ms = (time.perf_counter() - t0) * 1000
            e = lambda x: np.sqrt(np.mean((x.astype(float) - img) ** 2))  # noqa: E731
            print(f"{name:<8}{q:>4}{blockiness(j):>11.3f}{blockiness(o):>11.3f}{e(j):>10.3f}"
                  f"{e(o):>10.3f}{ms:>7.0f}")


def dsm():
    if not (DATA / "srtm").is_dir():
        print("DSM validation: no shared data")
        return
    t0 = time.perf_counter()
    v, _ = validate_dsm_files(DATA / "srtm" / "N44E005_UTM.tif", DATA / "srtm" / "N44E005.hgt")
    o = v.overall
    print(f"SRTM UTM tile vs .hgt (EPSG:4326) on the UTM grid: n={o.count} bias={o.bias:.4f} "
          f"sd={o.sd:.4f} rmse={o.rmse:.4f} nmad={o.nmad:.4f} m, {time.perf_counter() - t0:.2f} s")


if __name__ == "__main__":
    noise_floor()
    gdal_agreement()
    warp_speed()
    deblocking()
    dsm()
