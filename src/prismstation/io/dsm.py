"""A DSM from the oriented triplet (issue 4 item 3): F and B matched densely in N space along
the flight direction, heights from the fitted parallax line, ground positions from the fitted
N model, averaged onto a north-up grid and written as a GeoTIFF.

Coarse to fine: a pass at 1/8 resolution from the mean height with a wide search gives the
prior of the pass at the working resolution. F and B are first brought into N's frame by
their relative orientation (median offsets at the measured points, or the DEM control's).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from prismstation.core import prism
from prismstation.core.affine import Affine2D
from prismstation.core.dem_orient import grid_points, patch_windows
from prismstation.core.dense import parallax_map
from prismstation.core.solve import Solution
from prismstation.errors import InputError
from prismstation.io.orient_dem import Cancelled, _Images, _scale, _shift


@dataclass(frozen=True)
class Dsm:
    heights: np.ndarray   # (rows, cols) metres, NaN where unmatched
    transform: tuple      # rasterio order (a, b, c, d, e, f), north-up
    crs: str
    height_kind: str      # "ellipsoidal" or "orthometric"
    valid_fraction: float


def _fill(py: np.ndarray) -> np.ndarray:
    """Smoothed parallax with holes filled from the nearest valid cell (a prior for the next level)."""
    from scipy import ndimage
    bad = ~np.isfinite(py)
    idx = ndimage.distance_transform_edt(bad, return_distances=False, return_indices=True)
    return cv2.medianBlur(py[tuple(idx)].astype(np.float32), 5)


def relative_offsets(sol: Solution, record: dict | None = None) -> dict:
    """Where F and B see a point relative to N's view of it, as N-space pixel vectors."""
    if record and record.get("offsets_px"):
        return {v: np.asarray(o, float) for v, o in record["offsets_px"].items()}
    sc = sol.scene
    offs = {"F": [], "B": []}
    for p in sol.points:
        if p.ground_est is None or "N" not in p.measured:
            continue
        en, h = np.array(p.ground_est[:2]), p.ground_est[2]
        a_n = prism.ground_to_ancillary(sc, sc.views["N"], en, h)
        for v in offs:
            if v in p.measured:
                t = prism.to_nadir_space(sc, sc.views[v])
                a_v = t(prism.ground_to_ancillary(sc, sc.views[v], en, h))
                offs[v].append(t(np.array(p.measured[v])) - np.array(p.measured["N"]) - (a_v - a_n))
    if not offs["F"] or not offs["B"]:
        raise InputError("a DSM needs points measured in N, F and B to relate the views (or a DEM orientation)")
    return {v: np.median(o, axis=0) for v, o in offs.items()}


def _to_n(sc, images, v, box_n, offset, f):
    back = prism.to_nadir_space(sc, sc.views[v]).inverse()
    pc = back(box_n)
    (a0, b0), (a1, b1) = pc.min(0), pc.max(0)
    arr, ac0, ar0 = images.read(v, a0, b0, a1 - a0, b1 - b0)
    if arr is None:
        return None, None
    if f > 1:
        arr = cv2.resize(arr, (max(arr.shape[1] // f, 1), max(arr.shape[0] // f, 1)), interpolation=cv2.INTER_AREA)
    corr = Affine2D([[1, 0, -offset[0]], [0, 1, -offset[1]]])
    return arr, (_scale(1 / f) @ corr @ prism.to_nadir_space(sc, sc.views[v]) @ _shift(ac0, ar0) @ _scale(f)).matrix


def make_dsm(sol: Solution, window=None, *, posting_m: float = 10.0, decimation: int = 2,
             block_px: int = 1024, record: dict | None = None, orthometric_geoid=None,
             progress=None) -> Dsm:
    """DSM of the N-image ``window`` (col0, row0, cols, rows; default the whole image)."""
    sc = sol.scene
    if not sc.is_triplet or sol.parallax is None:
        raise InputError("a DSM needs an oriented N, F, B triplet")
    report = progress or (lambda fr, m="": True)
    N = sc.views["N"]
    rows, cols = N.shape
    col0, row0, w, h = window or (0, 0, cols, rows)
    offs = relative_offsets(sol, record)
    c0, c1 = sol.parallax.c0, sol.parallax.c1
    tanF, tanB = sc.views["F"].tan_theta, sc.views["B"].tan_theta
    d = prism.along_track_unit(sc, N.map_to_image.inverse()(np.array([col0 + w / 2, row0 + h / 2])))
    py_back = float((offs["F"] - offs["B"]) @ d)   # corrected py + this = py of raw positions
    pts = []
    images = _Images(sc)
    try:
        blocks = [(col0 + a, row0 + b, bw, bh) for (a, b, bw, bh) in patch_windows((h, w), block_px)]
        for k, (bc, br, bw, bh) in enumerate(blocks):
            if not report(k / len(blocks), f"block {k + 1} of {len(blocks)}"):
                raise Cancelled("cancelled")
            py, f_prev = None, None
            prior0 = (sol.mean_height - c0) / c1 - py_back
            levels = [(8, 90)] + [(f, 8) for f in (4, 2, 1) if decimation <= f < 8]
            for f, rng in levels:
                wd = (bc // f, br // f, max(bw // f, 1), max(bh // f, 1))
                reach = (abs(prior0) + (rng + 30) * f + 200)
                box = np.array([[bc - reach, br - reach], [bc + bw + reach, br - reach],
                                [bc - reach, br + bh + reach], [bc + bw + reach, br + bh + reach]], float)
                fa, fm = _to_n(sc, images, "F", box, offs["F"], f)
                ba, bm = _to_n(sc, images, "B", box, offs["B"], f)
                if fa is None or ba is None:
                    break
                if py is None:
                    pr = np.float32(prior0 / f)
                elif not np.isfinite(py).any():
                    break
                else:
                    pr = cv2.resize(_fill(py) * f_prev / f, (wd[2], wd[3]), interpolation=cv2.INTER_LINEAR)
                pm = parallax_map(fa, ba, fm, bm, wd, d, prior=pr, search_range=rng, half_window=4,
                                  n_weight=tanF / (tanF + tanB))
                py, f_prev = pm.parallax, f
            if py is None:
                continue
            j, i = np.nonzero(np.isfinite(py))
            xy = decimation * np.column_stack([wd[0] + i + 0.5, wd[1] + j + 0.5])
            hh = c0 + c1 * (py[j, i] * decimation + py_back)
            en = sol.image_to_ground("N", xy, hh)
            pts.append(np.column_stack([en, hh]))
    finally:
        images.close()
    report(1.0, "gridding")
    allp = np.concatenate(pts) if pts else np.zeros((0, 3))
    if len(allp) == 0:
        raise InputError("dense matching found no valid parallax in the window")
    lo, hi = allp[:, :2].min(0), allp[:, :2].max(0)
    e0, n0 = np.floor(lo[0] / posting_m) * posting_m, np.ceil(hi[1] / posting_m) * posting_m
    shape = (int((n0 - lo[1]) // posting_m) + 1, int((hi[0] - e0) // posting_m) + 1)
    t = (posting_m, 0.0, e0, 0.0, -posting_m, n0)
    grid = grid_points(allp[:, 0], allp[:, 1], allp[:, 2], t, shape, min_count=2)
    kind = "ellipsoidal"
    if orthometric_geoid is not None:
        from prismstation.io.dem import grid_coordinates
        E, Nn = grid_coordinates(t, shape)
        grid = grid - orthometric_geoid.undulation(E, Nn, sc.crs)
        kind = "orthometric"
    return Dsm(grid, t, sc.crs, kind, float(np.isfinite(grid).mean()))
