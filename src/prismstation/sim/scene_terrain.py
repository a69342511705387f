"""The terrain under a simulated scene: which relief, over what area, and its statistics.

``fractal`` (the default: ridges and valleys, :func:`terrain.synthesize_relief`), ``smooth``
(rolling hills of 6 % mean slope, :func:`terrain.smooth_relief`) or ``dem`` (a real DEM,
:mod:`sim.dem_terrain`), optionally lowered (heights scaled about their mean over the ground N
sees). The grid (5 m cells up to 6,000 px, 10 m above) covers everything any view can see
between the terrain's lowest and highest heights; its heights are orthometric metres.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from prismstation.errors import InputError
from prismstation.sim import geometry as geo
from prismstation.sim.scenario import GEOID
from prismstation.sim.terrain import (SMOOTH_LAMBDA_MIN_M, SMOOTH_MEAN_SLOPE, Grid, cell_centres, inside_polygon,
                                      scale_relief, smooth_relief, synthesize_relief,
                                      terrain_statistics)

RELIEF = 1400.0
TERRAINS = ("fractal", "smooth", "dem")
#: heights (m, orthometric) the smooth terrain's grid is first laid out for
SMOOTH_FIRST_BOUND_M = 1500.0


def scene_relief(size: int) -> float:
    """Relief (m) of a ``size`` px fractal scene: 1400 m on a full 14,000 px (35 km) scene
    like Gonçalves's; smaller scenes get less (∝ extent^0.35) so that slopes stay those of
    real hilly terrain instead of 1400 m walls in 5 km, which no stereo pair at ±26° could
    match."""
    return RELIEF * min(1.0, (size / 14000.0) ** 0.35)


def grid_spacing(size: int) -> float:
    """Cell (m) of the terrain grid of a ``size`` px scene."""
    return 5.0 if size <= 6000 else 10.0


def ground_bbox(scenario, h_lo, h_hi, margin=250.0):
    """Map bounding box of everything any view's pixels can see between two ellipsoidal
    heights (m): ``(lo, hi)``, each (E, N)."""
    s = scenario.size
    corners = np.array([[0, 0], [s, 0], [0, s], [s, s]], dtype=float)
    pts = []
    for view in scenario.views.values():
        o, d = geo.pixel_rays(scenario.orbit, view, corners)
        pts += [geo.ray_at_height(o, d, h) for h in (h_lo, h_hi)]
    pts = np.concatenate(pts)
    return pts.min(axis=0) - margin, pts.max(axis=0) + margin


def grid_over(lo, hi, spacing):
    """``(e0, n0, (rows, cols))`` of a grid of ``spacing`` cells covering the box lo..hi."""
    cols = int(np.ceil((hi[0] - lo[0]) / spacing))
    rows = int(np.ceil((hi[1] - lo[1]) / spacing))
    e0 = np.floor(lo[0] / spacing) * spacing
    n0 = np.ceil(hi[1] / spacing) * spacing
    return e0, n0, (rows + 1, cols + 1)


def n_footprint(scenario, h: float) -> np.ndarray:
    """The ground N's image corners see at ellipsoidal height ``h``: (4, 2) E, N in order."""
    s = scenario.size
    corners = np.array([[0, 0], [s, 0], [s, s], [0, s]], dtype=float)
    o, d = geo.pixel_rays(scenario.orbit, scenario.views["N"], corners)
    return geo.ray_at_height(o, d, h)


@dataclass
class SceneTerrain:
    """``ortho`` (orthometric heights, m) over the box ``lo``..``hi`` (E, N); ``h_min``,
    ``h_max`` bound its ellipsoidal heights; ``info`` goes into the truth."""

    ortho: Grid
    lo: np.ndarray
    hi: np.ndarray
    h_min: float
    h_max: float
    info: dict = field(default_factory=dict)


def check_terrain(kind: str, has_dem: bool, relief_scale: float) -> None:
    """Bad terrain arguments → :class:`InputError`."""
    if kind not in TERRAINS:
        raise InputError(f"--terrain must be one of {', '.join(TERRAINS)}, got {kind!r}")
    if not (np.isfinite(relief_scale) and 0 < relief_scale <= 1):
        raise InputError(f"--relief-scale must be in (0, 1], got {relief_scale}")
    if (kind == "dem") != has_dem:
        raise InputError("--terrain dem needs --terrain-dem, and --terrain-dem needs --terrain dem")


def make_terrain(scenario, kind: str = "fractal", rng=None, dem=None,
                 relief_scale: float = 1.0, wavelength_m: float | None = None) -> SceneTerrain:
    """The terrain of ``kind`` under ``scenario`` (``rng`` for the synthetic ones, ``dem`` a
    :class:`sim.dem_terrain.DemTerrain` placed at the scenario's centre), its heights scaled by
    ``relief_scale`` about their mean over the ground N sees, with its statistics;
    ``wavelength_m`` the smooth terrain's shortest wavelength (default
    :data:`~prismstation.sim.terrain.SMOOTH_LAMBDA_MIN_M`)."""
    check_terrain(kind, dem is not None, relief_scale)
    spacing = grid_spacing(scenario.size)
    info = {"kind": kind, "relief_scale": float(relief_scale)}
    if kind == "fractal":
        # as it always was: the grid for 0 .. relief, and the same draws from rng
        relief = scene_relief(scenario.size)
        h_min, h_max = GEOID - 1.0, GEOID + relief + 1.0
        lo, hi = ground_bbox(scenario, h_min - 50.0, h_max + 50.0)
        e0, n0, shape = grid_over(lo, hi, spacing)
        ortho = synthesize_relief(shape, spacing, rng, relief=relief)
        inside = _inside(scenario, e0, n0, spacing, shape, 0.5 * relief)
        ortho = _lower(ortho, inside, relief_scale, info)
        terrain = SceneTerrain(Grid(ortho, e0, n0, spacing), lo, hi, h_min, h_max, info)
    else:
        if kind == "smooth":
            seed = int(rng.integers(2 ** 63))
            info["target_mean_slope_pct"] = 100.0 * SMOOTH_MEAN_SLOPE
            if wavelength_m is not None:
                info["shortest_wavelength_m"] = float(wavelength_m)

            def heights(e0, n0, shape, inside):
                return smooth_relief(shape, spacing, np.random.default_rng(seed), inside,
                                     lambda_min=wavelength_m or SMOOTH_LAMBDA_MIN_M)

            bound = (0.0, SMOOTH_FIRST_BOUND_M)
        else:
            info.update(dem.describe())

            def heights(e0, n0, shape, inside):
                h, void = dem.heights(e0, n0, shape, spacing)
                info["void_filled_pct"] = round(100.0 * void, 3)
                return h

            bound = _dem_first_bound(scenario, dem)
        terrain = _fitted(scenario, spacing, bound, heights, relief_scale, info)
    footprint = n_footprint(scenario, GEOID + float(np.median(terrain.ortho.values)))
    info["statistics"] = terrain_statistics(terrain.ortho, footprint)
    return terrain


def _inside(scenario, e0, n0, spacing, shape, height) -> np.ndarray:
    """Cells of the grid inside N's footprint at orthometric ``height``."""
    grid = Grid(np.empty(shape, np.float32), e0, n0, spacing)
    return inside_polygon(n_footprint(scenario, GEOID + height), *cell_centres(grid))


def _lower(ortho, inside, relief_scale, info):
    if relief_scale == 1.0:
        return ortho
    ortho, mean = scale_relief(ortho, inside, relief_scale)
    info["scaled_about_m"] = round(mean, 3)
    return ortho


def _fitted(scenario, spacing, bound, heights, relief_scale, info) -> SceneTerrain:
    """Lay the grid out for heights within ``bound`` (orthometric m), make them, and lay it
    out again wider while they leave it (the box must hold all any view sees)."""
    for _ in range(4):
        lo, hi = ground_bbox(scenario, GEOID + bound[0] - 51.0, GEOID + bound[1] + 51.0)
        e0, n0, shape = grid_over(lo, hi, spacing)
        inside = _inside(scenario, e0, n0, spacing, shape, 0.5 * (bound[0] + bound[1]))
        ortho = _lower(heights(e0, n0, shape, inside), inside, relief_scale, info)
        h0, h1 = float(ortho.min()), float(ortho.max())
        if bound[0] <= h0 and h1 <= bound[1]:
            return SceneTerrain(Grid(ortho, e0, n0, spacing), lo, hi, GEOID + h0 - 1.0,
                                GEOID + h1 + 1.0, info)
        bound = (min(bound[0], h0 - 50.0), max(bound[1], h1 + 50.0))
    raise RuntimeError(f"the terrain's heights {h0:.0f}..{h1:.0f} m keep leaving its grid")


def _dem_first_bound(scenario, dem) -> tuple[float, float]:
    """The DEM's height range (m) over what the views see, from its heights on a 90 m
    lattice, widened until the box those heights make is covered."""
    lo, hi = ground_bbox(scenario, GEOID, GEOID)
    for _ in range(6):
        e0, n0, shape = grid_over(lo, hi, 90.0)
        h, _ = dem.heights(e0, n0, shape, 90.0)
        bound = (float(h.min()) - 50.0, float(h.max()) + 50.0)
        lo2, hi2 = ground_bbox(scenario, GEOID + bound[0] - 51.0, GEOID + bound[1] + 51.0)
        if np.all(lo2 >= lo) and np.all(hi2 <= hi):
            return bound
        lo, hi = np.minimum(lo, lo2), np.maximum(hi, hi2)
    return bound
