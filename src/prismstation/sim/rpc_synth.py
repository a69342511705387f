"""A synthetic pushbroom pair with RPCs over a known terrain, for the RPC DSM's tests and benchmarks.

Each image's RPC is a cubic rational polynomial (not an affine camera: quadratic terms in
ground and height and a non-constant denominator) looking ``tan_along`` forward or backward
along the lines and ``tan_across`` across them; the images are rendered by intersecting each
pixel's ray with the terrain (fixed-point iteration on the height) and sampling a random ground
texture. Ground is (lon°, lat°, ellipsoidal h m); local metres ``(e, n)`` are equirectangular
about ``(lon0, lat0)`` (exact enough over a few kilometres for a self-consistent test world).
"""
from __future__ import annotations

import warnings

import numpy as np
import rasterio
import rasterio.errors
from scipy import ndimage

from prismstation.core.models.rpc import Rpc
from prismstation.core.models.rpc_bias import metres_per_degree


class World:
    """Terrain ``height(lon, lat)`` and texture ``texture(lon, lat)`` about ``(lon0, lat0)``."""

    def __init__(self, lon0, lat0, height, extent_m=4000.0, texture_cell_m=1.0, seed=0):
        self.lon0, self.lat0 = lon0, lat0
        self.ke, self.kn = metres_per_degree(lat0)
        self._height = height
        rng = np.random.default_rng(seed)
        n = int(extent_m / texture_cell_m)
        t = ndimage.gaussian_filter(rng.normal(size=(n, n)), 1.2)
        t += 0.5 * ndimage.gaussian_filter(rng.normal(size=(n, n)), 6.0) * 6
        self.tex, self.cell, self.half = t.astype(np.float32), texture_cell_m, extent_m / 2

    def local(self, lon, lat):
        return (np.asarray(lon) - self.lon0) * self.ke, (np.asarray(lat) - self.lat0) * self.kn

    def height(self, lon, lat):
        return self._height(*self.local(lon, lat))

    def texture(self, lon, lat):
        e, n = self.local(lon, lat)
        c = (np.asarray(e) + self.half) / self.cell - 0.5
        r = (self.half - np.asarray(n)) / self.cell - 0.5
        return ndimage.map_coordinates(self.tex, [r.ravel(), c.ravel()], order=1,
                                       mode="nearest").reshape(np.shape(e))


def analytic_terrain(e, n):
    """Rolling hills with one steep knoll: 250–600 m."""
    return (420.0 + 110.0 * np.sin(e / 650.0) * np.cos(n / 800.0)
            + 70.0 * np.exp(-((e - 250.0) ** 2 + (n + 150.0) ** 2) / 220.0 ** 2))


def dem_terrain(path):
    """Bilinear heights of a geographic DEM file (e.g. an SRTM ``.hgt``)."""
    with rasterio.open(path) as ds:
        z = ds.read(1).astype(float)
        a, _, c0, _, e, f0 = tuple(ds.transform)[:6]

    def height(lon, lat):
        c = (np.asarray(lon, float) - c0) / a
        r = (np.asarray(lat, float) - f0) / e
        return ndimage.map_coordinates(z, [np.ravel(r) - 0.5, np.ravel(c) - 0.5], order=1,
                                       mode="nearest").reshape(np.shape(lon))
    return height


def make_rpc(lon0, lat0, *, gsd=2.0, size=500, tan_along=0.2, tan_across=0.05, h_off=400.0,
             h_scale=500.0, seed=0) -> Rpc:
    """An RPC of a ``size`` × ``size`` image of ``gsd`` m centred on ``(lon0, lat0)``."""
    ke, kn = metres_per_degree(lat0)
    half = size / 2.0
    lon_scale, lat_scale = gsd * half / ke, gsd * half / kn
    rng = np.random.default_rng(seed)
    # normalised image per normalised ground: x ≈ L, y ≈ −P, height moves (x, y) by tan/gsd px/m
    kh = h_scale / (gsd * half)
    samp_num = np.zeros(20)
    line_num = np.zeros(20)
    samp_num[[1, 2, 3]] = [1.0, 0.03, tan_across * kh]
    line_num[[1, 2, 3]] = [-0.02, -1.0, -tan_along * kh]
    # a little of every curvature a real product's RPC has
    samp_num[4:10] = rng.normal(0, 5e-4, 6)
    line_num[4:10] = rng.normal(0, 5e-4, 6)
    samp_num[10:] = rng.normal(0, 5e-5, 10)
    line_num[10:] = rng.normal(0, 5e-5, 10)
    den = np.zeros(20)
    den[0], den[1], den[2] = 1.0, 4e-3, -3e-3
    return Rpc(line_off=half - 0.5, samp_off=half - 0.5, lat_off=lat0, lon_off=lon0, h_off=h_off,
               line_scale=half, samp_scale=half, lat_scale=lat_scale, lon_scale=lon_scale,
               h_scale=h_scale, line_num=line_num, line_den=den.copy(), samp_num=samp_num,
               samp_den=den.copy(), source="synthetic")


def render(rpc: Rpc, world: World, size: int, iterations: int = 12, step: int = 6) -> np.ndarray:
    """The image (float32, ``size`` × ``size``): each pixel centre's ray meets the terrain.

    Rays are lifted exactly (:meth:`Rpc.localize`) at three heights over the RPC's domain on a
    lattice every ``step`` pixels, interpolated bilinearly between the nodes and taken as
    quadratic in height (millimetres from the exact ray for these smooth RPCs); the height
    where the ray meets the terrain by fixed-point iteration."""
    n = size // step + 2
    gx, gy = np.meshgrid(np.arange(n) * step + 0.5, np.arange(n) * step + 0.5)
    hs = rpc.h_off + rpc.h_scale * np.array([-1.0, 0.0, 1.0])
    nodes = [rpc.localize(gx, gy, np.full(gx.shape, h)) for h in hs]
    idx = np.meshgrid(np.arange(size) / step, np.arange(size) / step)
    up = lambda v: ndimage.map_coordinates(v, [idx[1], idx[0]], order=1)  # noqa: E731
    ray = [[up(v) for v in node] for node in nodes]          # [height][lon, lat]
    q = [(v[1], 0.5 * (v[2] - v[0]), 0.5 * (v[2] + v[0]) - v[1]) for v in zip(*ray)]
    h = np.full((size, size), rpc.h_off)
    for _ in range(iterations):
        t = (h - hs[1]) / rpc.h_scale
        lon, lat = (c0 + c1 * t + c2 * t * t for c0, c1, c2 in q)
        h = world.height(lon, lat)
    return (100.0 + 20.0 * world.texture(lon, lat)).astype(np.float32)


def write_image(path, image) -> None:
    """A plain GeoTIFF of the image (its RPC is given to the DSM as a model, not a tag)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path, "w", driver="GTiff", width=image.shape[1], height=image.shape[0],
                           count=1, dtype="float32") as ds:
            ds.write(image, 1)
