"""Orientation without GCPs from a reference DEM (Gonçalves, SRTM as ground control; docs/model.md §3) — the pure parts.

The workflow (``prismstation.ops.orient_dem``) matches F and B densely in N space per patch,
turns parallax into a *relative DEM* placed on the map by the ancillary model (this module:
the patches, the cells, their smoothing to the reference's resolution, their moving when the
view offsets change), and finds the shift field ``(dE, dN, dh)`` over the N image laying every
cell on the reference DEM (:mod:`prismstation.core.orientation.field_adjust`). This module then turns the
field into the sensor model: virtual control points on a grid over the image give the bias
affine of every view and the parallax line's offset.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from prismstation.core.models import prism
from prismstation.core.orientation.field_adjust import FieldObs
from prismstation.core.orientation.field_model import Basis
from prismstation.core.models.prism import BiasFit, FixedPrism, ParallaxLine
from prismstation.core.models.scene import Scene
from prismstation.core.orientation.shift_field import ShiftField
from prismstation.core.models.solution import Control
from prismstation.core.orientation.view_offsets import offset_at


def patch_windows(shape, patch_px: int, margin_px: int = 0) -> list[tuple[int, int, int, int]]:
    """Cut an image of ``shape`` (rows, cols) into patches ``(col0, row0, cols, rows)`` of
    about ``patch_px`` pixels, keeping ``margin_px`` from the borders; the last row and
    column of patches share the remainder so that none is a sliver."""
    rows, cols = (int(v) for v in shape)
    out = []

    def cuts(n):
        usable = n - 2 * margin_px
        k = max(1, int(round(usable / patch_px)))
        edges = np.linspace(margin_px, n - margin_px, k + 1).round().astype(int)
        return list(zip(edges[:-1], edges[1:]))

    for r0, r1 in cuts(rows):
        for c0, c1 in cuts(cols):
            out.append((int(c0), int(r0), int(c1 - c0), int(r1 - r0)))
    return out


def relative_dem_points(scene: Scene, py: np.ndarray, window, c1: float, step: int = 1, scale: float = 1.0):
    """Ground points ``(E, N, h)`` of a parallax map: ``h = c1·py`` (no offset yet) and the
    ancillary N model (no bias) places each cell on the map (docs/model.md §3 step 2).

    ``py`` ``(rows, cols)`` (N pixels) on the grid of ``window = (col0, row0, cols, rows)`` in
    N space decimated by ``scale`` (cell ``[j, i]`` centred at N pixel
    ``scale·(col0 + i + 0.5, row0 + j + 0.5)``); every ``step``-th cell.
    Returns three 1-D arrays (valid cells only).
    """
    col0, row0 = window[0], window[1]
    sub = py[::step, ::step]
    j, i = np.nonzero(np.isfinite(sub))
    xy = scale * np.column_stack([col0 + i * step + 0.5, row0 + j * step + 0.5])
    h = c1 * sub[j, i].astype(float)
    en = prism.ancillary_to_ground(scene, scene.views["N"], xy, h, iterations=3)
    return en[:, 0], en[:, 1], h


def grid_points(E, N, h, transform, shape, min_count: int = 3) -> np.ndarray:
    """Mean height per cell of a north-up grid (``transform`` = (a, b, c, d, e, f), rasterio
    order, ``b = d = 0``); NaN where fewer than ``min_count`` points fall."""
    a, _, c, _, e, f = (float(v) for v in tuple(transform)[:6])
    rows, cols = shape
    ci = np.floor((np.asarray(E) - c) / a).astype(int)
    ri = np.floor((np.asarray(N) - f) / e).astype(int)
    ok = (ci >= 0) & (ci < cols) & (ri >= 0) & (ri < rows)
    k = ri[ok] * cols + ci[ok]
    n = np.bincount(k, minlength=rows * cols)
    s = np.bincount(k, weights=np.asarray(h)[ok], minlength=rows * cols)
    with np.errstate(invalid="ignore", divide="ignore"):
        g = np.where(n >= min_count, s / n, np.nan)
    return g.reshape(rows, cols)


def smooth_like_reference(rel: np.ndarray, cells, need: float = 0.95) -> np.ndarray:
    """The relative DEM ``rel`` (rows, cols; NaN voids) seen at the reference's resolution.

    A reference of ``cells = (kx, ky)`` grid cells per own cell (its cell size over the
    grid's posting, per axis; not necessarily whole: 3″ of longitude at 45° N over 30 m is 2.3)
    holds cell averages read by bilinear interpolation: a box ``k`` cells wide convolved with a
    tent of half-width ``k``, both centred (an even-length kernel would move the surface by half
    a cell). The relative DEM gets the same kernel, normalised over its valid cells; cells
    whose kernel is less than ``need`` covered become NaN. Compared unsmoothed, the fine relief
    the reference has averaged away is left in the residuals, and where the matcher left voids —
    on steep relief, not at random — it no longer averages out: on simulated triplets the patch
    shifts came out 0.8 m along track (in the flight direction) with the true terrain on the
    matched cells, 0.1–0.2 m with this kernel on them. ``k`` ≤ 1: ``rel`` unchanged."""
    rel = np.asarray(rel, float)
    ok = np.isfinite(rel).astype(float)
    s = np.where(ok > 0, rel, 0.0)
    for axis, k in ((1, float(cells[0])), (0, float(cells[1]))):
        if k <= 1:
            continue
        i = np.abs(np.arange(-np.ceil(k), np.ceil(k) + 1))
        box = np.clip(k / 2 + 0.5 - i, 0.0, 1.0)          # width k, partial cells at its ends
        ker = np.convolve(box, np.clip(1 - i / k, 0.0, None), mode="same")
        ker = ker / ker.sum()
        s = ndimage.convolve1d(s, ker, axis=axis, mode="constant")
        ok = ndimage.convolve1d(ok, ker, axis=axis, mode="constant")
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(ok >= need - 1e-9, s / ok, np.nan)


@dataclass(frozen=True)
class PatchShift:
    """One patch as the orientation saw it: N-image window and centre (px); its shift
    ``(dE, dN, dh)`` (m: the field at its centre plus its own departure from it) and the σ its
    cells alone give it (NaN in a direction they do not fix: a flat patch fixes its height
    only); the cells used, the share of the patch matched, whether it was used and why not.
    ``T``, ``dof``: its χ² test against the other patches' field (NaN, 0 when not tested);
    ``spread`` (m, NMAD) and ``area`` (cells) of its residuals."""

    window: tuple
    x: float
    y: float
    dE: float
    dN: float
    dh: float
    sigma_E: float
    sigma_N: float
    sigma_h: float
    count: int
    valid_fraction: float
    used: bool = True
    reason: str = ""
    T: float = float("nan")
    dof: int = 0
    spread: float = float("nan")
    area: float = float("nan")


def affine_field(patches: list[PatchShift]):
    """The field of a record made before the joint adjustment: the used patches' shifts fitted
    by an affine function of their position (weights from their σ), as a callable
    ``(xx, yy) → (..., 3)``; a constant (the weighted mean) for fewer than 3 patches or
    patches on a line."""
    use = [p for p in patches if p.used and np.isfinite([p.dE, p.dN, p.dh]).all()]
    if len(use) == 0:
        return lambda xx, yy: np.zeros(np.shape(xx) + (3,))
    xy = np.array([[p.x, p.y] for p in use])
    s = np.array([[p.dE, p.dN, p.dh] for p in use])
    sig = np.nan_to_num(np.array([[p.sigma_E, p.sigma_N, p.sigma_h] for p in use], float), nan=1.0)
    sig = np.maximum(sig, 1e-3)
    field = ShiftField.fit(xy, s, sig)
    if field:
        return field.predict
    w = 1 / sig**2
    mean = (s * w).sum(0) / w.sum(0)
    return lambda xx, yy: np.broadcast_to(mean, np.shape(xx) + (3,)).copy()


@dataclass(frozen=True)
class ControlPoints:
    """Ground control points for the DEM orientation: ``ids``; F and B image positions
    ``xy_f``, ``xy_b`` (n, 2) px; ``ground`` (n, 3) (E, N, h ellipsoidal) m; ``sigma_m`` (n, 3)
    σ of the shift each gives (E, N, h; m: survey and image measurement together)."""

    ids: tuple
    xy_f: np.ndarray
    xy_b: np.ndarray
    ground: np.ndarray
    sigma_m: np.ndarray

    def __len__(self) -> int:
        return len(self.ids)


def gcp_field_obs(scene: Scene, xy_f, xy_b, ground, sigma_m, offset_of, n_weight: float,
                  ids=()) -> "FieldObs":
    """Ground control points as observations of the shift field, in the frame of the relative
    DEMs' cells: ``xy_f``, ``xy_b`` (n, 2) their F and B image positions (px), ``ground`` (n, 3)
    their (E, N, h ellipsoidal) (m), ``sigma_m`` (n, 3) σ of the shift each gives (m: survey and
    measurement together); ``offset_of(view, xy)`` the views' offsets from N (N-space px).

    As :func:`prismstation.core.matching.dense.parallax_map` makes a cell: F and B in N space with their
    offsets removed, ``pF``, ``pB``; parallax ``py = (pF − pB)·d`` (``d`` the N-space flight
    direction), relative height ``c1·py``, N position ``pF − w·py·d`` (``w = n_weight``), placed
    by the ancillary N model; the shift is the ground point minus that."""
    N = scene.views["N"]
    xy_f, xy_b = np.atleast_2d(np.asarray(xy_f, float)), np.atleast_2d(np.asarray(xy_b, float))
    ground = np.atleast_2d(np.asarray(ground, float))
    tf, tb = prism.to_nadir_space(scene, scene.views["F"]), prism.to_nadir_space(scene, scene.views["B"])
    d = prism.along_track_unit(scene, ground[:, :2])
    c1 = prism.theoretical_c1(scene)
    p = tf(xy_f)
    for _ in range(3):                         # the offsets are taken at the point's N position
        pF, pB = tf(xy_f) - offset_of("F", p), tb(xy_b) - offset_of("B", p)
        py = np.einsum("ij,ij->i", pF - pB, d)
        p = pF - n_weight * py[:, None] * d
    h_rel = c1 * py
    en = prism.ancillary_to_ground(scene, N, p, h_rel)
    value = np.column_stack([ground[:, :2] - en, ground[:, 2] - h_rel])
    n = len(ground)
    return FieldObs(np.repeat(p[:, 0], 3), np.repeat(p[:, 1], 3), np.tile(np.arange(3), n), value.ravel(),
                    np.broadcast_to(np.asarray(sigma_m, float), (n, 3)).ravel(), tuple(ids))


def control_from_field(scene: Scene, field, mean_height: float, view_offsets: dict | None = None,
                       grid: int = 7, bias_model: str = "affine", offset_gradients: dict | None = None,
                       source: str = "reference DEM") -> Control:
    """The sensor model implied by the shift field ``field(x, y) → (..., 3)`` (dE, dN, dh, m, at
    N positions; docs/model.md §3 step 4).

    Virtual control points on a ``grid × grid`` lattice over the N image, at the relative
    height ``mean_height − dh``: the ancillary model places them at ``P``; the truth is
    ``P + (dE, dN)`` at height ``+ dh``. ``view_offsets`` (N-space pixel vectors) say where
    F and B see a point relative to the ancillary prediction from N (relative orientation);
    the relative DEM was made with them removed; ``offset_gradients`` (2 × 2 px per N pixel,
    about the N image's centre) how they vary over N. Fitting each view's bias to the virtual
    points and the parallax line's offset ``c0 = dh − c1·(offF − offB)·t`` (affine over N)
    gives a model that carries every measurement to the reference DEM's frame. ``c1`` stays
    theoretical.
    """
    views = scene.views
    rows, cols = views["N"].shape or (14000, 14000)
    g = (np.arange(grid) + 0.5) / grid
    xy = np.column_stack([np.tile(g * cols, grid), np.repeat(g * rows, grid)])
    grads = offset_gradients or {}
    offs = {k: offset_at(v, grads.get(k), (cols / 2, rows / 2), xy) for k, v in (view_offsets or {}).items()}
    s = field(xy[:, 0], xy[:, 1])
    h_rel = mean_height - s[:, 2]
    en_anc = prism.ancillary_to_ground(scene, views["N"], xy, h_rel)
    en_true, h_true = en_anc + s[:, :2], h_rel + s[:, 2]
    bias = {}
    for name, view in views.items():
        measured = xy if name == "N" else prism.ground_to_ancillary(scene, view, en_anc, h_rel)
        if name in offs:
            measured = measured + prism.to_nadir_space(scene, view).inverse().apply_linear(offs[name])
        truth0 = prism.ground_to_ancillary(scene, view, en_true, h_true)
        fit = prism.fit_bias(truth0, measured, bias_model, what=f"view {name} (DEM control)")
        # fitted to exact virtual points: its σ0 and σ would be ~0 and say nothing; leave them out
        u = len(fit.params)
        bias[name] = BiasFit(fit.model, fit.M, fit.b, fit.params, np.full(u, np.nan),
                             fit.names, None, np.full((u, u), np.nan))
    c1 = prism.theoretical_c1(scene)
    dh = s[:, 2]
    t = prism.along_track_unit(scene, en_anc).mean(0)
    py_off = (offs.get("F", np.zeros(2)) - offs.get("B", np.zeros(2))) @ t
    # the patches' dh field and the offsets are affine over N: c0 follows them (a tilted line)
    d0, dx, dy = np.linalg.lstsq(np.column_stack([np.ones(len(xy)), xy]), dh - c1 * py_off, rcond=None)[0]
    parallax = ParallaxLine("offset", "offset", float(d0), c1, c1, None, None, None,
                            f"from reference-DEM control: c0 follows the patches' dh over the image "
                            f"({dh.min():+.1f} to {dh.max():+.1f} m); c1 theoretical",
                            (float(dx), float(dy)))
    return Control(source, FixedPrism(bias, parallax), float(mean_height))


def identity_control(scene: Scene, mean_height: float) -> Control:
    """The ancillary model alone (docs/model.md §3 step 1)."""
    c1 = prism.theoretical_c1(scene)
    return Control("ancillary data", FixedPrism({v: BiasFit.identity() for v in scene.views},
                                                ParallaxLine("theoretical", "theoretical", 0.0, c1, c1)),
                   mean_height)


def field_of_record(record: dict):
    """The shift field ``(x, y) → (..., 3)`` of a saved ``dem_control`` record (a record made
    before the joint adjustment: its used patches' affine fit)."""
    f = record.get("field")
    if f:
        basis = Basis(tuple(f["centre"]), float(f["scale"]), tuple(f["terms"]))
        theta = np.asarray(f["theta"], float)
        return lambda x, y: basis.predict(theta, x, y)
    patches = [PatchShift(**{**p, "window": tuple(p["window"])}) for p in record["patches"]]
    return affine_field(patches)


def control_from_record(scene: Scene, record: dict) -> Control:
    """The model of a project's saved ``dem_control`` record (``DemOrientation.to_dict()``):
    :func:`control_from_field` of its field; a malformed record is a ``KeyError``,
    ``TypeError`` or ``ValueError``."""
    return control_from_field(scene, field_of_record(record), record["mean_height"], record.get("offsets_px"),
                              offset_gradients=record.get("offset_gradients_px"),
                              source=(record.get("field") or {}).get("source", "reference DEM"))
