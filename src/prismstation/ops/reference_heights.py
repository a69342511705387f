"""Reference heights: a reference DEM (SRTM ``.hgt`` or GeoTIFF, any CRS) read through
:func:`prismstation.io.dem.read_dem` onto a 30 m north-up grid in the scene CRS covering every
view, made ellipsoidal through the project's geoid; :class:`DemHeights` samples it bilinearly
(heights for the linked cursor and for points without parallax).
"""
from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from prismstation.errors import InputError, PrismError
from prismstation.io.dem import dem_height_kind, read_dem
from prismstation.io.geoid import find_grid, grid_geoid
from prismstation.io.project import project_geoid
from prismstation.ops.progress import ProgressFn, checkpoint

SPACING_M = 30.0
MARGIN_M = 3000.0


class DemHeights:
    """Ellipsoidal heights of a :class:`~prismstation.io.dem.DemGrid` at map points.

    Call with ``en`` ``(n, 2)`` map metres of the grid's CRS; returns ``(n,)`` metres, NaN
    outside the grid or in voids (bilinear between pixel centres).
    """

    def __init__(self, grid, path=None):
        self.grid = grid
        self.path = path
        self._inv = ~grid.transform

    def __call__(self, en) -> np.ndarray:
        en = np.asarray(en, dtype=float).reshape(-1, 2)
        col, row = self._inv * (en[:, 0], en[:, 1])
        return ndimage.map_coordinates(self.grid.heights, [np.asarray(row) - 0.5, np.asarray(col) - 0.5],
                                       order=1, mode="constant", cval=np.nan, prefilter=False)


def scene_grid(scene, spacing: float = SPACING_M, margin: float = MARGIN_M):
    """``(transform, shape)`` of a north-up grid in the scene CRS covering every view's image;
    ``transform`` ``(a, 0, c, 0, e, f)`` (rasterio's order)."""
    c = np.vstack([v.footprint() for v in scene.views.values()])
    x0, y0 = c.min(axis=0) - margin
    x1, y1 = c.max(axis=0) + margin
    shape = (int(math.ceil((y1 - y0) / spacing)), int(math.ceil((x1 - x0) / spacing)))
    return (float(spacing), 0.0, float(x0), 0.0, -float(spacing), float(y1)), shape


def load_for_scene(path, project, progress: ProgressFn | None = None) -> DemHeights:
    """Read the DEM at ``path`` onto the scene's grid (:func:`scene_grid`), ellipsoidal through
    the project's geoid."""
    transform, shape = scene_grid(project.scene)
    checkpoint(progress, 0.0, "reading the DEM")
    grid = read_dem(path, project.scene.crs, transform, shape, geoid=project_geoid(project))
    if not np.isfinite(grid.heights).any():
        raise InputError("the DEM does not cover the scene", file=path)
    checkpoint(progress, 1.0, "done")
    return DemHeights(grid, path)


def height_sigma(heights: DemHeights, sigma_m: float):
    """The σ (m) of the reference's height at map points ``en`` ``(n, 2)`` → ``(n,)``: its own
    ``sigma_m`` ⊕ what its resolution cannot hold on a slope — a cell of ``d`` metres (the
    file's own, :attr:`~prismstation.io.dem.DemGrid.source_cell_m`, at least the grid's)
    on a slope ``s`` spans ``s·d`` metres of height, a point anywhere in it ``s·d/√12`` from
    the cell's mean. The slope is the gradient of the grid the heights are read on, bilinear
    at the points (0 outside)."""
    grid = heights.grid
    spacing = abs(float(grid.transform.a))
    cell = max([spacing] + [float(c) for c in (getattr(grid, "source_cell_m", None) or ()) if np.isfinite(c)])
    gy, gx = np.gradient(np.asarray(grid.heights, float), spacing)
    slope = np.nan_to_num(np.hypot(gx, gy), nan=0.0)
    inv = ~grid.transform

    def sigma(en) -> np.ndarray:
        en = np.asarray(en, dtype=float).reshape(-1, 2)
        col, row = inv * (en[:, 0], en[:, 1])
        s = ndimage.map_coordinates(slope, [np.asarray(row) - 0.5, np.asarray(col) - 0.5], order=1,
                                    mode="constant", cval=0.0, prefilter=False)
        return np.hypot(float(sigma_m), s * cell / math.sqrt(12.0))
    return sigma


#: how far (m) a project's constant geoid may lie from EGM96 at the scene before an orientation
#: from a reference DEM says its heights may be in another datum: beyond a reference's own
#: height σ (SRTM 2–4 m) and the few metres that separate global and national geoids
DATUM_TOLERANCE_M = 5.0


def datum_note(project, reference) -> str:
    """What an orientation from the reference DEM file ``reference`` could not check of its
    height datum, "" when nothing is amiss: a reference not stated ellipsoidal
    (:func:`~prismstation.io.dem.dem_height_kind`) is read through the project's geoid, and a
    constant one more than :data:`DATUM_TOLERANCE_M` from EGM96 at the scene's centre reads an
    SRTM-like reference (heights above EGM96) that far off — and the orientation's heights
    with it, which nothing without GCPs can see. Nothing is said without a grid to compare."""
    setting = project.geoid or {}
    grid = find_grid()
    if setting.get("kind") != "constant" or grid is None:
        return ""
    try:
        if dem_height_kind(reference) == "ellipsoidal":
            return ""
        e, n = project.scene.views[project.scene.reference_view].footprint().mean(axis=0)
        egm = float(grid_geoid(str(grid)).undulation(np.array([e]), np.array([n]), project.scene.crs)[0])
    except PrismError:
        return ""
    off = egm - float(setting.get("value") or 0.0)
    if not math.isfinite(off) or abs(off) <= DATUM_TOLERANCE_M:
        return ""
    return (f"not checked: the reference's height datum — the project's geoid is a constant "
            f"{float(setting.get('value') or 0.0):g} m where EGM96 lies {egm:.1f} m above the ellipsoid: a "
            f"reference above EGM96 (SRTM, Copernicus) is read {abs(off):.0f} m {'low' if off > 0 else 'high'}, "
            "and this orientation's heights with it; give the project its reference's geoid (Tools ▸ Geoid…, "
            "new --geoid auto), or tag an ellipsoidal reference HEIGHTS=ellipsoidal")
