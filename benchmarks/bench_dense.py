"""Dense parallax: ours (core.dense.parallax_map) vs OpenCV StereoSGBM on the same synthetic pair.

The pair: real Pléiades texture (../shared/data/real/pleiades_triplet/img_01.tif, 1024²,
slightly blurred) seen as the N image; F and B rendered from it (cubic spline) so that a ground
point at N position pN appears at pN ± py(pN)/2 along x, with a known smooth parallax field
py (two hills and a valley, −9 … +14 px, plus a tilt); both made 8-bit with noise σ 1 DN.
Errors against the known field; ours is sampled at N positions, SGBM (disparity on the F grid)
at F positions, each against the truth at its own positions.

Throughput is the window's megapixels per wall-clock second (CPU seconds shown beside: the
machine may be shared). Run: ``.venv/bin/python benchmarks/bench_dense.py``
"""
from __future__ import annotations

import time
from pathlib import Path

import cv2
import numpy as np
import rasterio
from scipy import ndimage

from prismstation.core.dense import parallax_map

IMG = Path(__file__).resolve().parents[2] / "shared" / "data" / "real" / "pleiades_triplet" / "img_01.tif"
MARGIN = 40


def py_true(x, y):
    return (12 * np.exp(-((x - 400) ** 2 + (y - 450) ** 2) / (2 * 150 ** 2))
            + 8 * np.exp(-((x - 780) ** 2 + (y - 250) ** 2) / (2 * 90 ** 2))
            - 9 * np.exp(-((x - 300) ** 2 + (y - 850) ** 2) / (2 * 120 ** 2)) + 0.002 * x)


def n_position(qx, qy, sign):
    """N position of the ground point seen at view coords (qx, qy) of F (sign +1) or B (−1)."""
    px = qx.copy()
    for _ in range(15):
        px = qx - sign * py_true(px, qy) / 2
    return px, qy


def make_pair(rng):
    with rasterio.open(IMG) as ds:
        t = ds.read(1).astype(float)
    t = ndimage.gaussian_filter(t, 0.7)
    coeffs = ndimage.spline_filter(t, 3)
    jj, ii = np.mgrid[0:t.shape[0], 0:t.shape[1]].astype(float)
    lo, hi = np.percentile(t, [0.5, 99.5])
    views = []
    for sign in (+1, -1):
        px, py = n_position(ii + 0.5, jj + 0.5, sign)
        v = ndimage.map_coordinates(coeffs, [py - 0.5, px - 0.5], order=3, prefilter=False,
                                    mode="reflect")
        v = (v - lo) / (hi - lo) * 255 + rng.normal(0, 1.0, v.shape)
        views.append(np.clip(np.rint(v), 0, 255).astype(np.uint8))
    return views


def report(name, est, truth, seconds, pixels, cpu):
    err = est - truth
    ok = np.isfinite(err)
    e = err[ok]
    print(f"{name:<26} {np.sqrt(np.mean(e ** 2)):8.3f} {np.median(np.abs(e)):8.3f} "
          f"{np.mean(np.abs(e) > 1):8.4f} {ok.mean():7.3f} {seconds:7.2f} {cpu:7.2f} "
          f"{pixels / seconds / 1e6:7.2f}")


def main():
    rng = np.random.default_rng(0)
    f, b = make_pair(rng)
    rows, cols = f.shape
    win = (MARGIN, MARGIN, cols - 2 * MARGIN, rows - 2 * MARGIN)
    npix = win[2] * win[3]
    jj, ii = np.mgrid[0:win[3], 0:win[2]].astype(float)
    gx, gy = ii + MARGIN + 0.5, jj + MARGIN + 0.5
    print(f"pair {cols}x{rows}, window {win[2]}x{win[3]}, parallax range "
          f"{py_true(gx, gy).min():.1f} … {py_true(gx, gy).max():.1f} px, direction x")
    print(f"{'method':<26} {'RMS px':>8} {'med|e|':>8} {'>1px':>8} {'valid':>7} {'wall s':>7} {'cpu s':>7} {'MP/s':>7}")
    for h in (3, 4):
        t0, c0 = time.perf_counter(), time.process_time()
        r = parallax_map(f, b, np.eye(2, 3), np.eye(2, 3), win, (1, 0), prior=2.5,
                         search_range=13, half_window=h)
        report(f"ours NCC {2*h+1}x{2*h+1} + LR", r.parallax, py_true(gx, gy),
               time.perf_counter() - t0, npix, time.process_time() - c0)
    # StereoSGBM: left = F, right = B, disparity xF − xB = py, on the F grid
    truth_f = py_true(*n_position(gx, gy, +1))
    for bs in (5, 7):
        sgbm = cv2.StereoSGBM_create(minDisparity=-14, numDisparities=32, blockSize=bs,
                                     P1=8 * bs * bs, P2=32 * bs * bs, disp12MaxDiff=1,
                                     uniquenessRatio=5, speckleWindowSize=100, speckleRange=2,
                                     mode=cv2.STEREO_SGBM_MODE_SGBM)
        t0, c0 = time.perf_counter(), time.process_time()
        disp = sgbm.compute(f, b).astype(np.float32) / 16.0
        dt, cpu = time.perf_counter() - t0, time.process_time() - c0
        disp[disp < -14] = np.nan
        d = disp[MARGIN:rows - MARGIN, MARGIN:cols - MARGIN]
        report(f"cv2 StereoSGBM block {bs}", d, truth_f, dt, rows * cols, cpu)


if __name__ == "__main__":
    main()
