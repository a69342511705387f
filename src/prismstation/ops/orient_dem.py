"""Orientation of a triplet from a reference DEM, no GCP (seed 003, MODEL.md §3): the workflow.

1. Ancillary model only; the reference DEM (orthometric → ellipsoidal through the project's
   geoid) gives the expected heights.
2. Tie points on a lattice, matched N→F and N→B, measure the across-track offsets F−N and
   B−N (the paper's relative orientation, Table 2) and the along-track offset of the parallax.
3. Per patch of the N image: F and B matched densely in N space along the flight direction →
   parallax → relative DEM (``h = c1·py``) placed on the map by the ancillary model, gridded,
   and laid on the reference by least-squares surface matching → shift ``(dE, dN, dh)`` with σ.
4. Outlying patches rejected; the shifts become the model (:mod:`prismstation.core.dem_orient`).
``progress`` per :mod:`prismstation.ops.progress`; a cancel raises
:class:`~prismstation.errors.Cancelled`.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import os

import cv2
import numpy as np

from prismstation.core import prism
from prismstation.core.affine import Affine2D
from prismstation.core.coreg import coregister
from prismstation.core.dem_orient import (PatchShift, control_from_shifts, grid_points, patch_windows,
                                          reject_outlier_patches, relative_dem_points)
from prismstation.core.dense import parallax_map
from prismstation.core.matching import match_point
from prismstation.core.solve import Control
from prismstation.errors import InputError
from prismstation.io.dem import read_dem
from prismstation.io.jsonfile import plain
from prismstation.io.project import project_geoid
from prismstation.io.windows import ImageWindows, scaling, shift
from prismstation.model.project import Project
from prismstation.ops.progress import ProgressFn, checkpoint


@dataclass(frozen=True)
class DemOrientation:
    reference: str
    patches: tuple
    mean_height: float
    offsets_px: dict          # 'F', 'B' -> where the view sees a point relative to the
    #                           ancillary prediction from N (N-space pixel vector, median of ties)
    across_px: dict           # the across-track components (the paper's Table 2)
    ties: int                 # tie points matched in all three views
    control: Control

    def to_dict(self) -> dict:
        return {"reference": self.reference, "mean_height": self.mean_height,
                "offsets_px": self.offsets_px, "across_px": self.across_px, "ties": self.ties,
                "patches": [plain(asdict(p)) for p in self.patches]}


def apply_orientation(project: Project, result: DemOrientation) -> None:
    """Make ``result`` the project's control and its orientation "dem" (one change event)."""
    with project.batch():
        project.set_dem_control(result.to_dict())
        project.set_settings(replace(project.settings, orientation="dem"))


def control_from_record(scene, record: dict) -> Control:
    """Rebuild the model from a project's saved ``dem_control`` record."""
    patches = [PatchShift(**{**p, "window": tuple(p["window"])}) for p in record["patches"]]
    return control_from_shifts(scene, patches, record["mean_height"], record.get("offsets_px"))


def orient_from_dem(project: Project, reference_path, *, patch_m: float = 4000.0, posting_m: float = 30.0,
                    search_px: int = 12, ties: int = 7, decimation: int = 2,
                    progress: ProgressFn | None = None) -> DemOrientation:
    """Orient ``project``'s triplet from the reference DEM at ``reference_path`` (see module doc)."""
    scene = project.scene
    if not scene.is_triplet:
        raise InputError("orientation from a DEM needs an N, F, B triplet")
    missing = [v.image for v in scene.views.values() if not v.image or not os.path.exists(v.image)]
    if missing:
        raise InputError("image not found (relocate the scene's images)", missing[0])
    geoid = project_geoid(project)
    N, F, B = (scene.views[v] for v in "NFB")
    rows, cols = N.shape
    c1 = prism.theoretical_c1(scene)
    # reference DEM over the whole N footprint, ellipsoidal, north-up in the scene CRS
    corners = N.map_to_image.inverse()(np.array([[0, 0], [cols, 0], [0, rows], [cols, rows]], float))
    lo, hi = corners.min(0) - 1000, corners.max(0) + 1000
    shape = (int((hi[1] - lo[1]) // posting_m) + 1, int((hi[0] - lo[0]) // posting_m) + 1)
    transform = (posting_m, 0.0, lo[0], 0.0, -posting_m, hi[1])
    ref = read_dem(reference_path, scene.crs, transform, shape, geoid=geoid)
    if not np.isfinite(ref.heights).any():
        raise InputError("the reference DEM does not cover the scene", reference_path)
    mean_h = float(np.nanmean(ref.heights))

    def ref_height(en):
        col = (en[..., 0] - lo[0]) / posting_m - 0.5
        row = (hi[1] - en[..., 1]) / posting_m - 0.5
        hh = cv2.remap(np.nan_to_num(ref.heights, nan=mean_h).astype(np.float32),
                       col.astype(np.float32).reshape(-1, 1), row.astype(np.float32).reshape(-1, 1),
                       cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return hh.reshape(col.shape).astype(float)

    def ground_at_ref(xy):
        h = np.full(len(xy), mean_h)
        for _ in range(3):
            en = prism.ancillary_to_ground(scene, N, xy, h)
            h = ref_height(en)
        return en, h

    images = ImageWindows(scene)
    try:
        # 2. tie points: across-track offsets and the parallax offset
        g = (np.arange(ties) + 0.5) / ties
        txy = np.column_stack([np.tile(g * cols, ties), np.repeat(g * rows, ties)])
        ten, th = ground_at_ref(txy)
        d_n = prism.along_track_unit(scene, ten)
        cross = np.column_stack([d_n[:, 1], -d_n[:, 0]])
        found = {"F": [], "B": []}
        for i, (xy, en, h) in enumerate(zip(txy, ten, th)):
            checkpoint(progress, 0.15 * i / len(txy), "matching tie points")
            nwin, nc0, nr0 = images.read("N", xy[0] - 40, xy[1] - 40, 80, 80)
            for v in ("F", "B"):
                view = scene.views[v]
                pred = prism.ground_to_ancillary(scene, view, en, h)
                sw, sc0, sr0 = images.read(v, pred[0] - 110, pred[1] - 110, 220, 220)
                if nwin is None or sw is None:
                    continue
                dv = view.map_to_image.apply_linear(prism.scene_track_dir(scene, en))
                m = match_point(nwin, xy[0] - nc0, xy[1] - nr0, sw, pred[0] - sc0, pred[1] - sr0,
                                direction=dv, search_range=60, across_range=12, half_window=12,
                                min_score=0.6)
                if m.ok:
                    pv = prism.to_nadir_space(scene, view)(np.array([m.x + sc0, m.y + sr0]))
                    pp = prism.to_nadir_space(scene, view)(pred)
                    found[v].append((i, pv - pp, float((pv - xy) @ cross[i])))
        both = {i for i, _, _ in found["F"]} & {i for i, _, _ in found["B"]}
        if len(both) < 3:
            raise InputError("fewer than 3 tie points matched in N, F and B: images too different "
                             "or the reference DEM does not fit the scene", reference_path)
        offsets = {v: np.median([o for _, o, _ in found[v]], axis=0) for v in found}
        across = {v: float(np.median([a for _, _, a in found[v]])) for v in found}

        # 3. patches
        patch_px = max(int(round(patch_m / N.pixel_size_m)), 64)
        wins = patch_windows((rows, cols), patch_px, margin_px=max(search_px, 16))
        tanF, tanB = F.tan_theta, B.tan_theta
        shifts = []
        for k, win in enumerate(wins):
            checkpoint(progress, 0.15 + 0.8 * k / len(wins), f"patch {k + 1} of {len(wins)}")
            shifts.append(_patch(scene, images, win, ground_at_ref, c1, offsets, search_px,
                                 tanF / (tanF + tanB), ref, posting_m, lo, hi, decimation))
    finally:
        images.close()
    patches = reject_outlier_patches(shifts)
    if sum(p.used for p in patches) == 0:
        raise InputError("no patch could be matched to the reference DEM", reference_path)
    checkpoint(progress, 1.0, "done")
    offsets = {v: [float(c) for c in o] for v, o in offsets.items()}
    control = control_from_shifts(scene, patches, mean_h, offsets)
    return DemOrientation(str(reference_path), tuple(patches), mean_h, offsets, across, len(both), control)


def _patch(scene, images, win, ground_at_ref, c1, offsets, search_px, n_weight,
           ref, posting_m, lo, hi, f) -> PatchShift:
    """One patch at N-space decimation ``f`` (F and B averaged f×f; SRTM is 90 m anyway)."""
    c0, r0, w, h = win
    x, y = c0 + w / 2, r0 + h / 2
    fail = lambda why: PatchShift(win, x, y, *(np.nan,) * 6, 0, 0.0, False, why)  # noqa: E731
    wd = (c0 // f, r0 // f, w // f, h // f)  # the window in decimated N space
    step = 8
    gx, gy = np.meshgrid(np.arange(wd[0] + 0.5, wd[0] + wd[2], step) * f,
                         np.arange(wd[1] + 0.5, wd[1] + wd[3], step) * f)
    en, hh = ground_at_ref(np.column_stack([gx.ravel(), gy.ravel()]))
    prior = cv2.resize((hh / c1 / f).reshape(gx.shape).astype(np.float32), (wd[2], wd[3]),
                       interpolation=cv2.INTER_LINEAR)
    d = prism.along_track_unit(scene, en.mean(0))
    reach = float(np.abs(prior).max()) * f + (search_px + 20) * f
    arrays, to_n = {}, {}
    for v in ("F", "B"):
        view = scene.views[v]
        back = prism.to_nadir_space(scene, view).inverse()
        box = np.array([[c0 - reach, r0 - reach], [c0 + w + reach, r0 - reach],
                        [c0 - reach, r0 + h + reach], [c0 + w + reach, r0 + h + reach]], float)
        pc = back(box)
        (a0, b0), (a1, b1) = pc.min(0), pc.max(0)
        arr, ac0, ar0 = images.read(v, a0, b0, a1 - a0, b1 - b0)
        if arr is None:
            return fail(f"the {v} image does not cover the patch")
        if f > 1:
            arr = cv2.resize(arr, (arr.shape[1] // f, arr.shape[0] // f), interpolation=cv2.INTER_AREA)
        o = np.asarray(offsets[v], float)
        corr = Affine2D([[1, 0, -o[0]], [0, 1, -o[1]]])
        to_n[v] = (scaling(1 / f) @ corr @ prism.to_nadir_space(scene, view) @ shift(ac0, ar0) @ scaling(f)).matrix
        arrays[v] = arr
    pm = parallax_map(arrays["F"], arrays["B"], to_n["F"], to_n["B"], wd, d, prior=prior,
                      search_range=search_px, half_window=4, n_weight=n_weight)
    if pm.valid_fraction < 0.05:
        return fail(f"only {pm.valid_fraction:.0%} of the patch matched")
    E, Nn, hr = relative_dem_points(scene, pm.parallax * f, wd, c1, step=1, scale=f)
    pad = 300.0
    elo = np.array([E.min() - pad, Nn.min() - pad]); ehi = np.array([E.max() + pad, Nn.max() + pad])
    i0, i1 = int((elo[0] - lo[0]) // posting_m), int((ehi[0] - lo[0]) // posting_m) + 1
    j0, j1 = int((hi[1] - ehi[1]) // posting_m), int((hi[1] - elo[1]) // posting_m) + 1
    i0, j0 = max(i0, 0), max(j0, 0)
    refp = ref.heights[j0:j1, i0:i1]
    t = (posting_m, 0.0, lo[0] + i0 * posting_m, 0.0, -posting_m, hi[1] - j0 * posting_m)
    rel = grid_points(E, Nn, hr, t, refp.shape)
    if np.isfinite(rel).sum() < 50:
        return fail("too few cells of the relative DEM")
    r = coregister(refp, rel, t)
    if not r.converged or not np.isfinite([r.dx, r.dy, r.dz]).all():
        return fail("surface matching did not converge (flat terrain?)")
    return PatchShift(win, x, y, r.dx, r.dy, r.dz, r.sigma_dx, r.sigma_dy, r.sigma_dz, r.count,
                      pm.valid_fraction)
