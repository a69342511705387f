"""DEMs and DSMs: the one reader (SRTM ``.hgt``, GeoTIFF or any single-band raster with a CRS,
on its own grid or resampled onto a target grid, optionally made ellipsoidal) and a writer.
Resampling onto another grid goes through :mod:`prismstation.io.reproject` (positions exact to
:data:`~prismstation.io.reproject.ERROR_PX` of a source cell).

Grids are ``(crs, transform, shape)``: ``transform`` a rasterio ``Affine`` from pixel
``(col, row)`` (docs/model.md §1, origin at the top-left corner of the top-left pixel) to CRS
coordinates; arrays are ``(rows, cols)`` float64 with NaN for voids.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np
import pyproj
import rasterio
from rasterio._err import CPLE_BaseError
from rasterio.crs import CRS
from rasterio.errors import RasterioError
from rasterio.transform import Affine
from rasterio.warp import transform_bounds
from rasterio.windows import Window, from_bounds

from prismstation.core.surfaces.dsmstats import white_noise_sigma
from prismstation.errors import InputError, RasterReadError
from prismstation.io.atomic import atomic_path, cause_text, raster_check
from prismstation.io.geoid import to_ellipsoidal
from prismstation.io.reproject import transformer, warp_array, warp_band
from prismstation.io.georef import height_metres_per_unit
from prismstation.io.windows import CheckedRaster

SRTM_VOID = -32768


@dataclass(frozen=True, eq=False)
class DemGrid:
    """Heights on a grid.

    Attributes
    ----------
    heights : ndarray (rows, cols), float64
        Metres, NaN where void or outside the source.
    crs : rasterio.crs.CRS
    transform : affine.Affine
        Pixel (col, row) → CRS (x, y).
    height_kind : str
        ``"orthometric"`` or ``"ellipsoidal"`` (a file's own heights are taken as
        orthometric unless a geoid made them ellipsoidal).
    path : str or None
        The file read.
    source_cell_m : (float, float) or None
        The file's own cell size in metres (along its columns, along its rows; geographic
        grids at their centre latitude): what detail the heights can hold, whatever grid
        they were resampled onto.
    source_crs, source_transform : CRS, Affine or None
        The file's own grid (where its posts are: :meth:`source_pixels`).
    source_noise_m : float or None
        σ (m) of the white noise in the file's own heights, post by post, estimated from them
        (:func:`~prismstation.core.surfaces.dsmstats.white_noise_sigma`; NaN: too few).
    """

    heights: np.ndarray
    crs: CRS
    transform: Affine
    height_kind: str = "orthometric"
    path: str | None = None
    source_cell_m: tuple[float, float] | None = None
    source_crs: CRS | None = None
    source_transform: Affine | None = None
    source_noise_m: float | None = None

    @property
    def shape(self) -> tuple[int, int]:
        return self.heights.shape

    def source_pixels(self, en) -> np.ndarray | None:
        """``(2, n)`` continuous ``(col, row)`` on the file's own grid (a cell's centre at
        ``+0.5``) of the map points ``en`` ``(n, 2)`` of this grid's CRS; None when that grid
        is not known."""
        if self._to_source is None:
            return None
        to_crs, inv = self._to_source
        x, y = np.asarray(en, float).T
        if to_crs is not None:
            x, y = (np.asarray(v, float) for v in to_crs.transform(x, y))
        return np.vstack([inv.a * x + inv.b * y + inv.c, inv.d * x + inv.e * y + inv.f])

    @cached_property
    def _to_source(self):
        """``(transformer or None when the CRSs are one, inverse of the file's transform)``,
        made once (a transfer asks for every template's posts)."""
        if self.source_crs is None or self.source_transform is None:
            return None
        same = self.source_crs == self.crs
        return (None if same else transformer(self.crs, self.source_crs)), ~Affine(*tuple(self.source_transform)[:6])


def grid_coordinates(transform, shape) -> tuple[np.ndarray, np.ndarray]:
    """CRS coordinates ``(x, y)`` of every pixel centre of a grid, each of shape ``shape``."""
    rows, cols = np.mgrid[0:shape[0], 0:shape[1]].astype(float)
    t = Affine(*tuple(transform)[:6])
    x = t.a * (cols + 0.5) + t.b * (rows + 0.5) + t.c
    y = t.d * (cols + 0.5) + t.e * (rows + 0.5) + t.f
    return x, y


def open_raster(path, what: str = "raster") -> CheckedRaster:
    """Open a raster for reading; a missing or unopenable file → InputError naming ``what``;
    its reads raise :class:`RasterReadError` naming the file, ``what`` and the window."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"{what} not found", file=p)
    try:
        return CheckedRaster(p, what)
    except RasterReadError as exc:
        raise InputError(str(exc).removeprefix(f"{p}: "), file=p) from None


#: the most cells one DEM read may hold (2 GiB as float64): a file declaring more is refused
MAX_READ_CELLS = 1 << 28


def _needed_window(ds, target):
    """The window of ``ds`` that covers the target grid ``(crs, transform, shape)`` with a
    margin of two cells (None: the whole file), so that a DEM is read only where it is used."""
    if target is None:
        return None
    crs, t, (rows, cols) = target
    xs, ys = zip(*(t * (c, r) for c, r in ((0, 0), (cols, 0), (0, rows), (cols, rows))))
    try:
        b = transform_bounds(crs, ds.crs, min(xs), min(ys), max(xs), max(ys), densify_pts=21)
        w = from_bounds(*b, transform=ds.transform)
    except Exception:  # bounds GDAL cannot transform: the whole file (its size checked below)
        return None
    c0, r0 = max(int(np.floor(w.col_off)) - 2, 0), max(int(np.floor(w.row_off)) - 2, 0)
    c1 = min(int(np.ceil(w.col_off + w.width)) + 2, ds.width)
    r1 = min(int(np.ceil(w.row_off + w.height)) + 2, ds.height)
    return Window(c0, r0, max(c1 - c0, 1), max(r1 - r0, 1)) if c1 > c0 and r1 > r0 else Window(0, 0, 1, 1)


def _read_source(path: Path, what: str, target=None):
    """Band 1 of the DEM in metres (NaN: no data), its CRS and transform; with ``target``
    (the grid it will be resampled onto) only the window that grid needs is read."""
    with open_raster(path, what) as ds:
        if ds.crs is None:
            raise InputError(f"{what} has no coordinate reference system", file=path)
        window = _needed_window(ds, target)
        rows, cols = (window.height, window.width) if window is not None else ds.shape
        if rows * cols > MAX_READ_CELLS:
            raise InputError(f"{what} of {ds.width:,} × {ds.height:,} cells: the part needed, {cols:,} × "
                             f"{rows:,}, is too large to read (at most {MAX_READ_CELLS:,} cells)", file=path)
        arr = ds.read(1, masked=True, window=window).astype(np.float64).filled(np.nan)  # RasterReadError
        transform = ds.transform if window is None else ds.window_transform(window)
        if ds.dtypes[0] == "int16":
            arr[arr <= SRTM_VOID] = np.nan        # SRTM voids even without a nodata tag
        arr[~np.isfinite(arr)] = np.nan
        arr *= height_metres_per_unit(ds.crs.to_wkt(), path)  # heights in feet: refused or converted
        return arr, ds.crs, transform


def _auto_resampling(src_crs, src_transform, src_shape, crs, transform, shape) -> str:
    """``"average"`` when the source cells are finer than half the target cells, else bilinear
    (cell sizes in metres, :func:`local_metric_transform`)."""
    def cell(c, t, s):
        a, b, _, d, e, _ = local_metric_transform(c, t, s)
        return np.sqrt(abs(a * e - b * d))
    return "average" if cell(src_crs, src_transform, src_shape) < 0.5 * cell(crs, transform, shape) else "bilinear"


def read_dem(path, crs=None, transform=None, shape=None, *, geoid=None,
             resampling: str = "auto", what: str = "DEM") -> DemGrid:
    """Read a DEM, optionally resampled onto a target grid and made ellipsoidal.

    Parameters
    ----------
    path : str or Path
        SRTM ``.hgt``, GeoTIFF, or any single-band raster GDAL reads, with a CRS.
    crs, transform, shape : optional
        Target grid (all three, or none for the file's own grid).
    geoid : float or object with ``undulation(E, N, crs)``, optional
        If given, the stored (orthometric) heights are converted to ellipsoidal — unless the
        file states ellipsoidal heights (:func:`dem_height_kind`: a DSM of prismstation's own,
        or a compound CRS whose vertical datum is an ellipsoid), which are taken as they are.
    resampling : str
        A ``rasterio.enums.Resampling`` name (``"bilinear"``, ``"average"``, ``"cubic"``...), or
        ``"auto"``: average when the source cells are finer than half the target cells (a
        2.5 m DSM onto a 90 m grid), bilinear otherwise.
    what : str
        What the file is, for messages (``"DSM"``, ``"reference"``...).

    Returns
    -------
    DemGrid
    """
    path = Path(path)
    target = None if crs is None or transform is None or shape is None else \
        (CRS.from_user_input(crs), Affine(*tuple(transform)[:6]), tuple(shape))
    src, src_crs, src_transform = _read_source(path, what, target)
    if crs is None and transform is None and shape is None:
        heights, out_crs, out_t = src, src_crs, src_transform
    elif crs is None or transform is None or shape is None:
        raise ValueError("give the target grid's crs, transform and shape together, or none")
    else:
        out_crs, out_t = CRS.from_user_input(crs), Affine(*tuple(transform)[:6])
        try:
            if resampling == "auto":
                resampling = _auto_resampling(src_crs, src_transform, src.shape, out_crs, out_t, shape)
            heights = warp_array(src, src_crs, src_transform, out_crs, out_t, shape,
                                 resampling=resampling)
        except (RasterioError, CPLE_BaseError, KeyError) as exc:
            raise RasterReadError(f"{path}: cannot resample {what} ({cause_text(exc, str(path))})") from None
    kind = "orthometric"
    if geoid is not None and dem_height_kind(path) == "ellipsoidal":
        kind = "ellipsoidal"       # the file says its heights are on the ellipsoid already
    elif geoid is not None:
        if isinstance(geoid, (int, float)):
            heights = to_ellipsoidal(heights, geoid)
        else:
            E, N = grid_coordinates(out_t, heights.shape)
            heights = to_ellipsoidal(heights, geoid, E, N, out_crs)
        kind = "ellipsoidal"
    a, b, _, d, e, _ = local_metric_transform(src_crs, src_transform, src.shape)
    return DemGrid(heights, out_crs, out_t, kind, str(path), (float(np.hypot(a, d)), float(np.hypot(b, e))),
                   src_crs, src_transform, white_noise_sigma(src))


def resample_to_grid(path, grid: DemGrid, *, resampling: str = "bilinear",
                     what: str = "reference", dtype=np.float64, fill=np.nan) -> np.ndarray:
    """Band 1 of raster ``path`` resampled onto ``grid`` (its transform, CRS and shape), the
    file's nodata becoming ``fill``."""
    with open_raster(path, what) as ds:
        if ds.crs is None:
            raise InputError(f"{what} has no coordinate reference system", file=path)
        try:
            out = warp_band(ds.dataset, grid.crs, grid.transform, grid.shape, resampling=resampling,
                            fill=fill, dtype=dtype)
        except Exception as exc:
            raise RasterReadError(f"{path}: cannot read or resample {what} onto the DSM grid "
                                  f"({cause_text(exc, str(path))})") from None
    return out


def write_dem(path, heights, crs, transform) -> None:
    """Write a single-band float32 GeoTIFF (deflate, nodata NaN), atomically: a failure is a
    :class:`~prismstation.errors.WriteError` and leaves no file.

    Parameters
    ----------
    heights : ndarray (rows, cols)
        Metres, NaN for voids.
    crs : anything ``rasterio.crs.CRS.from_user_input`` takes
    transform : affine.Affine or 6 numbers (a, b, c, d, e, f)
    """
    h = np.asarray(heights, np.float32)
    if h.ndim != 2:
        raise ValueError(f"heights must be 2-D, got shape {h.shape}")
    profile = dict(driver="GTiff", width=h.shape[1], height=h.shape[0], count=1,
                   dtype="float32", crs=CRS.from_user_input(crs),
                   transform=Affine(*tuple(transform)[:6]), nodata=np.nan, compress="deflate")
    if h.shape[0] >= 256 and h.shape[1] >= 256:
        profile.update(tiled=True, blockxsize=256, blockysize=256)
    with atomic_path(path, check=raster_check(h.shape[1], h.shape[0], 1)) as tmp:
        with rasterio.open(tmp, "w", **profile) as ds:
            ds.write(h, 1)


def local_metric_transform(crs, transform, shape) -> tuple[float, ...]:
    """The grid's pixel → metres affine ``(a, b, 0, d, e, 0)`` in a local frame at its centre.

    Projected CRS: the transform's terms times the CRS's linear unit (metres, feet...).
    Geographic CRS (EPSG:4326 SRTM, Copernicus GLO-30...): degrees become metres east/north
    on the CRS's ellipsoid at the grid's centre latitude φ0 (``M(φ0)`` per radian of latitude,
    ``N(φ0)·cos φ0`` per radian of longitude): an equirectangular tangent frame, whose scale
    departs from the true one by ``|cos φ / cos φ0 − 1|`` (about 1.2 % at the edge of a 1° tile at
    45° N) — the DEM shift is estimated in grid pixels, so this only scales slope thresholds
    and the shift's conversion to metres.
    """
    from pyproj import CRS as ProjCRS

    t = Affine(*tuple(transform)[:6])
    pc = ProjCRS.from_user_input(crs.to_wkt() if hasattr(crs, "to_wkt") else crs)
    if pc.is_geographic:
        ell = pc.ellipsoid
        a_ax, inv_f = ell.semi_major_metre, ell.inverse_flattening
        e2 = 0.0 if not inv_f else (2 - 1 / inv_f) / inv_f
        rows, cols = shape
        lat0 = np.radians(t.d * cols / 2 + t.e * rows / 2 + t.f)
        w = 1 - e2 * np.sin(lat0) ** 2
        m_per_rad_lat = a_ax * (1 - e2) / w ** 1.5
        m_per_rad_lon = a_ax / np.sqrt(w) * np.cos(lat0)
        kx, ky = np.radians(1.0) * m_per_rad_lon, np.radians(1.0) * m_per_rad_lat
        return (t.a * kx, t.b * kx, 0.0, t.d * ky, t.e * ky, 0.0)
    unit = pc.axis_info[0].unit_conversion_factor if pc.axis_info else 1.0
    return (t.a * unit, t.b * unit, 0.0, t.d * unit, t.e * unit, 0.0)


# ------------------------------------------------------------ a DEM read window by window


def dem_height_kind(path) -> str | None:
    """The height kind a DEM file states: a DSM of prismstation's own says it in its
    ``HEIGHTS`` tag; another file in the vertical part of a compound CRS (a vertical datum
    named after an ellipsoid: ``"ellipsoidal"``, any other: ``"orthometric"``). None when the
    file says nothing (a plain SRTM or Copernicus GeoTIFF: orthometric by convention)."""
    with rasterio.Env(GTIFF_REPORT_COMPD_CS="YES"), open_raster(path, "DEM") as ds:
        kind = (ds.tags().get("HEIGHTS") or "").lower()
        if kind in ("ellipsoidal", "orthometric"):
            return kind
        if ds.crs is None:
            return None
        try:
            crs = pyproj.CRS.from_wkt(ds.crs.to_wkt())
        except pyproj.exceptions.CRSError:
            return None
    if not crs.is_compound:
        return None
    vertical = crs.sub_crs_list[-1]
    names = f"{vertical.name} {vertical.datum.name if vertical.datum else ''}".lower()
    return "ellipsoidal" if "ellipsoid" in names else "orthometric"


def read_dem_window(path, crs, transform, shape, *, resampling: str = "bilinear",
                    what: str = "DEM") -> np.ndarray:
    """Band 1 of the DEM ``path`` on the grid ``(crs, transform, shape)``: float32 metres as the
    file holds them, NaN where void or outside it. Only the part of the file the grid needs is
    read (:func:`prismstation.io.reproject.warp_band`), so a tile
    of a large DSM costs a tile's memory. ``resampling``: a ``rasterio.enums.Resampling`` name
    (``"min"`` and ``"max"`` give a height range)."""
    path = Path(path)
    with open_raster(path, what) as ds:
        if ds.crs is None:
            raise InputError(f"{what} has no coordinate reference system", file=path)
        nodata = ds.nodata
        if nodata is None and ds.dtypes[0] == "int16":
            nodata = SRTM_VOID                  # SRTM voids even without a nodata tag
        rows, cols = (int(v) for v in shape)
        try:
            out = warp_band(ds.dataset, crs, transform, (rows, cols), resampling=resampling,
                            src_nodata=nodata, fill=np.nan, dtype=np.float32)
        except (RasterioError, CPLE_BaseError, KeyError) as exc:
            raise RasterReadError(f"{path}: cannot read {what} onto a grid "
                                  f"({cause_text(exc, str(path))})") from None
        out *= np.float32(height_metres_per_unit(ds.crs.to_wkt(), path))
    out[~np.isfinite(out)] = np.nan
    return out


def dem_bounds(path, crs, what: str = "DEM") -> tuple[float, float, float, float]:
    """``(x0, y0, x1, y1)``: the extent of the DEM ``path`` in ``crs`` (its corners and edges
    transformed)."""
    with open_raster(path, what) as ds:
        if ds.crs is None:
            raise InputError(f"{what} has no coordinate reference system", file=path)
        return tuple(transform_bounds(ds.crs, CRS.from_user_input(crs), *ds.bounds, densify_pts=21))


def _same_horizontal(file_crs, crs) -> bool:
    """Whether the file's CRS (its horizontal part, when compound) is ``crs``."""
    try:
        a = pyproj.CRS.from_wkt(file_crs.to_wkt())
        b = pyproj.CRS.from_user_input(crs.to_wkt() if hasattr(crs, "to_wkt") else crs)
    except pyproj.exceptions.CRSError:
        return False
    if a.is_compound:
        a = a.sub_crs_list[0]
    return a.equals(b, ignore_axis_order=True)


def read_dem_cells(path, crs, bounds, *, min_cell: float = 0.0, what: str = "DEM") -> tuple[np.ndarray, tuple]:
    """The DEM's heights over ``bounds`` ``(x0, y0, x1, y1)`` of ``crs`` and one cell beyond, on
    a north-up grid of ``crs``: ``(array, transform)``, float32 as the file holds them, NaN in
    voids and outside the file. A file that is a north-up grid of ``crs`` gives its own cells (a
    window read: nothing resampled, so a bilinear sample of the result is a bilinear sample of
    the file); another is warped (bilinear, :func:`read_dem_window`) onto a grid of its own cell
    size in metres, or ``min_cell`` if coarser."""
    path = Path(path)
    x0, y0, x1, y1 = bounds
    with open_raster(path, what) as ds:
        if ds.crs is None:
            raise InputError(f"{what} has no coordinate reference system", file=path)
        t = ds.transform
        if t.b == 0 and t.d == 0 and t.a > 0 and t.e < 0 and _same_horizontal(ds.crs, crs):
            c0 = int(np.floor((x0 - t.c) / t.a)) - 1
            c1 = int(np.ceil((x1 - t.c) / t.a)) + 1
            r0 = int(np.floor((y1 - t.f) / t.e)) - 1
            r1 = int(np.ceil((y0 - t.f) / t.e)) + 1
            out = np.full((r1 - r0, c1 - c0), np.nan, np.float32)
            a0, b0, a1, b1 = max(c0, 0), max(r0, 0), min(c1, ds.width), min(r1, ds.height)
            if a1 > a0 and b1 > b0:
                v = ds.read(1, window=Window(a0, b0, a1 - a0, b1 - b0), masked=True)
                v = v.astype(np.float32).filled(np.nan)
                if ds.dtypes[0] == "int16":
                    v[v <= SRTM_VOID] = np.nan
                out[b0 - r0:b1 - r0, a0 - c0:a1 - c0] = v * np.float32(height_metres_per_unit(ds.crs.to_wkt(), path))
            out[~np.isfinite(out)] = np.nan
            return out, (t.a, 0.0, t.c + t.a * c0, 0.0, t.e, t.f + t.e * r0)
        a, b, _, d, e, _ = local_metric_transform(ds.crs, t, (ds.height, ds.width))
    cell = max(min(float(np.hypot(a, d)), float(np.hypot(b, e))), min_cell)
    c0, r0 = np.floor(x0 / cell) - 1, np.ceil(y1 / cell) + 1
    shape = (int(r0 - np.floor(y0 / cell)) + 1, int(np.ceil(x1 / cell) - c0) + 1)
    transform = (cell, 0.0, c0 * cell, 0.0, -cell, r0 * cell)
    return read_dem_window(path, crs, transform, shape, what=what), transform
