"""Orientation of a triplet from a reference DEM, no GCP (Gonçalves, SRTM as ground control; docs/model.md §3).

Every search takes its range from a stated a-priori uncertainty (docs/orientation_engine.md):

1. Where F and B are relative to N, over the whole range the geolocation σ allows
   (:func:`prismstation.ops.coarse_offsets.coarse_view_offsets`).
2. Per patch of the N image: F and B, with those offsets removed, matched densely in N space
   along the flight direction around the reference DEM's parallax → a relative DEM
   (``h = c1·py``) placed on the map by the ancillary N model, gridded.
3. Where that relative DEM lies on the reference: :func:`prismstation.core.coarse.dem_offset`
   searches the radius N's geolocation σ allows, then least-squares surface matching gives
   ``(dE, dN, dh)`` with σ.
4. The patch shifts are tested against their σ (:func:`prismstation.core.dem_orient.judge_patches`,
   a χ² test with data snooping); the verdict goes into the result, the report and the exit status.
5. Step 1 again, now that N's own error is known to metres: the reference heights under each
   window are taken where N really looks; the patches' shifts follow the new offsets
   (:func:`prismstation.core.dem_orient.reoffset_patches`, no second matching) and are judged again.
6. The shifts of the patches kept become the model (:mod:`prismstation.core.dem_orient`).

A-priori settings: ``sigma_apriori_m`` (each view's ancillary geolocation σ per component; 50 m
by default, after the shifts of about 50 m Gonçalves reports with SRTM as control; Tadono et al. (2008) report ±10 m after calibration),
``sigma_height_m`` (the reference DEM's height σ, 10 m: SRTM's stated 16 m absolute at 90 %),
``k`` = 3 σ per search. ``progress`` per :mod:`prismstation.ops.progress`; a cancel raises
:class:`~prismstation.errors.Cancelled`.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import os

import cv2
import numpy as np

from prismstation.core import prism
from prismstation.core.affine import Affine2D
from prismstation.core.coarse import K_SIGMA, dem_offset
from prismstation.core.consistency import Verdict
from prismstation.core.dem_orient import (PatchShift, affine_field, control_from_shifts, grid_points,
                                          judge_patches, orientation_sigma, patch_windows,
                                          relative_dem_points, reoffset_patches, smooth_like_reference)
from prismstation.core.dense import parallax_map
from prismstation.core.solve import Control
from prismstation.core.sample import remap_points
from prismstation.core.view_offsets import SIGMA_HEIGHT_M, offset_at
from prismstation.errors import InputError
from prismstation.io.dem import read_dem
from prismstation.io.jsonfile import plain
from prismstation.io.project import project_geoid
from prismstation.io.windows import ImageWindows, scaling, shift
from prismstation.model.project import Project
from prismstation.ops.coarse_offsets import SIGMA_APRIORI_M, coarse_view_offsets
from prismstation.ops.progress import ProgressFn, checkpoint, scaled


@dataclass(frozen=True)
class DemOrientation:
    """The result: patches (with shifts, σ and whether used), the view offsets F−N and B−N
    (N-space px, from the ancillary prediction to where the view sees the point), the coarse
    step's record, the consistency verdict of the patch field and the model."""

    reference: str
    patches: tuple
    mean_height: float
    offsets_px: dict
    coarse: dict
    verdict: Verdict
    sigma_apriori_m: float
    control: Control
    sigma_m: dict     # the orientation's σ (m): {"E", "N", "h"}, RMS over the N image
    gradients_px: dict | None = None   # the offsets' gradients over N (px per N pixel, 2 × 2)

    @property
    def sigma_plan_m(self) -> float:
        return float(np.hypot(self.sigma_m["E"], self.sigma_m["N"]))

    @property
    def exit_status(self) -> int:
        return self.verdict.exit_status

    def to_dict(self) -> dict:
        return {"reference": self.reference, "mean_height": self.mean_height,
                "sigma_apriori_m": self.sigma_apriori_m, "offsets_px": self.offsets_px,
                "offset_gradients_px": self.gradients_px, "coarse": self.coarse, "verdict": self.verdict.to_dict(), "sigma_m": self.sigma_m,
                "patches": [plain(asdict(p)) for p in self.patches]}


def apply_orientation(project: Project, result: DemOrientation) -> None:
    """Make ``result`` the project's control and its orientation "dem" (one change event)."""
    with project.batch():
        project.set_dem_control(result.to_dict())
        project.set_settings(replace(project.settings, orientation="dem"))


def control_from_record(scene, record: dict) -> Control:
    """Rebuild the model from a project's saved ``dem_control`` record."""
    patches = [PatchShift(**{**p, "window": tuple(p["window"])}) for p in record["patches"]]
    return control_from_shifts(scene, patches, record["mean_height"], record.get("offsets_px"),
                               offset_gradients=record.get("offset_gradients_px"))


def orient_from_dem(project: Project, reference_path, *, sigma_apriori_m: float = SIGMA_APRIORI_M,
                    sigma_height_m: float = SIGMA_HEIGHT_M, patch_m: float = 4000.0,
                    posting_m: float = 30.0, decimation: int = 2,
                    progress: ProgressFn | None = None) -> DemOrientation:
    """Orient ``project``'s triplet from the reference DEM at ``reference_path`` (see module doc).

    Raises InputError when the views cannot be related (step 1) or no patch matches; an
    untrustworthy patch field is not an error: it is ``result.verdict`` (exit status 3).
    """
    scene = project.scene
    if not scene.is_triplet:
        raise InputError("orientation from a DEM needs an N, F, B triplet")
    missing = [v.image for v in scene.views.values() if not v.image or not os.path.exists(v.image)]
    if missing:
        raise InputError("image not found (relocate the scene's images)", missing[0])
    if not sigma_apriori_m > 0:
        raise InputError(f"the a-priori geolocation σ must be positive, got {sigma_apriori_m} m")
    geoid = project_geoid(project)
    N, F, B = (scene.views[v] for v in "NFB")
    rows, cols = N.shape
    c1 = prism.theoretical_c1(scene)

    # 1. F and B relative to N over the a-priori range
    coarse = coarse_view_offsets(scene, reference_path, geoid, sigma_apriori_m=sigma_apriori_m,
                                 progress=scaled(progress, 0.0, 0.25))
    bad = [v for v in "FB" if not coarse.ok(v)]
    if bad:
        why = "; ".join(dict.fromkeys(w.reason for w in coarse.windows if w.view in bad and w.reason))
        raise InputError(f"view {' and '.join(bad)} could not be found relative to N within "
                         f"{coarse.radius_px:.0f} px (a-priori σ {sigma_apriori_m:g} m per view): "
                         f"{why or 'no window matched'}", reference_path)
    offsets = {v: np.asarray(coarse.offsets_px[v], float) for v in "FB"}
    grads = {v: np.asarray(coarse.gradients_px[v], float) for v in "FB"}

    def offset_of(v, xy):
        return offset_at(offsets[v], grads[v], (cols / 2, rows / 2), xy)

    # reference DEM over the N footprint and the search radius, ellipsoidal, north-up
    radius_m = K_SIGMA * sigma_apriori_m            # N's own error against the reference
    corners = N.map_to_image.inverse()(np.array([[0, 0], [cols, 0], [0, rows], [cols, rows]], float))
    lo, hi = corners.min(0) - 1000 - radius_m, corners.max(0) + 1000 + radius_m
    shape = (int((hi[1] - lo[1]) // posting_m) + 1, int((hi[0] - lo[0]) // posting_m) + 1)
    transform = (posting_m, 0.0, lo[0], 0.0, -posting_m, hi[1])
    ref = read_dem(reference_path, scene.crs, transform, shape, geoid=geoid)
    if not np.isfinite(ref.heights).any():
        raise InputError("the reference DEM does not cover the scene", reference_path)
    mean_h = float(np.nanmean(ref.heights))
    # the reference's own cells, in grid cells: the relative DEMs are smoothed to match
    ref_cells = tuple(c / posting_m for c in (ref.source_cell_m or (posting_m, posting_m)))
    filled = np.nan_to_num(ref.heights, nan=mean_h).astype(np.float32)
    gy, gx = np.gradient(filled, posting_m)
    slope = np.hypot(gx, gy)

    def at(grid, en):
        col = (en[..., 0] - lo[0]) / posting_m - 0.5
        row = (hi[1] - en[..., 1]) / posting_m - 0.5
        return remap_points(grid, col, row).astype(float)

    def ground_at_ref(xy):
        h = np.full(len(xy), mean_h)
        for _ in range(3):
            en = prism.ancillary_to_ground(scene, N, xy, h)
            h = at(filled, en)
        return en, h

    # 2.–3. patches
    # the parallax's a-priori σ (px) from the offsets' along-track σ
    d = N.map_to_image.apply_linear(prism.along_track_unit(scene, ground_at_ref(
        np.array([[cols / 2, rows / 2]]))[0][0]))
    d = d / np.linalg.norm(d)
    sigma_py_off = float(np.hypot(*(np.hypot(*(d * coarse.sigma_px[v])) for v in "FB")))
    patch_px = max(int(round(patch_m / N.pixel_size_m)), 64)
    wins = patch_windows((rows, cols), patch_px, margin_px=32)
    tanF, tanB = F.tan_theta, B.tan_theta
    images = ImageWindows(scene)
    shifts = []
    try:
        for k, win in enumerate(wins):
            checkpoint(progress, 0.25 + 0.7 * k / len(wins), f"patch {k + 1} of {len(wins)}")
            shifts.append(_patch(scene, images, win, ground_at_ref, at, slope, c1, offset_of, sigma_py_off,
                                 sigma_apriori_m, sigma_height_m, radius_m, tanF / (tanF + tanB), ref,
                                 posting_m, lo, hi, decimation, ref_cells))
    finally:
        images.close()
    if not any(p.used for p in shifts):
        raise InputError("no patch could be matched to the reference DEM: "
                         + "; ".join(sorted({p.reason for p in shifts})), reference_path)
    # 4. the field against its σ
    patches, verdict = judge_patches(shifts)
    # 5. N's own error is now known to metres: step 1 again with the reference heights taken
    # where N really looks (tens of metres off on slopes made its windows scatter by pixels,
    # so the offsets' drift over N went unseen), and the patches moved to the new offsets
    field = affine_field(patches)
    second = coarse_view_offsets(scene, reference_path, geoid, sigma_apriori_m=sigma_apriori_m,
                                 n_shift=lambda xy: field(xy[:, 0], xy[:, 1])[..., :2],
                                 progress=scaled(progress, 0.95, 1.0))
    record = coarse.to_dict()
    if not all(second.ok(v) for v in "FB"):
        record["second_pass"] = "not used: " + ("; ".join(
            f"{w.view}: {w.reason}" for w in second.windows if w.reason)[:300] or "a view was not found")
    else:
        new_off = {v: np.asarray(second.offsets_px[v], float) for v in "FB"}
        new_grad = {v: np.asarray(second.gradients_px[v], float) for v in "FB"}
        shifts = reoffset_patches(scene, shifts, lambda v, xy: offset_of(v, xy),
                                  lambda v, xy: offset_at(new_off[v], new_grad[v], (cols / 2, rows / 2), xy),
                                  tanF / (tanF + tanB), mean_h)
        patches, verdict = judge_patches(shifts)
        offsets, grads = new_off, new_grad
        record = {**second.to_dict(), "first_pass": record}
    checkpoint(progress, 1.0, "done")
    offsets = {v: [float(c) for c in o] for v, o in offsets.items()}
    grads = {v: [[float(c) for c in row] for row in g] for v, g in grads.items()}
    control = control_from_shifts(scene, patches, mean_h, offsets, offset_gradients=grads)
    g = (np.arange(5) + 0.5) / 5
    sig = orientation_sigma(patches, *np.meshgrid(g * cols, g * rows))
    sigma_m = {k: float(np.sqrt(np.mean(sig[..., i] ** 2))) for i, k in enumerate("ENh")}
    return DemOrientation(str(reference_path), tuple(patches), mean_h, offsets, record, verdict,
                          float(sigma_apriori_m), control, sigma_m, grads)


def _patch(scene, images, win, ground_at_ref, at, slope, c1, offset_of, sigma_py_off, sigma_apriori_m,
           sigma_height_m, radius_m, n_weight, ref, posting_m, lo, hi, f, ref_cells) -> PatchShift:
    """One patch at N-space decimation ``f`` (F and B averaged f×f; SRTM is 90 m anyway).
    Its relative DEM is gridded at ``posting_m`` and smoothed to the reference's resolution
    (``ref_cells`` grid cells per reference cell: :func:`prismstation.core.dem_orient.smooth_like_reference`).

    The parallax search covers K_SIGMA σ of the prior's error: the reference heights' σ, the
    height error of sampling them where N's error puts the patch (σ_geolocation × the patch's
    RMS slope) and the offsets' along-track σ. ``offset_of(view, xy)``: the view's offset (px)
    from N at N position ``xy``, taken at the patch's centre."""
    c0, r0, w, h = win
    x, y = c0 + w / 2, r0 + h / 2
    fail = lambda why: PatchShift(win, x, y, *(np.nan,) * 6, 0, 0.0, False, why)  # noqa: E731
    wd = (c0 // f, r0 // f, w // f, h // f)  # the window in decimated N space
    step = 8
    gx, gy = np.meshgrid(np.arange(wd[0] + 0.5, wd[0] + wd[2], step) * f,
                         np.arange(wd[1] + 0.5, wd[1] + wd[3], step) * f)
    en, hh = ground_at_ref(np.column_stack([gx.ravel(), gy.ravel()]))
    rms_slope = float(np.sqrt(np.mean(at(slope, en) ** 2)))
    sigma_py = float(np.hypot(np.hypot(sigma_height_m, sigma_apriori_m * rms_slope) / c1, sigma_py_off))
    search_px = int(np.ceil(K_SIGMA * sigma_py / f)) + 1
    # the samples sit at decimated pixel centres 0.5 + step·k of the window: interpolate there
    # (a plain resize would take them as the centres of step-wide blocks, step/2 − 0.5 off)
    u = (np.arange(wd[2], dtype=np.float32) / step)[None, :].repeat(wd[3], 0)
    v = (np.arange(wd[3], dtype=np.float32) / step)[:, None].repeat(wd[2], 1)
    prior = cv2.remap((hh / c1 / f).reshape(gx.shape).astype(np.float32), u, v, cv2.INTER_LINEAR,
                      borderMode=cv2.BORDER_REPLICATE)
    d = prism.along_track_unit(scene, en.mean(0))
    reach = float(np.abs(prior).max()) * f + (search_px + 20) * f
    arrays, to_n = {}, {}
    for v in ("F", "B"):
        view = scene.views[v]
        back = prism.to_nadir_space(scene, view).inverse()
        box = np.array([[c0 - reach, r0 - reach], [c0 + w + reach, r0 - reach],
                        [c0 - reach, r0 + h + reach], [c0 + w + reach, r0 + h + reach]], float)
        o = offset_of(v, np.array([x, y], float))
        pc = back(box + o)
        (a0, b0), (a1, b1) = pc.min(0), pc.max(0)
        # whole f × f blocks from the window's corner (a resize of the rest would stretch it)
        arr, ac0, ar0 = images.read_reduced(v, a0, b0, a1 - a0, b1 - b0, f)
        if arr is None:
            return fail(f"the {v} image does not cover the patch")
        corr = Affine2D([[1, 0, -o[0]], [0, 1, -o[1]]])
        to_n[v] = (scaling(1 / f) @ corr @ prism.to_nadir_space(scene, view) @ shift(ac0, ar0) @ scaling(f)).matrix
        arrays[v] = arr
    pm = parallax_map(arrays["F"], arrays["B"], to_n["F"], to_n["B"], wd, d, prior=prior,
                      search_range=search_px, half_window=4, n_weight=n_weight)
    if pm.valid_fraction < 0.05:
        return fail(f"only {pm.valid_fraction:.0%} of the patch matched")
    E, Nn, hr = relative_dem_points(scene, pm.parallax * f, wd, c1, step=1, scale=f)
    pad = radius_m + 300.0
    elo = np.array([E.min() - pad, Nn.min() - pad]); ehi = np.array([E.max() + pad, Nn.max() + pad])
    i0, i1 = int((elo[0] - lo[0]) // posting_m), int((ehi[0] - lo[0]) // posting_m) + 1
    j0, j1 = int((hi[1] - ehi[1]) // posting_m), int((hi[1] - elo[1]) // posting_m) + 1
    i0, j0 = max(i0, 0), max(j0, 0)
    refp = ref.heights[j0:j1, i0:i1]
    t = (posting_m, 0.0, lo[0] + i0 * posting_m, 0.0, -posting_m, hi[1] - j0 * posting_m)
    rel = smooth_like_reference(grid_points(E, Nn, hr, t, refp.shape), ref_cells)
    if np.isfinite(rel).sum() < 50:
        return fail("too few cells of the relative DEM")
    r = dem_offset(refp, rel, t, radius_m)
    if not r.converged or not np.isfinite([r.dx, r.dy, r.dz]).all():
        return fail(r.reason or "surface matching did not converge (flat terrain?)")
    return PatchShift(win, x, y, r.dx, r.dy, r.dz, r.sigma_dx, r.sigma_dy, r.sigma_dz, r.count,
                      pm.valid_fraction)
