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
from pathlib import Path

import numpy as np
import rasterio
from rasterio._err import CPLE_BaseError
from rasterio.crs import CRS
from rasterio.errors import RasterioError
from rasterio.transform import Affine

from prismstation.errors import InputError, RasterReadError
from prismstation.io.atomic import atomic_path, cause_text, raster_check
from prismstation.io.geoid import to_ellipsoidal
from prismstation.io.reproject import warp_array, warp_band
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
    """

    heights: np.ndarray
    crs: CRS
    transform: Affine
    height_kind: str = "orthometric"
    path: str | None = None
    source_cell_m: tuple[float, float] | None = None

    @property
    def shape(self) -> tuple[int, int]:
        return self.heights.shape


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


def _read_source(path: Path, what: str):
    with open_raster(path, what) as ds:
        if ds.crs is None:
            raise InputError(f"{what} has no coordinate reference system", file=path)
        arr = ds.read(1, masked=True).astype(np.float64).filled(np.nan)  # RasterReadError
        if ds.dtypes[0] == "int16":
            arr[arr <= SRTM_VOID] = np.nan        # SRTM voids even without a nodata tag
        arr[~np.isfinite(arr)] = np.nan
        return arr, ds.crs, ds.transform


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
        If given, the stored (orthometric) heights are converted to ellipsoidal.
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
    src, src_crs, src_transform = _read_source(path, what)
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
    if geoid is not None:
        if isinstance(geoid, (int, float)):
            heights = to_ellipsoidal(heights, geoid)
        else:
            E, N = grid_coordinates(out_t, heights.shape)
            heights = to_ellipsoidal(heights, geoid, E, N, out_crs)
        kind = "ellipsoidal"
    a, b, _, d, e, _ = local_metric_transform(src_crs, src_transform, src.shape)
    return DemGrid(heights, out_crs, out_t, kind, str(path), (float(np.hypot(a, d)), float(np.hypot(b, e))))


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
