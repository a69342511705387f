"""The DSM's tiles as independent Dask tasks, and how they are run and blended.

A :class:`TileSpec` holds everything one tile needs (the fitted solution, its output window,
its crop of the prior surface, the level's parameters); :func:`run_tile` reads the three
images' windows itself, so a tile runs anywhere the image files can be read (a thread, a
process, a ``dask.distributed`` worker on a shared file system).

A read that fails inside a task (a truncated or corrupt image, a file gone) is a
:class:`~prismstation.errors.RasterReadError` naming the file, the view, the window and the
tile; Dask hands it to the caller as it is (it pickles, errno and all, from another process).

Schedulers: ``"threads"`` (default) or ``"processes"`` on this machine, or the address of an
existing ``dask.distributed`` scheduler (``"tcp://host:8786"``), or a ``distributed.Client``.
"""
from __future__ import annotations

import ctypes
import sys
from dataclasses import dataclass
from functools import partial

from prismstation.core.lazy_cv2 import cv2  # imported at first use: start-up saving
import numpy as np

from prismstation.errors import PrismError, RasterReadError
from prismstation.io.raster import gdal_env
from prismstation.io.windows import ImageWindows
from prismstation.core.models.solution import Solution
from prismstation.core.surfaces.stereo_tile import frame_over, tile_dsm
from prismstation.ops.progress import checkpoint


@dataclass(frozen=True)
class TileSpec:
    """One tile of one level: output cells ``window`` = (row0, col0, rows, cols) of the level
    grid ``transform`` (north-up, rasterio order), matched on frames of ``g`` metres/pixel
    within ``±half_range_m`` of the prior ``prior`` (array on ``prior_transform``)."""

    sol: Solution
    window: tuple
    transform: tuple
    g: float
    half_range_m: float
    prior: np.ndarray
    prior_transform: tuple
    refine: bool = True
    rect: tuple | None = None      # (origin, t, u, x0, x1, y0, y1): the track-aligned rectangle
    overlap_m: float = 0.0


def _cell_corners(transform, window) -> np.ndarray:
    a, _, c, _, e, f = transform[:6]
    r0, c0, rows, cols = window
    x = c + a * np.array([c0, c0 + cols, c0, c0 + cols])
    y = f + e * np.array([r0, r0, r0 + rows, r0 + rows])
    return np.column_stack([x, y])


def _prior_on_frame(prior, prior_t, frame) -> np.ndarray:
    """The prior grid (north-up) resampled bilinearly onto the frame's pixel centres (float32)."""
    a, _, c, _, e, f = prior_t
    F = frame.affine()
    # frame coords → prior array index: ((E − c)/a − 0.5, (N − f)/e − 0.5)
    S = np.array([[1 / a, 0.0, -c / a - 0.5], [0.0, 1 / e, -f / e - 0.5]])
    M = S[:, :2] @ F[:, :2]
    o = S[:, :2] @ F[:, 2] + S[:, 2] + 0.5 * M.sum(axis=1)
    rows, cols = frame.shape
    return cv2.warpAffine(np.asarray(prior, np.float32), np.column_stack([M, o]), (cols, rows),
                          flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_REPLICATE)


def _read_views(sol: Solution, frame, h_lo: float, h_hi: float, factor: int) -> dict:
    """Each view's window covering the frame between two heights, reduced by ``factor``:
    ``{view: (array, index_of)}``."""
    rows, cols = frame.shape
    corners = frame.to_map(np.array([0, cols, 0, cols]), np.array([0, 0, rows, rows]))
    out = {}
    images = ImageWindows(sol.scene)
    try:
        for v in ("N", "F", "B"):
            xy = np.concatenate([sol.ground_to_image(v, corners, h) for h in (h_lo, h_hi)])
            lo = np.floor(xy.min(axis=0)) - 4 * factor
            hi = np.ceil(xy.max(axis=0)) + 4 * factor
            arr, c0, r0 = images.read_reduced(v, lo[0], lo[1], hi[0] - lo[0], hi[1] - lo[1], factor)
            if arr is None:
                arr, c0, r0 = np.full((2, 2), np.nan, np.float32), 0, 0
            # full-image pixel coordinate x → array index (x − c0)/factor − 0.5
            out[v] = (arr, np.array([[1 / factor, 0, -c0 / factor - 0.5],
                                     [0, 1 / factor, -r0 / factor - 0.5]]))
    finally:
        images.close()
    return out


def return_freed_memory() -> None:
    """glibc: hand the heaps' freed memory back to the system (``malloc_trim``). The tiles'
    arrays (1–30 MB) are freed into per-thread heaps that otherwise keep them; trimming after
    each batch of tiles and each level costs next to nothing (a fixed mmap threshold did the
    same for 37 % more time). Elsewhere a no-op."""
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL("libc.so.6").malloc_trim(0)
        except (OSError, AttributeError):
            pass


def run_tile(spec: TileSpec):
    """Heights, quality (pairs agreeing) and blend weights of the tile's cells, and the tile's
    σ check ``(z_nmad, count)`` (:class:`prismstation.core.surfaces.stereo_tile.TileResult`)."""
    cv2.setNumThreads(1)
    sol = spec.sol
    a = spec.transform[0]
    rows, cols = spec.window[2], spec.window[3]
    tile_t = (a, 0.0, spec.transform[2] + a * spec.window[1], 0.0, spec.transform[4],
              spec.transform[5] + spec.transform[4] * spec.window[0])
    if spec.rect is None:
        corners = _cell_corners(spec.transform, spec.window)
    else:
        o, t, u, x0, x1, y0, y1 = spec.rect
        corners = np.array([np.add(o, np.multiply(xx, t) + np.multiply(yy, u)) for xx in (x0, x1) for yy in (y0, y1)])
    # along track: the reach of the height range in the most oblique view and SGBM's edge band
    margin_x = 0.6 * spec.half_range_m + 1.0 * spec.half_range_m + 16 * spec.g
    frame = frame_over(sol, corners, spec.g, margin_x, 8 * spec.g)
    h0 = _prior_on_frame(spec.prior, spec.prior_transform, frame)
    pixel = sol.scene.views["N"].pixel_size_m
    factor = max(1, int(round(spec.g / pixel)))
    # a worker may be another process: its own bounded GDAL cache (in this process the
    # caller's, run_tiles', holds it while a thread leaves its own)
    try:
        with gdal_env():
            images = _read_views(sol, frame, float(h0.min()) - spec.half_range_m,
                                 float(h0.max()) + spec.half_range_m, factor)
    except RasterReadError as exc:  # which tile, beside the file and the window
        r0, c0 = spec.window[0], spec.window[1]
        raise RasterReadError(f"{exc}, for the DSM tile of cells rows {r0}–{r0 + rows}, columns "
                              f"{c0}–{c0 + cols} at {spec.g:g} m") from None
    res = tile_dsm(sol, images, frame, h0, tile_t, (rows, cols), spec.half_range_m,
                   refine=spec.refine)
    return res.heights, res.quality, feather(spec, tile_t, (rows, cols)), (res.z_nmad, res.z_count)


def feather(spec: TileSpec, transform, shape) -> np.ndarray:
    """Blend weights of the tile's cells: 0 outside its rectangle, rising linearly over
    ``2·overlap_m`` from its edge, so that neighbours (which share that band) cross-fade with
    weights summing to one — no seams. Without a rectangle: 1 everywhere."""
    if spec.rect is None:
        return np.ones(shape, np.float32)
    o, t, u, x0, x1, y0, y1 = spec.rect
    en = np.stack(np.meshgrid(transform[2] + transform[0] * (np.arange(shape[1]) + 0.5),
                              transform[5] + transform[4] * (np.arange(shape[0]) + 0.5)), axis=-1) - np.asarray(o)
    x, y = en @ np.asarray(t), en @ np.asarray(u)
    d = np.minimum(np.minimum(x - x0, x1 - x), np.minimum(y - y0, y1 - y))
    return np.clip(d / max(2 * spec.overlap_m, 1e-9), 0.0, 1.0).astype(np.float32)


def run_tiles(specs: list, consume, scheduler=None, workers: int | None = None, progress=None,
              fn=None) -> None:
    """Run ``fn`` (default :func:`run_tile`) on ``specs`` and hand each result to ``consume(index, result)`` as
    it arrives, so that no more than a few tiles' arrays are held at once (a 14,000 px scene at
    5 m has ~56 million cells: all its tiles' results together would be ~0.7 GB). See the
    module docstring for ``scheduler``. ``progress(fraction, message)`` after each tile; False
    cancels. Local schedulers run the tiles in batches of four per worker."""
    with gdal_env():      # the bound for every local worker thread, entry point or not
        _run_tiles(specs, consume, scheduler, workers, progress, partial(_portable, fn or run_tile))


def _portable(fn, spec):
    """``fn(spec)``, its failure made fit to cross a process boundary: the project's error
    without the library exceptions it was raised from (a GDAL error chained to it does not
    unpickle in the caller, which then saw an AttributeError of the unpickler instead)."""
    try:
        return fn(spec)
    except PrismError as exc:
        exc.__context__ = exc.__cause__ = None
        raise


def _run_tiles(specs, consume, scheduler, workers, progress, fn) -> None:
    import dask
    done = 0

    def take(i, result):
        nonlocal done
        consume(i, result)
        done += 1
        checkpoint(progress, done / len(specs), f"tile {done} of {len(specs)}")

    if scheduler is None or scheduler in ("threads", "processes", "sync"):
        from dask.system import CPU_COUNT
        batch = 4 * max(1, workers or CPU_COUNT)
        for b0 in range(0, len(specs), batch):
            # named, untraversed specs: dask neither hashes nor walks the solution's points
            tasks = [dask.delayed(fn)(dask.delayed(specs[i], traverse=False, name=f"tile-spec-{i}"),
                                            dask_key_name=f"run_tile-{i}")
                     for i in range(b0, min(b0 + batch, len(specs)))]
            results = list(dask.compute(*tasks, scheduler=scheduler or "threads", num_workers=workers))
            for k in range(len(results)):
                take(b0 + k, results[k])
                results[k] = None
            del results
            return_freed_memory()
        return
    from distributed import Client, as_completed
    client = scheduler if isinstance(scheduler, Client) else Client(scheduler)
    try:
        futures = client.map(fn, specs, pure=True)
        index = {f.key: i for i, f in enumerate(futures)}
        try:
            for future in as_completed(futures):
                take(index[future.key], future.result())
                future.release()
        except BaseException:
            client.cancel(futures)
            raise
    finally:
        if client is not scheduler:
            client.close()
