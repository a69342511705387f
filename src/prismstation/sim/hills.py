"""A surface known exactly on a geographic and a projected grid: analytic hills written on a
3″ EPSG:4326 grid (cells on whole multiples of 3″, as SRTM's) and on a 21 km, 30 m UTM zone 31
grid around a place (:class:`Place`), and the horizontal shift that lays the true surface on
heights read elsewhere (:func:`shift_m`). What a reprojection is checked against (its tests and
``benchmarks/bench_reproject.py``). Heights metres, map coordinates metres of UTM zone 31N."""
from __future__ import annotations

import numpy as np
import rasterio
from pyproj import Transformer
from rasterio.transform import Affine

CELL = 30.0                  # the UTM grid's cell, m
SIDE = 700                   # its cells per side: 21 km
ARCSEC3 = 3.0 / 3600.0
TOLERANCE_M = 0.05 * CELL    # the agreement asked of every path
UTM31 = "EPSG:32631"         # central meridian 3° E; the zone spans 0–6° E

#: (latitude °, longitude − central meridian °): equator to 70° N, on the central meridian
#: and at the zone's edges (±2.95°: the UTM grid reaches past them)
PLACES = [(0.0, 0.0), (0.0, 2.95), (20.0, -2.95), (41.0, 0.0), (41.0, 2.95), (60.0, 0.0),
          (70.0, 0.0), (70.0, -2.95)]


def surface(e, n, e0, n0):
    """Rolling hills (m) at UTM (e, n): 2–5 km wavelengths, slopes up to ~30 %, and its
    gradient (∂/∂e, ∂/∂n)."""
    x, y = e - e0, n - n0
    k1, k2, k3 = 2 * np.pi / 3100.0, 2 * np.pi / 2300.0, 2 * np.pi / 5300.0
    h = 400 + 150 * np.sin(k1 * x) * np.cos(k2 * y) + 60 * np.sin(k3 * (x + 0.6 * y))
    ge = 150 * k1 * np.cos(k1 * x) * np.cos(k2 * y) + 60 * k3 * np.cos(k3 * (x + 0.6 * y))
    gn = -150 * k2 * np.sin(k1 * x) * np.sin(k2 * y) + 36 * k3 * np.cos(k3 * (x + 0.6 * y))
    return h, ge, gn


def centres(transform, shape):
    rows, cols = np.mgrid[0:shape[0], 0:shape[1]] + 0.5
    t = transform
    return t.a * cols + t.b * rows + t.c, t.d * cols + t.e * rows + t.f


def write(path, heights, crs, transform):
    with rasterio.open(path, "w", driver="GTiff", width=heights.shape[1], height=heights.shape[0],
                       count=1, dtype="float32", crs=crs, transform=transform, nodata=np.nan) as ds:
        ds.write(heights.astype(np.float32), 1)


class Place:
    """A 3″ EPSG:4326 grid (cells on whole multiples of 3″, as SRTM's) and a 30 m UTM zone 31
    grid around one place (the UTM grid inside the geographic one); :meth:`write` puts the
    surface on both, exact at every cell centre."""

    def __init__(self, lat, dlon):
        lon = 3.0 + dlon
        to_utm = Transformer.from_crs("EPSG:4326", UTM31, always_xy=True)
        self.e0, self.n0 = (round(v) for v in to_utm.transform(lon, lat))
        self.utm_t = Affine(CELL, 0, self.e0 - SIDE * CELL / 2, 0, -CELL, self.n0 + SIDE * CELL / 2)
        self.utm_shape = (SIDE, SIDE)
        half_lat = 0.6 * SIDE * CELL / 111_000.0
        half_lon = half_lat / np.cos(np.radians(lat)) + 0.02
        w = np.floor((lon - half_lon) / ARCSEC3) * ARCSEC3
        nn = np.ceil((lat + half_lat) / ARCSEC3) * ARCSEC3
        self.geo_t = Affine(ARCSEC3, 0, w, 0, -ARCSEC3, nn)
        self.geo_shape = (int(2 * half_lat / ARCSEC3), int(2 * half_lon / ARCSEC3))

    def write(self, tmp_path) -> "Place":
        self.utm, self.geo = tmp_path / "utm.tif", tmp_path / "geo.tif"
        write(self.utm, self.truth(*self.utm_en())[0], UTM31, self.utm_t)
        write(self.geo, self.truth(*self.geo_en())[0], "EPSG:4326", self.geo_t)
        return self

    def truth(self, e, n):
        return surface(e, n, self.e0, self.n0)

    def utm_en(self):
        return centres(self.utm_t, self.utm_shape)

    def geo_en(self):
        lon, lat = centres(self.geo_t, self.geo_shape)
        return Transformer.from_crs("EPSG:4326", UTM31, always_xy=True).transform(lon, lat)


def shift_m(moved, e, n, truth, margin=3):
    """The horizontal shift (east, north, m) that lays the true surface on ``moved`` (heights at
    UTM points ``e, n``): least squares of ``moved − h = −∇h · s + dz`` over finite cells away
    from the edges."""
    h, ge, gn = truth(e, n)
    ok = np.isfinite(moved)
    ok[:margin], ok[-margin:], ok[:, :margin], ok[:, -margin:] = False, False, False, False
    a = np.column_stack([-ge[ok], -gn[ok], np.ones(ok.sum())])
    s, *_ = np.linalg.lstsq(a, moved[ok] - h[ok], rcond=None)
    return float(s[0]), float(s[1])
