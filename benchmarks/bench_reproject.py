"""Where a geographic DEM lands on a UTM grid: GDAL's default warp against ``io.reproject``.

Per place (latitude, longitude off the UTM zone's central meridian): the analytic hills of
``prismstation.sim.hills`` written on a 3″ EPSG:4326 grid and on a 21 km, 30 m UTM grid,
the first read onto the second with the approximate transformer at GDAL's default threshold
(0.125 source pixel) and at ``ERROR_PX``; printed: where the surface arrives (east, north, m,
least squares on its gradient) and the largest error of the warp's source positions against
pyproj (source pixels, found by warping the source's own column and row numbers). Then the
cost: a 3″ grid onto a 6,000² 2.5 m UTM grid at both thresholds.

Run: ``.venv/bin/python benchmarks/bench_reproject.py``
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from rasterio.transform import Affine

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from prismstation.io.reproject import ERROR_PX, grid_pixels, warp_array  # noqa: E402
from prismstation.sim.hills import PLACES, UTM31, Place, shift_m  # noqa: E402

GDAL_DEFAULT = 0.125


def main() -> int:
    print(f"| latitude | off the central meridian | shift E, N m at {GDAL_DEFAULT} px | "
          f"at {ERROR_PX} px | largest position error px at {GDAL_DEFAULT} | at {ERROR_PX} |")
    print("|---|---|---|---|---|---|")
    for lat, dlon in PLACES:
        p = Place(lat, dlon)
        e, n = p.geo_en()
        heights = p.truth(e, n)[0]
        rows, cols = np.mgrid[0:p.geo_shape[0], 0:p.geo_shape[1]] + 0.5
        want = grid_pixels(*p.utm_en(), UTM31, "EPSG:4326", p.geo_t)
        shifts, errs = [], []
        for tol in (GDAL_DEFAULT, ERROR_PX):
            on_utm = warp_array(heights, "EPSG:4326", p.geo_t, UTM31, p.utm_t, p.utm_shape, error_px=tol)
            shifts.append(shift_m(on_utm, *p.utm_en(), p.truth))
            worst = 0.0
            for v, w in zip((cols, rows), want):
                g = warp_array(v, "EPSG:4326", p.geo_t, UTM31, p.utm_t, p.utm_shape, error_px=tol)
                inner = np.isfinite(g)
                inner[:2], inner[-2:], inner[:, :2], inner[:, -2:] = False, False, False, False
                worst = max(worst, float(np.abs(g - w)[inner].max()))
            errs.append(worst)
        print(f"| {lat:g}° | {dlon:+g}° | {shifts[0][0]:+.2f}, {shifts[0][1]:+.2f} | "
              f"{shifts[1][0]:+.2f}, {shifts[1][1]:+.2f} | {errs[0]:.4f} | {errs[1]:.4f} |")
    p = Place(41.0, 0.0)
    rng = np.random.default_rng(0)
    src = rng.normal(size=p.geo_shape)
    big = (6000, 6000)
    fine = Affine(2.5, 0, p.utm_t.c + 3000, 0, -2.5, p.utm_t.f - 3000)     # inside the 3″ grid
    for tol in (GDAL_DEFAULT, ERROR_PX):
        t0 = time.perf_counter()
        warp_array(src, "EPSG:4326", p.geo_t, UTM31, fine, big, error_px=tol)
        print(f"3″ grid onto 6,000² cells of 2.5 m at {tol} px: {time.perf_counter() - t0:.2f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
