"""Terrain from a real DEM: the simulator's height grid resampled (bicubic) from any
single-band raster with a CRS (SRTM ``.hgt``, a GeoTIFF in EPSG:4326 or projected).

The scene moves to the DEM: its centre is the chosen point of the DEM (by default the DEM's
centre), its map frame the WGS 84 UTM zone there (``EPSG:326zz`` north, ``327zz`` south). Every
cell centre of the simulator's grid is carried into the DEM's CRS by pyproj and interpolated
there by a cubic B-spline through the DEM's posts (``scipy.ndimage``: the surface passes through
every post, values at post centres, GDAL's pixel-is-area convention with centres at +0.5).
The DEM's heights are taken as orthometric (SRTM's are EGM96); its band scale and offset and a
vertical unit in feet are applied. Voids (nodata, SRTM's −32768, NaN) are filled by GDAL's
inverse-distance fill when they are at most ``MAX_VOID_SHARE`` of the DEM under the scene,
else the DEM is refused for that place.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pyproj import CRS as ProjCRS
from pyproj import Transformer
from pyproj.exceptions import CRSError, ProjError
from rasterio.errors import RasterioError
from rasterio.fill import fillnodata
from rasterio.transform import Affine
from rasterio.windows import Window
from scipy import ndimage

from prismstation.errors import InputError
from prismstation.io.dem import SRTM_VOID, open_raster
from prismstation.io.reproject import grid_pixels

#: largest share of void posts under the scene that is filled; more and the DEM is refused there
MAX_VOID_SHARE = 0.05
#: posts read beyond the ones the grid needs (the cubic spline's support, and its edge effects)
MARGIN_POSTS = 8
_UNITS_M = {None: 1.0, "": 1.0, "m": 1.0, "metre": 1.0, "meter": 1.0, "metres": 1.0,
            "meters": 1.0, "ft": 0.3048, "foot": 0.3048, "feet": 0.3048,
            "us-ft": 1200.0 / 3937.0, "us survey foot": 1200.0 / 3937.0}


@dataclass(frozen=True)
class DemTerrain:
    """A DEM placed under a scene.

    ``crs``/``transform``/``shape`` are the DEM file's; ``to_m`` and ``offset_m`` turn stored
    values into metres; ``at`` is the DEM point (its CRS) under the scene's centre, which is
    ``centre`` (E, N metres) in ``scene_crs``.
    """

    path: Path
    crs: ProjCRS
    transform: Affine
    shape: tuple[int, int]
    to_m: float
    offset_m: float
    at: tuple[float, float]
    scene_crs: str
    centre: tuple[float, float]

    def describe(self) -> dict:
        return {"kind": "dem", "file": str(self.path), "dem_crs": self.crs.to_string(),
                "at": [float(v) for v in self.at], "scene_crs": self.scene_crs,
                "heights": "orthometric, as the DEM's"}

    def _to_dem_pixels(self, e, n) -> tuple[np.ndarray, np.ndarray]:
        """Continuous DEM array indices ``(col, row)``, post centres at integers."""
        col, row = grid_pixels(e, n, self.scene_crs, self.crs, self.transform)
        return np.asarray(col) - 0.5, np.asarray(row) - 0.5

    def heights(self, e0: float, n0: float, shape, spacing: float,
                block_rows: int = 256) -> tuple[np.ndarray, float]:
        """Orthometric heights (m, float32, ``shape``) at the cell centres of the north-up scene
        grid with west edge ``e0``, north edge ``n0`` and cell ``spacing`` (m), and the share of
        void posts that were filled under it."""
        rows, cols = shape
        # the window of posts the grid needs: the image of its boundary bounds its interior
        k = np.linspace(0.0, 1.0, 65)
        be = np.concatenate([k * cols, k * cols, np.zeros_like(k), np.full_like(k, cols)])
        bn = np.concatenate([np.zeros_like(k), np.full_like(k, rows), k * rows, k * rows])
        c, r = self._to_dem_pixels(e0 + be * spacing, n0 - bn * spacing)
        if not (np.all(np.isfinite(c)) and np.all(np.isfinite(r))):
            raise InputError("the scene's area cannot be carried into the DEM's CRS",
                             file=self.path)
        c0, c1 = int(np.floor(c.min())) - MARGIN_POSTS, int(np.ceil(c.max())) + MARGIN_POSTS + 1
        r0, r1 = int(np.floor(r.min())) - MARGIN_POSTS, int(np.ceil(r.max())) + MARGIN_POSTS + 1
        if c0 < 0 or r0 < 0 or c1 > self.shape[1] or r1 > self.shape[0]:
            w, h = cols * spacing / 1000.0, rows * spacing / 1000.0
            raise InputError(f"a {w:.1f} × {h:.1f} km scene centred at {self.at[0]:g} "
                             f"{self.at[1]:g} does not fit inside the DEM ({self.shape[1]} × "
                             f"{self.shape[0]} posts): choose another --terrain-centre or a "
                             f"larger DEM", file=self.path)
        posts, void_share = self._read_posts(Window(c0, r0, c1 - c0, r1 - r0))
        coeffs = ndimage.spline_filter(posts, order=3, mode="mirror")
        out = np.empty(shape, np.float32)
        e = e0 + (np.arange(cols) + 0.5) * spacing
        for a in range(0, rows, block_rows):
            b = min(rows, a + block_rows)
            ee, nn = np.meshgrid(e, n0 - (np.arange(a, b) + 0.5) * spacing)
            cc, rr = self._to_dem_pixels(ee, nn)
            out[a:b] = ndimage.map_coordinates(coeffs, [rr - r0, cc - c0], order=3,
                                               mode="mirror", prefilter=False)
        return out, void_share

    def _read_posts(self, window: Window) -> tuple[np.ndarray, float]:
        """Posts (m, float64) of ``window``, voids filled; the share of void posts."""
        try:
            with open_raster(self.path, "terrain DEM") as ds:
                raw = ds.read(1, window=window, masked=True)
        except RasterioError as exc:
            raise InputError(f"cannot read the terrain DEM ({exc})", file=self.path) from None
        values = raw.astype(np.float64).filled(np.nan)
        if raw.dtype == np.int16:
            values[values <= SRTM_VOID] = np.nan        # SRTM voids even without a nodata tag
        valid = np.isfinite(values)
        share = 1.0 - float(valid.mean())
        if share > MAX_VOID_SHARE:
            raise InputError(f"{100 * share:.1f} % of the DEM under the scene is void (at most "
                             f"{100 * MAX_VOID_SHARE:.0f} % is filled): choose another "
                             f"--terrain-centre", file=self.path)
        values = values * self.to_m + self.offset_m
        if share > 0:
            filled = fillnodata(np.where(valid, values, 0.0).astype(np.float32),
                                mask=valid.astype(np.uint8),
                                max_search_distance=float(max(values.shape)),
                                smoothing_iterations=0)
            values = np.where(valid, values, filled.astype(np.float64))
        return values, share


def utm_crs(lon: float, lat: float) -> str:
    """The WGS 84 UTM zone of a point (``"EPSG:326zz"`` north, ``"EPSG:327zz"`` south)."""
    zone = int(np.floor((lon + 180.0) / 6.0)) % 60 + 1
    return f"EPSG:{(32600 if lat >= 0 else 32700) + zone}"


def open_dem_terrain(path, at=None) -> DemTerrain:
    """Check a DEM and place the scene's centre on its point ``at`` (x, y in the DEM's CRS:
    longitude, latitude in degrees for EPSG:4326), by default the DEM's centre; the scene's
    centre is that point in its UTM zone, rounded to the metre. Anything
    wrong with the file or the place → :class:`InputError` naming the file."""
    path = Path(path)
    with open_raster(path, "terrain DEM") as ds:
        if ds.crs is None:
            raise InputError("the terrain DEM has no coordinate reference system", file=path)
        if ds.transform.is_identity:
            raise InputError("the terrain DEM has no geotransform", file=path)
        unit = (ds.units[0] or "").strip().lower() if ds.units else ""
        if unit not in _UNITS_M:
            raise InputError(f"the terrain DEM's heights are in {ds.units[0]!r}, not metres or "
                             f"feet", file=path)
        crs_wkt, transform, shape = ds.crs.to_wkt(), ds.transform, (ds.height, ds.width)
        scale, offset = ds.scales[0], ds.offsets[0]
        if ds.dtypes[0] not in ("int8", "uint8", "int16", "uint16", "int32", "uint32",
                                "float32", "float64"):
            raise InputError(f"the terrain DEM's band is {ds.dtypes[0]}, not real numbers",
                             file=path)
    try:
        crs = ProjCRS.from_wkt(crs_wkt)
        x, y = at if at is not None else transform @ (shape[1] / 2.0, shape[0] / 2.0)
        col, row = ~transform @ (float(x), float(y))
        if not (0 <= col <= shape[1] and 0 <= row <= shape[0]):
            raise InputError(f"--terrain-centre {x:g} {y:g} (in the DEM's CRS, "
                             f"{crs.name}) is outside the DEM", file=path)
        lon, lat = Transformer.from_crs(crs, "EPSG:4326", always_xy=True).transform(x, y)
        scene_crs = utm_crs(lon, lat)
        e, n = Transformer.from_crs("EPSG:4326", scene_crs, always_xy=True).transform(lon, lat)
    except (CRSError, ProjError) as exc:
        raise InputError(f"cannot place a scene in the DEM's CRS ({exc})", file=path) from None
    if not (np.isfinite(e) and np.isfinite(n)):
        raise InputError(f"--terrain-centre {x:g} {y:g} has no position in {scene_crs}",
                         file=path)
    to_m = float(scale if scale else 1.0) * _UNITS_M[unit]
    return DemTerrain(path, crs, transform, shape, to_m,
                      float(offset or 0.0) * _UNITS_M[unit], (float(x), float(y)), scene_crs,
                      (float(round(e)), float(round(n))))
