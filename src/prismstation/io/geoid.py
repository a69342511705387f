"""Geoid undulation ``Ngeoid`` (metres) so that ``h = H + Ngeoid`` (docs/model.md §1).

A constant, or a geoid grid (EGM96 ``egm96_15.gtx`` or any grid GDAL reads) sampled
bilinearly at the points' geographic position (converted from the project CRS by pyproj at
every point: :func:`prismstation.io.reproject.grid_pixels`).
Never a silent no-op: a missing grid is an error, not zero.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import pyproj
import rasterio
from scipy.ndimage import map_coordinates

from prismstation.errors import InputError, RasterReadError
from prismstation.io.inputs import open_raster_file
from prismstation.io.reproject import grid_pixels

GRID_NAMES = ("egm96_15.gtx", "us_nga_egm96_15.tif", "egm08_25.gtx", "us_nga_egm08_25.tif")


def search_paths() -> list[Path]:
    """Where geoid grids are looked for: PROJ's data directories, its user directory, Debian's."""
    paths = [Path(p) for p in pyproj.datadir.get_data_dir().split(os.pathsep) if p]
    try:
        paths.append(Path(pyproj.datadir.get_user_data_dir()))
    except Exception:  # pragma: no cover - depends on the PROJ build
        pass
    paths.append(Path("/usr/share/proj"))
    paths.append(Path("/usr/local/share/proj"))
    return paths


def find_grid(names=GRID_NAMES) -> Path | None:
    """The first geoid grid found on :func:`search_paths`, or None."""
    for d in search_paths():
        for n in names:
            if (d / n).is_file():
                return d / n
    return None


@dataclass(frozen=True)
class ConstantGeoid:
    value: float

    def undulation(self, E, N, crs=None) -> np.ndarray:
        return np.full(np.shape(E), float(self.value))

    def describe(self) -> str:
        return f"constant {self.value:g} m"

    def to_dict(self) -> dict:
        return {"kind": "constant", "value": self.value}


class GridGeoid:
    """A geoid grid read once into memory (EGM96 15′ is 4 MB)."""

    def __init__(self, path):
        self.path = Path(path)
        try:
            with open_raster_file(self.path, "geoid grid") as ds:
                if ds.crs is not None and not ds.crs.is_geographic:
                    raise InputError("a geoid grid must be in geographic coordinates", self.path)
                grid = ds.read(1, masked=True).astype(float).filled(np.nan)
                t = ds.transform
        except (rasterio.errors.RasterioError, RasterReadError) as exc:
            raise InputError(f"cannot read the geoid grid: {str(exc).removeprefix(f'{self.path}: ')}",
                             self.path) from None
        if t.b or t.d:
            raise InputError("a rotated geoid grid is not supported", self.path)
        self._grid = grid
        self._transform = t
        self._wraps = abs(grid.shape[1] * t.a - 360.0) < 1e-6

    def undulation(self, E, N, crs) -> np.ndarray:
        """Undulation at map points ``E``, ``N`` (any shape) of ``crs``; NaN outside the grid."""
        col, row = grid_pixels(E, N, crs, "EPSG:4326", self._transform)
        col, row = np.asarray(col) - 0.5, np.asarray(row) - 0.5     # cell centres at integers
        grid = self._grid
        if self._wraps:
            col = np.mod(col, grid.shape[1])
            grid = np.concatenate([grid, grid[:, :1]], axis=1)
        return map_coordinates(grid, [np.ravel(row), np.ravel(col)], order=1, mode="constant",
                               cval=np.nan).reshape(np.shape(col))

    def describe(self) -> str:
        return f"grid {self.path.name}"

    def to_dict(self) -> dict:
        return {"kind": "grid", "path": str(self.path)}


@lru_cache(maxsize=8)
def grid_geoid(path: str) -> GridGeoid:
    """The geoid grid at ``path``, read once a process (EGM96 15′: 4 MB, ~40 ms)."""
    return GridGeoid(path)


def geoid_from_setting(setting: dict | None, base_dir=None, default: float = 0.0):
    """Geoid from a project's setting ``{"kind": "constant", "value": 55}`` or
    ``{"kind": "grid", "path": "..."}`` (relative to ``base_dir``) or ``{"kind": "auto"}``
    (the first grid on PROJ's paths, else the constant ``default``)."""
    setting = setting or {"kind": "constant", "value": default}
    kind = setting.get("kind")
    if kind == "constant":
        return ConstantGeoid(float(setting.get("value", default)))
    if kind == "grid":
        p = Path(setting["path"])
        if not p.is_absolute() and base_dir is not None:
            p = Path(base_dir) / p
        if not p.is_file():
            raise InputError(f"geoid grid not found: {p}", setting.get("path"))
        return grid_geoid(str(p))
    if kind == "auto":
        g = find_grid()
        return grid_geoid(str(g)) if g else ConstantGeoid(float(setting.get("value", default)))
    raise InputError(f"unknown geoid setting {setting!r}")


def to_ellipsoidal(H, geoid, E=None, N=None, crs=None) -> np.ndarray:
    """Ellipsoidal heights ``h = H + Ngeoid`` (docs/model.md §1).

    Parameters
    ----------
    H : array_like
        Orthometric heights (metres), NaN allowed.
    geoid : float or object with ``undulation(E, N, crs) -> array``
        A constant undulation (metres) or a geoid model (e.g. ``io.geoid.GridGeoid``).
    E, N : array_like, optional
        Map coordinates of ``H`` (same shape) in ``crs``; needed for a geoid model.
    crs : optional
        CRS of ``E, N``.
    """
    H = np.asarray(H, float)
    if isinstance(geoid, (int, float, np.floating, np.integer)):
        return H + float(geoid)
    if not hasattr(geoid, "undulation"):
        raise TypeError("geoid must be a number or have an undulation(E, N, crs) method")
    if E is None or N is None:
        raise ValueError("a geoid model needs the map coordinates E, N of the heights")
    return H + np.asarray(geoid.undulation(np.asarray(E, float), np.asarray(N, float), crs), float)


def undulation_on_grid(geoid, grid, max_samples: int = 256) -> np.ndarray:
    """Geoid undulation (m) at every cell centre of ``grid`` (an :class:`io.dem.DemGrid`, or
    anything with its ``shape``, ``crs`` and ``transform`` — an ``Affine`` or its six numbers):
    exact on a coarse lattice of at most ``max_samples`` per axis, bilinear in between (geoids
    vary over kilometres)."""
    rows, cols = grid.shape
    exact = rows * cols <= max_samples ** 2 or rows < 2 or cols < 2
    r = np.arange(rows) if exact else np.unique(np.linspace(0, rows - 1, max_samples).round())
    c = np.arange(cols) if exact else np.unique(np.linspace(0, cols - 1, max_samples).round())
    cc, rr = np.meshgrid(c + 0.5, r + 0.5)
    ta, tb, tc, td, te, tf = tuple(grid.transform)[:6]
    e = tc + cc * ta + rr * tb
    n = tf + cc * td + rr * te
    u = np.asarray(geoid.undulation(e, n, grid.crs), float).reshape(cc.shape)
    if exact:
        return u
    if np.all(u == u.flat[0]):                    # a constant geoid
        return np.full(grid.shape, u.flat[0])
    # separable bilinear interpolation in cell-index space: along columns, then along rows
    along = np.stack([np.interp(np.arange(cols), c, row) for row in u])      # (len(r), cols)
    i = np.clip(np.searchsorted(r, np.arange(rows), side="right") - 1, 0, len(r) - 2)
    t = ((np.arange(rows) - r[i]) / (r[i + 1] - r[i]))[:, None]
    return (1 - t) * along[i] + t * along[i + 1]
