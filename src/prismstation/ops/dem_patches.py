"""The relative DEMs of the DEM orientation, patch by patch, as cells for the joint adjustment.

Per patch of N: F and B, each with its offset field from N removed (:class:`prismstation.ops.orient_dem.OrientRun`),
are matched densely in N space along the flight direction around the reference DEM's
parallax; the parallax becomes heights ``h = c1·py`` placed on the map by the ancillary N model,
gridded on the reference's 30 m grid and smoothed to the reference's own resolution
(:func:`prismstation.core.orientation.dem_orient.smooth_like_reference`). Each valid grid cell is a cell
of :class:`prismstation.core.orientation.field_adjust.Cells`.
"""
from __future__ import annotations

from dataclasses import dataclass

from prismstation.core.lazy_cv2 import cv2  # imported at first use: start-up saving
import numpy as np
from scipy import ndimage

from prismstation.core.models import prism
from prismstation.core.adjustment.affine import Affine2D
from prismstation.core.matching.coarse import K_SIGMA
from prismstation.core.orientation.dem_orient import grid_points, patch_windows, relative_dem_points, smooth_like_reference
from prismstation.core.matching.dense import parallax_map
from prismstation.core.orientation.field_adjust import Cells
from prismstation.core.orientation.field_model import Surface
from prismstation.core.models.ray_dem import ray_meets_surface
from prismstation.core.surfaces.sample import remap_points
from prismstation.errors import InputError
from prismstation.io.dem import read_dem
from prismstation.io.windows import ImageWindows, scaling, shift
from prismstation.ops.progress import checkpoint


#: the dense prior is the reference smoothed by a Gaussian of this many of its own cells (σ): a
#: reference's noise is white from cell to cell (SRTM: metres), and the matcher's sub-pixel
#: value is drawn toward its prior — a prior holding that noise printed it into the relative
#: DEMs, whose gradients then shared the reference's noise and were taken for relief (the σ of
#: the field 5 × too small on smooth hills under a 4 m-noise reference). Smoothed over two
#: cells its noise falls ~7 ×; the search covers what the smoothing takes off the relief.
PRIOR_SMOOTH_CELLS = 2.0


@dataclass(frozen=True)
class ReferenceGrid:
    """The reference DEM read over N's footprint and the search radius: ellipsoidal heights
    ``dem.heights`` (NaN where void) on the north-up grid of ``posting_m`` whose corner cells
    span ``lo`` (west, south) to ``hi`` (east, north), metres; ``filled`` the same with voids
    at the mean height ``mean_h`` (float32), ``slope`` its gradient's norm (m/m), ``cells`` the
    reference's own cell size in grid cells (col, row); ``smooth`` the filled heights smoothed
    over :data:`PRIOR_SMOOTH_CELLS` of the reference's own cells (the dense matcher's prior)."""

    dem: object
    lo: np.ndarray
    hi: np.ndarray
    posting_m: float
    mean_h: float
    filled: np.ndarray
    slope: np.ndarray
    cells: tuple
    smooth: np.ndarray | None = None

    def at(self, grid: np.ndarray, en: np.ndarray) -> np.ndarray:
        """``grid`` (one of this grid's arrays) sampled bilinearly at map points ``en`` (..., 2)."""
        col = (en[..., 0] - self.lo[0]) / self.posting_m - 0.5
        row = (self.hi[1] - en[..., 1]) / self.posting_m - 0.5
        return remap_points(grid, col, row).astype(float)

    def ground(self, scene, xy: np.ndarray, shift=None, smooth: bool = False):
        """Where N's ancillary rays through image points ``xy`` (n, 2) meet the reference
        (:class:`~prismstation.core.models.ray_dem.RayHits`: ``en`` (n, 2), ``h`` (n,), NaN where a
        ray did not meet it). ``shift`` (optional): N's shift field ``(x, y) → (dE, dN, dh)``
        (m), the reference laid where N really looks — ``en`` and ``h`` are then in the
        ancillary frame (the reference at ``en + (dE, dN)``, minus ``dh``). ``smooth``: the
        reference smoothed (``self.smooth``) instead of as it is."""
        s = np.zeros((len(xy), 3)) if shift is None else np.asarray(shift(xy[:, 0], xy[:, 1]), float)
        grid = self.smooth if smooth and self.smooth is not None else self.filled
        return ray_meets_surface(lambda h: prism.ancillary_to_ground(scene, scene.views["N"], xy, h),
                                 lambda en: self.at(grid, en + s[:, :2]) - s[:, 2], self.mean_h)

    def surface(self) -> Surface:
        """The heights (voids NaN) as the adjustment samples them."""
        return Surface(self.dem.heights, float(self.lo[0]), float(self.hi[1]), self.posting_m)


def read_reference(run) -> ReferenceGrid:
    """The reference DEM over the N footprint and the search radius, ellipsoidal, north-up."""
    N, posting_m = run.scene.views["N"], run.posting_m
    rows, cols = run.shape
    corners = N.map_to_image.inverse()(np.array([[0, 0], [cols, 0], [0, rows], [cols, rows]], float))
    lo, hi = corners.min(0) - 1000 - run.radius_m, corners.max(0) + 1000 + run.radius_m
    shape = (int((hi[1] - lo[1]) // posting_m) + 1, int((hi[0] - lo[0]) // posting_m) + 1)
    transform = (posting_m, 0.0, lo[0], 0.0, -posting_m, hi[1])
    ref = read_dem(run.reference_path, run.scene.crs, transform, shape, geoid=run.geoid)
    if not np.isfinite(ref.heights).any():
        raise InputError("the reference DEM does not cover the scene", run.reference_path)
    mean_h = float(np.nanmean(ref.heights))
    # the reference's own cells, in grid cells: the relative DEMs are smoothed to match
    cells = tuple(c / posting_m for c in (ref.source_cell_m or (posting_m, posting_m)))
    filled = np.nan_to_num(ref.heights, nan=mean_h).astype(np.float32)
    gy, gx = np.gradient(filled, posting_m)
    smooth = ndimage.gaussian_filter(filled.astype(float), [PRIOR_SMOOTH_CELLS * c for c in cells[::-1]],
                                     mode="nearest").astype(np.float32)
    return ReferenceGrid(ref, lo, hi, posting_m, mean_h, filled, np.hypot(gx, gy), cells, smooth)


@dataclass(frozen=True)
class PatchCells:
    """One patch of N: its window ``(col0, row0, cols, rows)`` and centre ``x, y`` (N px), the
    share of it matched, its cells (a dict of :class:`~prismstation.core.orientation.field_adjust.Cells`
    fields, empty when it failed) and why it failed ("" when it did not)."""

    window: tuple
    x: float
    y: float
    valid_fraction: float
    cells: dict
    reason: str = ""

    @property
    def count(self) -> int:
        return int(np.size(self.cells.get("h", ())))


def join_cells(pcs) -> tuple[Cells, list[int]]:
    """The matched patches' cells as one :class:`~prismstation.core.orientation.field_adjust.Cells`, the
    adjustment's patch ``j`` being ``pcs[index[j]]`` (patches without cells are left out, and
    the labels stay contiguous: the adjustment counts its patches 0 … n − 1)."""
    index = [k for k, p in enumerate(pcs) if p.count]
    return Cells.join([{**pcs[k].cells, "patch": j} for j, k in enumerate(index)]), index


def match_patches(run, patch_m: float, progress_range=(0.25, 0.8)) -> list[PatchCells]:
    """Every patch of N matched (:func:`match_patch`); InputError when none was."""
    scene, N = run.scene, run.scene.views["N"]
    rows, cols = run.shape
    # the parallax's a-priori σ (px) from the offsets' along-track σ
    centre = np.array([[cols / 2, rows / 2]])
    hit = run.ref.ground(scene, centre)
    en0 = hit.en[0] if hit else prism.ancillary_to_ground(scene, N, centre, run.ref.mean_h)[0]
    d = N.map_to_image.apply_linear(prism.along_track_unit(scene, en0))
    d = d / np.linalg.norm(d)
    sigma_py_off = float(np.hypot(*(np.hypot(*(d * run.coarse.sigma_px[v])) for v in "FB")))
    patch_px = max(int(round(patch_m / N.pixel_size_m)), 64)
    wins = patch_windows((rows, cols), patch_px, margin_px=32)
    images = ImageWindows(scene)
    out = []
    a, b = progress_range
    try:
        for k, win in enumerate(wins):
            checkpoint(run.progress, a + (b - a) * k / len(wins), f"patch {k + 1} of {len(wins)}")
            out.append(match_patch(run, images, win, sigma_py_off))
    finally:
        images.close()
    if not any(p.count for p in out):
        raise InputError("no patch could be matched to the reference DEM: "
                         + "; ".join(sorted({p.reason for p in out})), run.reference_path)
    return out


def _to_n_space(run, scene, view, origin, f) -> np.ndarray:
    """2 × 3 affine from ``view``'s array (f × f blocks read at ``origin``) into decimated N
    space, the view's offset field from N removed: a view sees N's point ``p`` at its
    ancillary prediction plus ``o(p) = o + G·(p − centre)``. A constant (the patch centre's)
    would leave the offsets' drift across the patch — 0.1–0.3 px along track over 4 km on the
    simulated scenes — as a tilt of the relative DEM, metres of shift on gentle slopes."""
    rows, cols = run.shape
    G = np.asarray(run.grads[view], float)
    o0 = np.asarray(run.offsets[view], float) - G @ np.array([cols / 2, rows / 2])
    corr = Affine2D([[1 - G[0, 0], -G[0, 1], -o0[0]], [-G[1, 0], 1 - G[1, 1], -o0[1]]])
    return (scaling(1 / f) @ corr @ prism.to_nadir_space(scene, scene.views[view]) @ shift(*origin)
            @ scaling(f)).matrix


def match_patch(run, images, win, sigma_py_off: float) -> PatchCells:
    """One patch at N-space decimation ``f = run.decimation`` (F and B averaged f×f; SRTM is 90 m
    anyway): its relative DEM gridded at ``run.posting_m``, smoothed to the reference's
    resolution, as cells.

    The prior is the reference where N's ancillary model puts the patch, or where the field
    ``run.n_field`` puts it once one is known, moved by ``run.prior_offset_px`` matched pixels
    (0 but when the prior's pull is measured: :func:`prismstation.ops.dem_unchecked.prior_pull`).
    With ``run.pairs`` the cells also hold ``dh_pairs`` (m): the F–B relative DEM's own error
    as the pair DEMs with N disagree (:func:`_pair_disagreement`), gridded like the heights.
    The parallax search covers K_SIGMA σ of the
    prior's error: the reference heights' σ, the height error of sampling them where N's error
    puts the patch (``run.n_sigma_m`` × the patch's RMS slope: the a-priori geolocation σ, or
    the field's), what the prior's smoothing (:data:`PRIOR_SMOOTH_CELLS`) takes off the relief
    (RMS over the patch) and the offsets' along-track σ ``sigma_py_off`` (px)."""
    scene, ref, f, posting_m = run.scene, run.ref, run.decimation, run.posting_m
    lo, hi = ref.lo, ref.hi
    c1 = prism.theoretical_c1(scene)
    c0, r0, w, h = win
    x, y = c0 + w / 2, r0 + h / 2
    fail = lambda why, frac=0.0: PatchCells(win, x, y, frac, {}, why)  # noqa: E731
    wd = (c0 // f, r0 // f, w // f, h // f)  # the window in decimated N space
    step = 8
    gx, gy = np.meshgrid(np.arange(wd[0] + 0.5, wd[0] + wd[2], step) * f,
                         np.arange(wd[1] + 0.5, wd[1] + wd[3], step) * f)
    pts = np.column_stack([gx.ravel(), gy.ravel()])
    hit = ref.ground(scene, pts, run.n_field, smooth=True)
    if hit.converged.mean() < 0.98:
        return fail(f"N's rays did not meet the reference DEM: {hit.reason}")
    en, hh = hit.en, hit.h
    if not hit:
        # a few rays on steep relief do not settle: the prior there is the median height's
        # (the parallax search covers the difference); 1–8 of 9,409 had cost whole patches
        miss = ~hit.converged
        hh = np.where(miss, np.nanmedian(hh), hh)
        en = np.where(miss[:, None], prism.ancillary_to_ground(scene, scene.views["N"], pts, hh), en)
    rms_slope = float(np.sqrt(np.mean(ref.at(ref.slope, en) ** 2)))
    # what the smoothing took off the relief under the patch (m, RMS)
    rms_smooth = float(np.sqrt(np.mean((ref.at(ref.filled, en) - ref.at(ref.smooth, en)) ** 2)))
    sigma_py = float(np.hypot(np.linalg.norm([run.sigma_height_m, run.n_sigma_m * rms_slope, rms_smooth]) / c1,
                              sigma_py_off))
    search_px = int(np.ceil(K_SIGMA * sigma_py / f)) + 1
    # the samples sit at decimated pixel centres 0.5 + step·k of the window: interpolate there
    # (a plain resize would take them as the centres of step-wide blocks, step/2 − 0.5 off)
    u = (np.arange(wd[2], dtype=np.float32) / step)[None, :].repeat(wd[3], 0)
    v = (np.arange(wd[3], dtype=np.float32) / step)[:, None].repeat(wd[2], 1)
    prior = cv2.remap((hh / c1 / f).reshape(gx.shape).astype(np.float32), u, v, cv2.INTER_LINEAR,
                      borderMode=cv2.BORDER_REPLICATE) + np.float32(run.prior_offset_px)
    d = prism.along_track_unit(scene, en.mean(0))
    reach = float(np.abs(prior).max()) * f + (search_px + 20) * f
    arrays, to_n = {}, {}
    for view in ("F", "B", "N") if run.pairs else ("F", "B"):
        back = prism.to_nadir_space(scene, scene.views[view]).inverse()
        box = np.array([[c0 - reach, r0 - reach], [c0 + w + reach, r0 - reach],
                        [c0 - reach, r0 + h + reach], [c0 + w + reach, r0 + h + reach]], float)
        pc = back(box + (run.offset_of(view, np.array([x, y], float)) if view != "N" else 0.0))
        (a0, b0), (a1, b1) = pc.min(0), pc.max(0)
        # whole f × f blocks from the window's corner (a resize of the rest would stretch it)
        arr, ac0, ar0 = images.read_reduced(view, a0, b0, a1 - a0, b1 - b0, f)
        if arr is None:
            return fail(f"the {view} image does not cover the patch")
        to_n[view] = (_to_n_space(run, scene, view, (ac0, ar0), f) if view != "N" else
                      (scaling(1 / f) @ prism.to_nadir_space(scene, scene.views["N"]) @ shift(ac0, ar0)
                       @ scaling(f)).matrix)
        arrays[view] = arr
    pm = parallax_map(arrays["F"], arrays["B"], to_n["F"], to_n["B"], wd, d, prior=prior,
                      search_range=search_px, half_window=4, n_weight=run.n_weight)
    if pm.valid_fraction < 0.05:
        return fail(f"only {pm.valid_fraction:.0%} of the patch matched", pm.valid_fraction)
    E, Nn, hr = relative_dem_points(scene, pm.parallax * f, wd, c1, step=1, scale=f)
    pad = run.radius_m + 300.0
    elo = np.array([E.min() - pad, Nn.min() - pad]); ehi = np.array([E.max() + pad, Nn.max() + pad])
    i0, i1 = max(int((elo[0] - lo[0]) // posting_m), 0), int((ehi[0] - lo[0]) // posting_m) + 1
    j0, j1 = max(int((hi[1] - ehi[1]) // posting_m), 0), int((hi[1] - elo[1]) // posting_m) + 1
    shape = ref.dem.heights[j0:j1, i0:i1].shape
    t = (posting_m, 0.0, lo[0] + i0 * posting_m, 0.0, -posting_m, hi[1] - j0 * posting_m)
    rel = smooth_like_reference(grid_points(E, Nn, hr, t, shape), ref.cells)
    j, i = np.nonzero(np.isfinite(rel))
    if j.size < 50:
        return fail("too few cells of the relative DEM", pm.valid_fraction)
    e = lo[0] + (i0 + i + 0.5) * posting_m
    n = hi[1] - (j0 + j + 0.5) * posting_m
    hc = rel[j, i]
    xy = prism.ground_to_ancillary(scene, scene.views["N"], np.column_stack([e, n]), hc)
    cells = {"x": xy[:, 0], "y": xy[:, 1], "e": e, "n": n, "h": hc, "row": j0 + j, "col": i0 + i}
    if run.pairs:
        dh = _pair_disagreement(run, arrays, to_n, wd, d, prior, search_px, pm.parallax)
        E2, N2, _ = relative_dem_points(scene, np.where(np.isfinite(dh), pm.parallax, np.nan) * f, wd, c1,
                                        step=1, scale=f)
        dgrid = smooth_like_reference(grid_points(E2, N2, dh[np.isfinite(dh) & np.isfinite(pm.parallax)], t, shape),
                                      ref.cells)
        cells["dh_pairs"] = np.nan_to_num(dgrid[j, i], nan=0.0)
    return PatchCells(win, x, y, pm.valid_fraction, cells)


def _pair_disagreement(run, arrays, to_n, wd, d, prior, search_px: int, py_fb) -> np.ndarray:
    """How the triplet's two pair DEMs with N disagree, as an error of the F–B relative DEM (m)
    on the decimated N window ``wd``: F–N and N–B matched like F–B (their parallax is the share
    ``w`` and ``1 − w`` of F–B's, N's position is F's and N's own), each scaled to F–B's
    parallax, their difference times ``c1·f``. With independent errors of σ per image and
    pixel, F–B's error has variance 2σ² and the difference
    ``σ²·(1/w² + 1/(1 − w)² + 1/(w(1 − w))²)``: scaled by the root of that ratio (1/√12 for
    θ_F = θ_B), it is one draw of F–B's own error (the part each image brings: sampling,
    aliasing, noise), NaN where either pair did not match."""
    wF, f, c1 = run.n_weight, run.decimation, prism.theoretical_c1(run.scene)
    fn = parallax_map(arrays["F"], arrays["N"], to_n["F"], to_n["N"], wd, d, prior=prior * wF,
                      search_range=search_px, half_window=4, n_weight=1.0)
    nb = parallax_map(arrays["N"], arrays["B"], to_n["N"], to_n["B"], wd, d, prior=prior * (1 - wF),
                      search_range=search_px, half_window=4, n_weight=0.0)
    r = np.sqrt(2.0 / (1 / wF ** 2 + 1 / (1 - wF) ** 2 + 1 / (wF * (1 - wF)) ** 2))
    return (fn.parallax / wF - nb.parallax / (1 - wF)) * (c1 * f * r)
