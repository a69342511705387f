"""DEM co-registration: ours (least-squares surface matching) vs xDEM NuthKaab on the same pairs.

Pairs: the real SRTM tile ../shared/data/real/srtm/N44E005_UTM.tif (90 m, Mont Ventoux) as
reference; the DEM to align is the same tile moved by a known (dcol, drow) with a cubic spline,
lowered by dz, with Gaussian noise (σ 3 m) and a void of 100 x 100 cells. Errors are in metres
(x, y planimetric; z), per pair and as RMS. xDEM is optional: ``.venv/bin/pip install xdem``.

Run: ``.venv/bin/python benchmarks/bench_coreg.py``
"""
from __future__ import annotations

import time
import warnings
from pathlib import Path

import numpy as np
import rasterio
from scipy import ndimage

from prismstation.core.matching.coreg import coregister, nuth_kaab

TILE = Path(__file__).resolve().parents[2] / "shared" / "data" / "real" / "srtm" / "N44E005_UTM.tif"
CASES = [(0.3, -0.45, 2.0), (0.05, 0.12, 0.0), (1.7, 0.6, -5.0), (3.0, 5.0, 10.0),
         (-6.7, 4.2, -25.0), (12.5, -9.3, 0.0), (-0.8, -2.35, 50.0)]
NOISE = 3.0


def moved(h, dcol, drow, dz, rng):
    """dem(c, r) = h(c + dcol, r + drow) - dz + noise: content dcol px left, drow px up."""
    rr, cc = np.mgrid[0:h.shape[0], 0:h.shape[1]].astype(float)
    filled = np.where(np.isfinite(h), h, np.nanmean(h))
    out = ndimage.map_coordinates(filled, [rr + drow, cc + dcol], order=3, mode="constant",
                                  cval=np.nan)
    void = ndimage.map_coordinates(np.isnan(h).astype(float), [rr + drow, cc + dcol], order=1,
                                   mode="constant", cval=1.0) > 0
    out[void] = np.nan
    out[500:600, 300:400] = np.nan
    return out - dz + rng.normal(0, NOISE, out.shape)


def ours(ref, dem, transform, crs):
    r = coregister(ref, dem, tuple(transform)[:6])
    return r.dx, r.dy, r.dz


def ours_nk(ref, dem, transform, crs):
    r = nuth_kaab(ref, dem, tuple(transform)[:6])
    return r.dx, r.dy, r.dz


def xdem_nuthkaab(ref, dem, transform, crs):
    import xdem
    nk = xdem.coreg.NuthKaab()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        nk.fit(ref.astype(np.float32), dem.astype(np.float32), transform=transform, crs=crs)
    s = nk.meta["outputs"]["affine"]
    return float(s["shift_x"]), float(s["shift_y"]), float(s["shift_z"])


def xdem_available() -> bool:
    import importlib.util
    return importlib.util.find_spec("xdem") is not None


def main():
    with rasterio.open(TILE) as ds:
        h = ds.read(1).astype(float)
        h[h == ds.nodata] = np.nan
        transform, crs = ds.transform, ds.crs
    px = transform.a
    methods = {"ours LSM": ours, "ours NuthKaab": ours_nk}
    if xdem_available():
        methods["xDEM NuthKaab"] = xdem_nuthkaab
    else:
        print("xdem not installed: its column is skipped (.venv/bin/pip install xdem)\n")
    rng = np.random.default_rng(0)
    pairs = [(c, moved(h, *c, rng)) for c in CASES]
    print(f"reference {TILE.name} {h.shape}, {px:g} m cells; noise σ {NOISE} m; errors in metres")
    print(f"{'true dcol,drow,dz':>22} {'method':<14} {'err x':>7} {'err y':>7} {'err z':>7} {'s':>6}")
    totals = {m: [] for m in methods}
    for (dcol, drow, dz), dem in pairs:
        truth = (dcol * transform.a + drow * transform.b, dcol * transform.d + drow * transform.e, dz)
        for name, fn in methods.items():
            t0 = time.perf_counter()
            est = fn(h, dem, transform, crs)
            dt = time.perf_counter() - t0
            err = np.subtract(est, truth)
            totals[name].append((*err, dt))
            print(f"{dcol:7.2f},{drow:6.2f},{dz:6.1f}  {name:<14} {err[0]:7.2f} {err[1]:7.2f} "
                  f"{err[2]:7.2f} {dt:6.2f}")
    print("\nwhole tile:")
    summary(totals)
    # the use of docs/model.md §3: 4.3 km patches (48 x 48 cells) cut from the same pairs
    print("\n48 x 48-cell patches (4.3 km) at 4 places, same shifts (multi-pixel ones within 6 px):")
    totals = {m: [] for m in methods}
    for (dcol, drow, dz), dem in pairs:
        if max(abs(dcol), abs(drow)) > 6:
            continue
        truth = (dcol * transform.a + drow * transform.b, dcol * transform.d + drow * transform.e, dz)
        for r0, c0 in ((300, 300), (600, 450), (800, 200), (450, 650)):
            sl = (slice(r0, r0 + 48), slice(c0, c0 + 48))
            t = transform * transform.translation(c0, r0)
            for name, fn in methods.items():
                t0 = time.perf_counter()
                est = fn(h[sl], dem[sl], t, crs)
                totals[name].append((*np.subtract(est, truth), time.perf_counter() - t0))
    summary(totals)


def summary(totals):
    for name, rows in totals.items():
        e = np.array(rows)
        print(f"{name:<14} RMS planimetric {np.sqrt(np.mean(e[:, 0]**2 + e[:, 1]**2)):.2f} m, "
              f"max {np.max(np.hypot(e[:, 0], e[:, 1])):.2f} m, RMS z {np.sqrt(np.mean(e[:, 2]**2)):.2f} m,"
              f" mean time {e[:, 3].mean():.2f} s")


if __name__ == "__main__":
    main()
