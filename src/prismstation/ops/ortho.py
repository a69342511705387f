"""Orthoimages, once: ``prismstation ortho`` and Tools ▸ Orthoimage… both build an
:class:`OrthoRequest` and call :func:`export_orthos`.

Each view is resampled through the project's fitted sensor model — the solution's
``model.ground_to_image`` with its biases, whatever the model (:mod:`prismstation.core.models.sensor`)
— onto a DEM (the project's DSM, a reference DEM of any CRS, orthometric heights made
ellipsoidal through the project's geoid) or a constant height, on a north-up grid of the scene's
CRS aligned on multiples of the posting (so the orthos of several views share their cells). The
grid covers what the view sees between the lowest and highest heights of the DEM there (or the
ground under a window of the reference view) within the DEM. Tiles of
:data:`TILE` × :data:`TILE` cells run as Dask tasks through the DSM's machinery
(:func:`prismstation.ops.dsm_tiles.run_tiles`: threads, processes or a cluster, progress and
cancel); each reads only its DEM window and the image window it needs and is written into the
file as it arrives (:mod:`prismstation.io.ortho`), so memory does not grow with the scene.

The expected planimetric accuracy (:mod:`prismstation.ops.ortho_accuracy`) goes into each file's
metadata and the result.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from prismstation.core.surfaces.dsm_grid import grid_over
from prismstation.errors import InputError, ModelError
from prismstation.io.atomic import check_writable
from prismstation.io.dem import dem_bounds, dem_height_kind
from prismstation.io.jsonfile import dumps
from prismstation.io.ortho import image_dtype, ortho_dtype, write_ortho
from prismstation.io.project import project_geoid
from prismstation.ops.dsm_tiles import run_tiles
from prismstation.ops.ortho_accuracy import OrthoAccuracy, expected_accuracy
from prismstation.ops.ortho_tiles import Heights, OrthoTile, run_ortho_tile
from prismstation.ops.predict import known_ground
from prismstation.ops.progress import checkpoint, scaled

DEM_KINDS = ("auto", "orthometric", "ellipsoidal")
RESAMPLINGS = ("bilinear", "cubic")
#: cells per side of a tile
TILE = 1024
#: spacing (m) of the geoid's coarse grid over an ortho
UNDULATION_SPACING_M = 500.0
#: cells per side of the coarse grid the DEM's height range is read on, at most
RANGE_CELLS = 256
#: share of each view's progress the tiles take (the rest: planning and the COG)
TILES_SHARE = 0.93


@dataclass(frozen=True)
class OrthoRequest:
    """What to make.

    ``output``: the GeoTIFF (several views: ``NAME_VIEW.tif`` beside it). ``views``: view
    names (or image file names), None for the reference view. ``dem``: a DEM file (the
    project's DSM, a reference DEM), ``dem_kind`` its heights (``auto``: as the file states,
    else orthometric), ``dem_sigma_m`` its height σ when known. Without a DEM: the constant
    orthometric ``height_m``, else the project's reference DEM, else the fit's mean height (a
    constant and the mean height with a warning). ``posting_m``: the grid's cell (default the
    reference view's pixel, rounded: :func:`default_posting`). ``window``: ``(col, row, w, h)``
    pixels of the reference view, None for each whole image. ``resampling``: ``bilinear`` or
    ``cubic``. ``scheduler``, ``workers``: see :mod:`prismstation.ops.dsm_tiles`."""

    output: str
    views: tuple | None = None
    dem: str | None = None
    dem_kind: str = "auto"
    dem_sigma_m: float | None = None
    height_m: float | None = None
    posting_m: float | None = None
    window: tuple | None = None
    resampling: str = "bilinear"
    scheduler: object = None
    workers: int | None = None


@dataclass(frozen=True)
class OrthoView:
    """One written ortho: its ``path``, ``view``, grid (``transform``, ``shape``), the share of
    its cells with data, the largest interpolation error of its positions (px), its expected
    accuracy and the tags written."""

    path: str
    view: str
    transform: tuple
    shape: tuple
    valid_percent: float
    max_error_px: float
    accuracy: OrthoAccuracy
    tags: dict = field(default_factory=dict)


@dataclass(frozen=True)
class OrthoExport:
    """What :func:`export_orthos` made: the request, each view's :class:`OrthoView`, the heights
    in words and the warnings (a constant height, a DEM's kind assumed…)."""

    request: OrthoRequest
    orthos: tuple
    heights: str
    warnings: tuple = ()


def resolve_views(scene, names) -> tuple:
    """View names of ``names`` (``None``: the reference view; ``"all"``; a view name; an image
    file's name or stem); an unknown one is an :class:`InputError` listing the views."""
    if names is None:
        return (scene.reference_view,)
    if isinstance(names, str):
        names = (names,)
    out = []
    for n in names:
        if n == "all":
            out.extend(scene.views)
            continue
        if n in scene.views:
            out.append(n)
            continue
        by_image = [v for v, view in scene.views.items()
                    if view.image and n in (Path(view.image).name, Path(view.image).stem)]
        if not by_image:
            raise InputError(f"--view {n}: not a view of the project ({', '.join(scene.views)}, all, "
                             "or an image's file name)")
        out.extend(by_image)
    return tuple(dict.fromkeys(out))


def output_paths(output, views) -> dict:
    """View → file: ``output`` itself for one view, ``STEM_VIEW.tif`` beside it for several."""
    p = Path(output)
    if len(views) == 1:
        return {views[0]: str(p)}
    return {v: str(p.with_name(f"{p.stem}_{v}{p.suffix or '.tif'}")) for v in views}


def heights_source(project, request: OrthoRequest, sol) -> tuple[Heights, tuple]:
    """The :class:`Heights` of the request (its geoid not yet laid on a grid) and warnings."""
    crs = project.scene.crs
    dem = request.dem
    if dem is None and request.height_m is None and getattr(project, "reference_dem", None):
        dem = project.reference_dem        # the project's own reference DEM
    if dem is not None:
        path = Path(dem)
        if not path.exists():
            raise InputError("DEM not found", file=path)
        if request.dem_kind not in DEM_KINDS:
            raise InputError(f"DEM heights {request.dem_kind!r}: expected one of {', '.join(DEM_KINDS)}")
        warnings = []
        kind = request.dem_kind
        if kind == "auto":
            kind = dem_height_kind(path)
            if kind is None:
                kind = "orthometric"
                warnings.append(f"{path.name} does not say its heights' kind: taken as orthometric "
                                "(as SRTM and Copernicus DEMs are); say --dem-heights ellipsoidal if not")
        return Heights(crs, kind, str(path)), tuple(warnings)
    if request.height_m is not None:
        if not math.isfinite(request.height_m):
            raise InputError(f"--height {request.height_m}: expected a number of metres")
        return (Heights(crs, "orthometric", constant=float(request.height_m)),
                (f"no DEM: every cell at the constant height {request.height_m:g} m (orthometric); relief "
                 "moves the ortho sideways by its height above or below that times the view's off-nadir tangent",))
    return (Heights(crs, "ellipsoidal", constant=float(sol.mean_height)),
            (f"no DEM and no height: every cell at the fit's mean height {sol.mean_height:.1f} m (ellipsoidal); "
             "relief moves the ortho sideways by its height above or below that times the view's off-nadir "
             "tangent: give --dem",))


def _border(c0, r0, w, h, n: int = 16) -> np.ndarray:
    """``(4n, 2)`` points along the edges of an image rectangle."""
    s = np.linspace(0.0, 1.0, n, endpoint=False)
    return np.concatenate([np.column_stack([c0 + w * s, np.full(n, r0)]),
                           np.column_stack([np.full(n, c0 + w), r0 + h * s]),
                           np.column_stack([c0 + w * (1 - s), np.full(n, r0 + h)]),
                           np.column_stack([np.full(n, c0), r0 + h * (1 - s)])])


def _with_undulation(heights: Heights, geoid, bounds) -> Heights:
    """``heights`` with the geoid laid on a coarse grid over ``bounds`` (orthometric only)."""
    if heights.kind != "orthometric":
        return heights
    x0, y0, x1, y1 = bounds
    s = UNDULATION_SPACING_M
    cols, rows = max(2, int(math.ceil((x1 - x0) / s)) + 3), max(2, int(math.ceil((y1 - y0) / s)) + 3)
    t = (s, 0.0, x0 - s, 0.0, -s, y1 + s)
    E, N = np.meshgrid(t[2] + s * (np.arange(cols) + 0.5), t[5] - s * (np.arange(rows) + 0.5))
    u = np.asarray(geoid.undulation(E, N, heights.crs), float)
    if not np.isfinite(u).all():
        raise InputError("the project's geoid does not cover the ortho's area")
    if np.all(u == u.flat[0]):
        return replace(heights, undulation=float(u.flat[0]))
    return replace(heights, undulation=(u.astype(np.float32), t))


def plan_grid(sol, view: str, heights: Heights, posting: float, window=None) -> tuple[tuple, tuple]:
    """``(transform, shape)`` of the ortho grid of ``view``: what it sees between the DEM's
    lowest and highest heights there (or the ground under ``window`` of the reference view),
    within the DEM's extent, aligned on multiples of ``posting``."""
    source = sol.scene.reference_view if window is not None else view
    v = sol.scene.views[source]
    rows, cols = v.shape
    border = _border(*(window if window is not None else (0, 0, cols, rows)))
    model = sol.model

    def bbox(en):
        en = en[np.isfinite(en).all(axis=1)]
        if not len(en):
            raise ModelError(f"view {source}: the model places none of the image's edge on the ground")
        return (*en.min(axis=0), *en.max(axis=0))
    x0, y0, x1, y1 = bbox(model.image_to_ground(source, border, sol.mean_height))
    pad = max(2000.0, 0.3 * max(x1 - x0, y1 - y0))     # room for the relief's sideways reach
    around = (x0 - pad, y0 - pad, x1 + pad, y1 + pad)
    if heights.path is not None:
        d = dem_bounds(heights.path, heights.crs)
        around = (max(around[0], d[0]), max(around[1], d[1]), min(around[2], d[2]), min(around[3], d[3]))
        if around[0] >= around[2] or around[1] >= around[3]:
            raise InputError(f"the DEM {Path(heights.path).name} does not cover view {source}'s ground")
    lo, hi = heights.range_over(around, RANGE_CELLS)
    if not np.isfinite(lo):
        raise InputError(f"the DEM {Path(heights.path).name} does not cover view {source}'s ground")
    en = np.concatenate([model.image_to_ground(source, border, h) for h in (lo, hi)])
    x0, y0, x1, y1 = bbox(en)
    if heights.path is not None:
        x0, y0, x1, y1 = max(x0, around[0]), max(y0, around[1]), min(x1, around[2]), min(y1, around[3])
        if x0 >= x1 or y0 >= y1:
            raise InputError(f"the DEM {Path(heights.path).name} does not cover view {source}'s ground")
    return grid_over(np.array([[x0, y0], [x1, y1]]), posting)


def orientation_text(sol, project, view: str) -> str:
    """How the model of ``view`` was fitted, in words (the ortho's metadata)."""
    b = sol.bias[view]
    if project.settings.orientation == "dem":
        return f"from a reference DEM (no GCP); view {view}: {b.model} bias"
    n = sum(1 for p in project.points.values() if p.kind == "GCP" and (p.id, view) in project.measurements)
    s0 = getattr(b, "sigma0", None)
    return (f"fitted to GCPs ({n} measured in view {view}); view {view}: {b.model} bias"
            + (f", σ0 {s0:.2f}" if s0 is not None and math.isfinite(s0) else ""))


def _tags(sol, project, view, request, heights, posting, accuracy: OrthoAccuracy, project_path) -> dict:
    image = sol.scene.views[view].image
    t = {"ORTHO_VIEW": view, "ORTHO_IMAGE": Path(image).name if image else "",
         "ORTHO_MODEL": f"{sol.scene.sensor.name} ({sol.scene.sensor.description})",
         "ORTHO_ORIENTATION": orientation_text(sol, project, view),
         "ORTHO_PROJECT": str(project_path) if project_path else "", "ORTHO_REVISION": sol.revision,
         "ORTHO_DEM": heights.describe(), "ORTHO_DEM_KIND": heights.kind,
         "ORTHO_POSTING_M": f"{posting:g}", "ORTHO_RESAMPLING": request.resampling}
    if heights.path is not None:
        t["ORTHO_DEM_PATH"] = str(Path(heights.path).resolve())
    else:
        t["ORTHO_DEM_CONSTANT_M"] = f"{heights.constant:.3f}"
    for key, value in (("ORTHO_EXPECTED_SIGMA_M", accuracy.expected_sigma_m),
                       ("ORTHO_ORIENTATION_SIGMA_M", accuracy.orientation_sigma_m),
                       ("ORTHO_DEM_SIGMA_M", accuracy.dem_sigma_m), ("ORTHO_OFF_NADIR_TAN", accuracy.off_nadir_tan),
                       ("ORTHO_CHECK_RMSE_M", accuracy.check_rmse_m)):
        t[key] = "unknown" if value is None or not math.isfinite(value) else f"{value:.3f}"
    t["ORTHO_ACCURACY"] = dumps(accuracy.as_dict())
    return t


def default_posting(scene) -> float:
    """The reference view's pixel rounded to two significant figures (PRISM 2.5 m, Pléiades
    0.5 m): one posting for every view, so their orthos share their cells."""
    g = float(scene.views[scene.reference_view].pixel_size_m)
    return float(f"{g:.2g}")


def tiles_of(shape, size: int | None = None):
    """``(row0, col0, rows, cols)`` windows of ``size`` (default :data:`TILE`) cells covering a
    grid of ``shape``."""
    size = size or TILE
    rows, cols = shape
    return [(r, c, min(size, rows - r), min(size, cols - c)) for r in range(0, rows, size)
            for c in range(0, cols, size)]


def export_orthos(sol, project, request: OrthoRequest, *, project_path=None, progress=None) -> OrthoExport:
    """Make and write the orthos ``request`` asks for from the fitted solution ``sol`` of
    ``project``. ``progress(fraction, message)`` returning False cancels
    (:class:`~prismstation.errors.Cancelled`: the file being written is not left, those written
    before stay). A solution that did not fit is a :class:`ModelError`."""
    if not sol.ok and project.settings.orientation != "dem":
        raise ModelError("; ".join(sol.messages) or "the model could not be fitted")
    if request.resampling not in RESAMPLINGS:
        raise InputError(f"--resampling {request.resampling}: expected one of {', '.join(RESAMPLINGS)}")
    if request.posting_m is not None and not (math.isfinite(request.posting_m) and request.posting_m > 0):
        raise InputError(f"--posting {request.posting_m}: expected a positive number of metres")
    if request.dem_sigma_m is not None and not (math.isfinite(request.dem_sigma_m) and request.dem_sigma_m >= 0):
        raise InputError(f"--dem-sigma {request.dem_sigma_m}: expected a number of metres ≥ 0")
    scene = sol.scene
    views = resolve_views(scene, request.views)
    for v in views:
        if not scene.views[v].image or not scene.views[v].shape:
            raise InputError(f"view {v} has no image to resample")
    if request.window is not None:
        c0, r0, w, h = request.window
        rows, cols = scene.views[scene.reference_view].shape
        if w <= 0 or h <= 0 or c0 >= cols or r0 >= rows or c0 + w <= 0 or r0 + h <= 0:
            raise InputError(f"--window {c0} {r0} {w} {h}: outside view {scene.reference_view}'s "
                             f"{cols} × {rows} image")
    paths = output_paths(request.output, views)
    for p in paths.values():
        check_writable(p)     # a folder that cannot be written: now, not after the work
    heights, warnings = heights_source(project, request, sol)
    geoid = project_geoid(project) if heights.kind == "orthometric" else None
    ground = known_ground(project)
    out = []
    for i, view in enumerate(views):
        p = scaled(progress, i / len(views), (i + 1) / len(views))
        out.append(_one_view(sol, project, request, view, paths[view], heights, geoid, ground, project_path, p))
    warnings = list(warnings)
    for o in out:
        if o.max_error_px > 0.01:
            warnings.append(f"view {o.view}: positions interpolated to {o.max_error_px:.3f} px at worst")
    return OrthoExport(request, tuple(out), heights.describe(), tuple(warnings))


def _one_view(sol, project, request, view, path, heights, geoid, ground, project_path, progress) -> OrthoView:
    checkpoint(progress, 0.0, f"view {view}: planning")
    v = sol.scene.views[view]
    posting = float(request.posting_m or default_posting(sol.scene))
    plan_heights = heights if geoid is None else _with_undulation(heights, geoid, _rough_bounds(sol, view, request))
    transform, shape = plan_grid(sol, view, plan_heights, posting, request.window)
    if geoid is not None:
        a, _, c, _, e, f = transform
        plan_heights = _with_undulation(heights, geoid, (c, f + e * shape[0], c + a * shape[1], f))
    factor = max(1, int(math.floor(posting / v.pixel_size_m + 1e-6)))
    window = None
    if request.window is not None and view == sol.scene.reference_view:
        window = request.window
    accuracy = expected_accuracy(sol, view, plan_heights, ground, dem_sigma_m=request.dem_sigma_m, window=window)
    tags = _tags(sol, project, view, request, plan_heights, posting, accuracy, project_path)
    specs = [OrthoTile(sol.model, view, v.image, tuple(v.shape), w, transform, plan_heights, request.resampling,
                       factor) for w in tiles_of(shape)]
    dtype = ortho_dtype(image_dtype(v.image))
    stats = {"valid": 0, "error": 0.0}

    def fill(f):
        def consume(i, res):
            f.write(specs[i].window, res.values)
            stats["valid"] += int(np.isfinite(res.values).sum())
            stats["error"] = max(stats["error"], res.max_error_px)
        run_tiles(specs, consume, request.scheduler, request.workers, scaled(progress, 0.02, TILES_SHARE),
                  fn=run_ortho_tile)
        if not stats["valid"]:
            raise InputError(f"view {view}: no cell of the ortho has data (the DEM does not cover what "
                             "the image sees)")
        tags["ORTHO_VALID_PERCENT"] = f"{100.0 * stats['valid'] / (shape[0] * shape[1]):.2f}"
        tags["ORTHO_INTERPOLATION_MAX_PX"] = f"{stats['error']:.2e}"
        f.ds.update_tags(**tags)
        checkpoint(progress, TILES_SHARE, f"view {view}: writing")

    write_ortho(path, shape, transform, sol.scene.crs, dtype, fill, tags=tags,
                before_keep=lambda: checkpoint(progress, 1.0, f"view {view}: written"))
    return OrthoView(path, view, tuple(transform), tuple(shape), 100.0 * stats["valid"] / (shape[0] * shape[1]),
                     stats["error"], accuracy, tags)


def _rough_bounds(sol, view, request) -> tuple:
    """A generous box around the ground of ``view`` (or the window): where the geoid is laid
    for planning."""
    source = sol.scene.reference_view if request.window is not None else view
    rows, cols = sol.scene.views[source].shape
    en = sol.model.image_to_ground(source, _border(*(request.window or (0, 0, cols, rows))), sol.mean_height)
    en = en[np.isfinite(en).all(axis=1)]
    x0, y0 = en.min(axis=0)
    x1, y1 = en.max(axis=0)
    pad = max(2000.0, 0.3 * max(x1 - x0, y1 - y0)) + 2 * UNDULATION_SPACING_M
    return (x0 - pad, y0 - pad, x1 + pad, y1 + pad)

