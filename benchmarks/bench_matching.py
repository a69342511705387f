"""Point-transfer accuracy and speed: ours (NCC + LSM) vs OpenCV matchTemplate vs skimage phase correlation.

Cases: real Pléiades texture (uint16, ../shared/data/real/pleiades_triplet), a random point,
the search image made by warping the reference by a known affine (subpixel shift, rotation up
to ±2°, scale ±2 %, shear ±1 %) with a cubic spline, the prediction off by up to ±3 px along a
random search direction, Gaussian noise added to both images. Truth is the warp of the point.

Time per point is wall-clock (CPU time beside it: the machine may be shared).
Run: ``.venv/bin/python benchmarks/bench_matching.py [n_cases]``
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import cv2
import numpy as np
import rasterio
from scipy import ndimage

from prismstation.core.matching.matching import match_point

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "real" / "pleiades_triplet"
H = 15            # template half size: 31 x 31 for every method
CROP = 48         # half size of the image crops handed to the matchers


def load_images():
    out = []
    for f in sorted(DATA.glob("*.tif")):
        with rasterio.open(f) as ds:
            img = ds.read(1).astype(np.float64)
        out.append((img, ndimage.spline_filter(img, order=3)))
    return out


def make_case(rng, img, coeffs, noise):
    """Reference crop, point, search crop, truth, prediction and direction (crop pixel coords)."""
    rows, cols = img.shape
    margin = CROP + 20
    p = np.array([rng.uniform(margin, cols - margin), rng.uniform(margin, rows - margin)])
    ang = np.radians(rng.uniform(-2, 2))
    s = 1 + rng.uniform(-0.02, 0.02)
    A = s * np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
    A = A @ np.array([[1, rng.uniform(-0.01, 0.01)], [0, 1]])
    t = rng.uniform(-0.5, 0.5, 2)
    # reference crop with the point: crop origin (continuous coords) at integer corner
    r_org = np.floor(p) - CROP
    ref = img[int(r_org[1]):int(r_org[1]) + 2 * CROP, int(r_org[0]):int(r_org[0]) + 2 * CROP].copy()
    # search crop: q = A (p' - p) + p + t maps reference (full-image coords) to search coords;
    # the search crop's origin is set so that q of the point lies near its centre.
    s_org = np.floor(p + t) - CROP
    oy, ox = np.mgrid[0:2 * CROP, 0:2 * CROP]
    q = np.stack([ox + 0.5 + s_org[0], oy + 0.5 + s_org[1]], -1)
    src = (q - p - t) @ np.linalg.inv(A).T + p                 # reference continuous coords
    srch = ndimage.map_coordinates(coeffs, [src[..., 1] - 0.5, src[..., 0] - 0.5],
                                   order=3, prefilter=False)
    ref = ref + rng.normal(0, noise, ref.shape)
    srch = srch + rng.normal(0, noise, srch.shape)
    truth = p + t - s_org                                       # point in search-crop coords
    pt = p - r_org                                              # point in reference-crop coords
    d = rng.normal(size=2)
    d /= np.hypot(*d)
    pred = truth + d * rng.uniform(-3, 3)
    to_u16 = lambda a: np.clip(np.rint(a), 0, 65535).astype(np.uint16)  # noqa: E731
    return to_u16(ref), pt, to_u16(srch), truth, pred, d


def ours(ref, pt, srch, pred, d):
    r = match_point(ref, pt[0], pt[1], srch, pred[0], pred[1], direction=d, search_range=6,
                    half_window=H)
    return (r.x, r.y) if r.ok else None


def opencv_ncc(ref, pt, srch, pred, d):
    i0, j0 = int(np.floor(pt[0])), int(np.floor(pt[1]))
    tmpl = ref[j0 - H:j0 + H + 1, i0 - H:i0 + H + 1].astype(np.float32)
    res = cv2.matchTemplate(srch.astype(np.float32), tmpl, cv2.TM_CCOEFF_NORMED)
    v, u = np.unravel_index(np.argmax(res), res.shape)
    if not (0 < u < res.shape[1] - 1 and 0 < v < res.shape[0] - 1):
        return None
    par = lambda m, c, p: 0.5 * (m - p) / (m - 2 * c + p)  # noqa: E731
    su = par(res[v, u - 1], res[v, u], res[v, u + 1])
    sv = par(res[v - 1, u], res[v, u], res[v + 1, u])
    return (u + su + H + 0.5 + pt[0] - (i0 + 0.5), v + sv + H + 0.5 + pt[1] - (j0 + 0.5))


def skimage_phase(ref, pt, srch, pred, d, half=H):
    from skimage.registration import phase_cross_correlation
    i0, j0 = int(np.floor(pt[0])), int(np.floor(pt[1]))
    a = ref[j0 - half:j0 + half + 1, i0 - half:i0 + half + 1].astype(float)
    k0, l0 = int(np.floor(pred[0])), int(np.floor(pred[1]))
    b = srch[l0 - half:l0 + half + 1, k0 - half:k0 + half + 1].astype(float)
    shift, _, _ = phase_cross_correlation(b, a, upsample_factor=100)   # (row, col) of a vs b
    # the shift registers a onto b: a's content at offset o appears in b at o + shift
    return (pt[0] + (k0 - i0) + shift[1], pt[1] + (l0 - j0) + shift[0])


def run(n_cases: int = 300, noises=(0.0, 5.0, 10.0, 20.0), seed: int = 1):
    images = load_images()
    std = np.mean([im.std() for im, _ in images])
    print(f"{n_cases} cases per noise level, Pléiades texture (DN std {std:.0f}), template 31x31\n")
    methods = {"ours NCC+LSM": ours, "cv2 matchTemplate+parabola": opencv_ncc,
               "skimage phase_corr 31x31": skimage_phase,
               "skimage phase_corr 61x61": lambda *a: skimage_phase(*a, half=30)}
    print(f"{'noise σ (DN)':>12} {'method':<28} {'RMS px':>8} {'max px':>8} {'fail':>5} {'ms/pt':>7} {'cpu ms':>7}")
    for noise in noises:
        rng = np.random.default_rng(seed)
        cases = []
        for _ in range(n_cases):
            img, coeffs = images[rng.integers(len(images))]
            cases.append(make_case(rng, img, coeffs, noise))
        for name, fn in methods.items():
            errs, fails = [], 0
            t0, c0 = time.perf_counter(), time.process_time()
            for ref, pt, srch, truth, pred, d in cases:
                res = fn(ref, pt, srch, pred, d)
                if res is None:
                    fails += 1
                else:
                    errs.append(np.hypot(res[0] - truth[0], res[1] - truth[1]))
            ms = (time.perf_counter() - t0) / len(cases) * 1e3
            cpu = (time.process_time() - c0) / len(cases) * 1e3
            e = np.array(errs)
            # robust to the rare gross blunder of a peer: RMS over all successful cases
            print(f"{noise:12.1f} {name:<28} {np.sqrt(np.mean(e ** 2)):8.4f} {e.max():8.3f} "
                  f"{fails:5d} {ms:7.2f} {cpu:7.2f}")
        print()


if __name__ == "__main__":
    run(int(sys.argv[1]) if len(sys.argv) > 1 else 300)
