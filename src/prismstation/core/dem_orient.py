"""Orientation without GCPs from a reference DEM (Gonçalves, SRTM as ground control; docs/model.md §3) — the pure parts.

The workflow (``prismstation.ops.orient_dem``) matches F and B densely in N space per patch,
turns parallax into a *relative DEM* placed on the map by the ancillary model, and finds the
3-D shift ``(dE, dN, dh)`` laying each patch on the reference DEM. This module turns those
shifts into the sensor model: the shifts are modelled as an affine function of the patch
position in the N image, and virtual control points on a grid over the image then give the
bias affine of every view and the parallax line's offset.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy import ndimage

from prismstation.core import prism
from prismstation.core.prism import BiasFit, ParallaxLine
from prismstation.core.consistency import ALPHA, MIN_PATCHES, snoop
from prismstation.core.scene import Scene
from prismstation.core.shift_field import ShiftField
from prismstation.core.solve import Control
from prismstation.core.view_offsets import offset_at


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
    """One patch's result: N-image window, centre, shift (metres) with σ, and whether used."""

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


#: how far (m; E, N, h) a patch's shift may depart from an affine field beyond its formal σ
#: (added in quadrature): attitude drift that is not affine across the scene, the reference's
#: errors correlated over a patch. Measured on simulated triplets at 0–100 m per view (6,000 px,
#: 4 km patches, both passes): 0.4–2.2 m horizontally and 0.7–1.1 m in height beyond
#: ``coregister``'s σ, whose height σ (≈ 0.1 m) counts only the cells' noise.
FIELD_SIGMA_M = (1.5, 1.5, 1.0)


def patch_sigmas(patches: list[PatchShift]) -> np.ndarray:
    """(n, 3) σ (m) of the patches' shifts as the field sees them: formal σ ⊕ :data:`FIELD_SIGMA_M`."""
    formal = np.array([[p.sigma_E, p.sigma_N, p.sigma_h] for p in patches], float).reshape(-1, 3)
    return np.sqrt(np.nan_to_num(formal, nan=0.0) ** 2 + np.square(FIELD_SIGMA_M))


def affine_field(patches: list[PatchShift]):
    """The :class:`~prismstation.core.shift_field.ShiftField` of ``(dE, dN, dh)`` over the
    used patches (weights 1/σ², σ from :func:`patch_sigmas`), as a callable ``(xx, yy) → (..., 3)``;
    fewer than 3 patches, or patches (nearly) on one line → a constant field (weighted mean)."""
    use = [p for p in patches if p.used]
    if len(use) == 0:
        return lambda xx, yy: np.zeros(np.shape(xx) + (3,))
    xy = np.array([[p.x, p.y] for p in use])
    s = np.array([[p.dE, p.dN, p.dh] for p in use])
    sig = patch_sigmas(use)
    field = ShiftField.fit(xy, s, sig)
    if field:
        return field.predict
    w = 1 / sig**2
    mean = (s * w).sum(0) / w.sum(0)
    return lambda xx, yy: np.broadcast_to(mean, np.shape(xx) + (3,)).copy()


#: the part of the patches' error they share, which fitting a field over many patches does not
#: reduce (m; E, N, h): the reference's coarse posting and what the matcher's voids leave of its
#: smoothing bias every patch alike. Measured on simulated triplets (6,000 px, 4 km patches,
#: three scenes per pass, no geolocation error, so that the field fit is exact; relative DEMs
#: smoothed like the reference): check-point RMSE 1.11–1.41 m planimetric (≤ 1.0 m per
#: component; 1.6–2.3 m before the smoothing) and 0.9–1.45 m in height.
COMMON_SIGMA_M = (1.0, 1.0, 1.2)


def orientation_sigma(patches: list[PatchShift], x, y) -> np.ndarray:
    """σ (m; E, N, h), shape (..., 3), of the orientation at N-image positions ``x, y`` (px):
    the used patches' field (:func:`affine_field`'s fit) predicted there — a-priori from
    :func:`patch_sigmas`, scaled up by σ0 where the patches scatter more than that — ⊕
    :data:`COMMON_SIGMA_M`. With fewer than 3 patches or patches on a line: the weighted
    mean's σ. Relative to the reference DEM's own frame (its geolocation error is not in it)."""
    use = [p for p in patches if p.used]
    x, y = np.asarray(x, float), np.asarray(y, float)
    if not use:
        return np.full(x.shape + (3,), np.nan)
    sig = patch_sigmas(use)
    field = ShiftField.fit([[p.x, p.y] for p in use],
                           [[p.dE, p.dN, p.dh] for p in use], sig)
    if field:
        s0 = np.nan_to_num(field.sigma0, nan=1.0)
        s0 = np.where(s0 > 0, s0, 1.0)
        fit = field.predict_sigma(x, y) / s0 * np.maximum(s0, 1.0)
    else:
        fit = np.broadcast_to(np.sqrt(1 / (1 / sig ** 2).sum(0)), x.shape + (3,))
    return np.sqrt(fit ** 2 + np.square(COMMON_SIGMA_M))


def reoffset_patches(scene: Scene, patches: list[PatchShift], old_offset_of, new_offset_of,
                     n_weight: float, mean_height: float) -> list[PatchShift]:
    """The patches' shifts had their relative DEMs been made with the view offsets
    ``new_offset_of(view, xy)`` instead of ``old_offset_of`` (N-space px at N position
    ``xy``), without matching them again.

    A patch's F (B) image entered N space moved by −offset, so a change δF, δB at its centre
    moves every matched cell alike: its parallax by −(δF − δB)·d (``d`` the N-space flight
    direction) — the height by c1 times that — and its N position by −δF across track and
    −((1 − w)·δF + w·δB)·d along it (``w = n_weight``: where :func:`prismstation.core.dense.parallax_map`
    places a value). The relative DEM moves by that, so its shift onto the reference moves back.
    Exact for offsets constant over a patch (their gradients change them by ≲ 0.1 px per 4 km).
    The patches keep their σ and their used flag."""
    c1 = prism.theoretical_c1(scene)
    out = []
    for p in patches:
        if not np.isfinite([p.dE, p.dN, p.dh]).all():
            out.append(p)
            continue
        xy = np.array([[p.x, p.y]], float)
        dF = new_offset_of("F", xy[0]) - old_offset_of("F", xy[0])
        dB = new_offset_of("B", xy[0]) - old_offset_of("B", xy[0])
        h = np.array([mean_height - p.dh])
        en = prism.ancillary_to_ground(scene, scene.views["N"], xy, h)
        d = prism.along_track_unit(scene, en)[0]
        dpy = float((dF - dB) @ d)
        moved = xy - dF + n_weight * dpy * d
        en2 = prism.ancillary_to_ground(scene, scene.views["N"], moved, h - c1 * dpy)
        dE, dN = (en2 - en)[0]
        out.append(replace(p, dE=p.dE - float(dE), dN=p.dN - float(dN), dh=p.dh + c1 * dpy))
    return out


def judge_patches(patches: list[PatchShift], alpha: float = ALPHA, min_patches: int = MIN_PATCHES):
    """Test the usable patches' shift field against their σ (:func:`prismstation.core.consistency.snoop`,
    σ from :func:`patch_sigmas`) and mark the blunders it removes as not used. Returns ``(patches, verdict)``;
    the verdict's indices refer to the usable patches."""
    patches = list(patches)
    use = [i for i, p in enumerate(patches) if p.used]
    verdict = snoop([patches[i].x for i in use], [patches[i].y for i in use],
                    [[patches[i].dE, patches[i].dN, patches[i].dh] for i in use],
                    patch_sigmas([patches[i] for i in use]), alpha=alpha, min_patches=min_patches)
    for j in verdict.rejected:
        i = use[j]
        patches[i] = replace(patches[i], used=False,
                             reason=f"a blunder: departs from the other patches' field by "
                                    f"more than its σ allows (χ² test, α {alpha})")
    return patches, verdict


def control_from_shifts(scene: Scene, patches: list[PatchShift], mean_height: float,
                        view_offsets: dict | None = None, grid: int = 7,
                        bias_model: str = "affine", offset_gradients: dict | None = None) -> Control:
    """The sensor model implied by the patches' shifts (docs/model.md §3 step 4).

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
    field = affine_field(patches)
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
    return Control(bias, parallax, "reference DEM", float(mean_height))


def identity_control(scene: Scene, mean_height: float) -> Control:
    """The ancillary model alone (docs/model.md §3 step 1)."""
    c1 = prism.theoretical_c1(scene)
    return Control({v: BiasFit.identity() for v in scene.views},
                   ParallaxLine("theoretical", "theoretical", 0.0, c1, c1), "ancillary data", mean_height)
