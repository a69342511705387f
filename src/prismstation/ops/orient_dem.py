"""Orientation of a triplet from a reference DEM, no GCP needed (Gonçalves, SRTM as ground control; docs/model.md §3).

Every search takes its range from a stated a-priori uncertainty (docs/orientation_engine.md):

1. Where F and B are relative to N, over the whole range the geolocation σ allows
   (:func:`prismstation.ops.coarse_offsets.coarse_view_offsets`).
2. What the terrain can fix: the field's σ expected from the reference's gradients over N's
   footprint (:mod:`prismstation.core.orientation.conditioning`), before any matching.
3. Per patch of the N image: F and B, with those offsets removed, matched densely in N space →
   relative-DEM cells (:mod:`prismstation.ops.dem_patches`).
4. One adjustment of the shift field ``(dE, dN, dh)`` over N from every cell of every patch
   (:func:`prismstation.core.orientation.field_adjust.adjust_field`), started from a search of the whole
   mosaic over the a-priori radius; GCPs, when given, are observations of the same field.
5. Step 1 again with N placed by that field, every patch matched again with the new offsets
   and the reference laid where the field puts N, the field adjusted again.
6. The verdict on the field's σ against the target (:func:`prismstation.core.orientation.conditioning.judge`)
   and the model (:func:`prismstation.core.orientation.dem_orient.control_from_field`).

A-priori settings: ``sigma_apriori_m`` (each view's ancillary geolocation σ per component; 50 m
by default, after the shifts of about 50 m Gonçalves reports with SRTM as control; Tadono et al.
(2008) report ±10 m after calibration), ``sigma_height_m`` (the reference DEM's height σ, 10 m:
SRTM's stated 16 m absolute at 90 %), ``k`` = 3 σ per search, ``target_m`` (the σ an
orientation must reach to be trusted, 2.5 m). ``progress`` per :mod:`prismstation.ops.progress`;
a cancel raises :class:`~prismstation.errors.Cancelled`.
"""
from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass

import numpy as np

from prismstation.core.orientation import conditioning as cond
from prismstation.core.models import prism
from prismstation.core.matching.coarse import K_SIGMA, dem_offset
from prismstation.core.orientation.dem_orient import ControlPoints, PatchShift, control_from_field, gcp_field_obs
from prismstation.core.orientation.field_adjust import Cells, adjust_field
from prismstation.core.orientation.field_model import Basis, Distortion
from prismstation.core.models.solution import Control
from prismstation.core.orientation.view_offsets import SIGMA_FIELD_PX, SIGMA_HEIGHT_M, n_along_sigma_px, offset_at
from prismstation.errors import InputError
from prismstation.io.jsonfile import plain
from prismstation.io.project import project_geoid
from prismstation.model.project import Project
from prismstation.ops.coarse_offsets import SIGMA_APRIORI_M, coarse_view_offsets
from prismstation.ops import dem_unchecked as unchecked
from prismstation.ops.dem_patches import ReferenceGrid, join_cells, match_patches, read_reference
from prismstation.ops.fit import ellipsoidal_heights
from prismstation.ops.progress import ProgressFn, checkpoint, scaled

TARGET_M = cond.TARGET_M            # the front ends' default target σ (m)
SigmaSummary = cond.SigmaSummary


@dataclass(frozen=True)
class DemOrientation:
    """The result: the patches (their shifts, σ, whether used), the view offsets F−N and B−N
    (N-space px, from the ancillary prediction to where the view sees the point) and their
    gradients, the coarse step's record, the adjusted field (``field``: its parameters and
    covariance), the σ expected from the terrain before the run and the σ stated after it
    (:class:`~prismstation.core.orientation.conditioning.SigmaSummary` dicts, m), the verdict and the model."""

    reference: str
    patches: tuple
    mean_height: float
    offsets_px: dict
    coarse: dict
    verdict: cond.OrientVerdict
    sigma_apriori_m: float
    control: Control
    sigma_m: dict
    gradients_px: dict | None = None
    field: dict | None = None
    expected_sigma_m: dict | None = None
    adjustment: dict | None = None

    @property
    def sigma_plan_m(self) -> float:
        return float(np.hypot(self.sigma_m["E"], self.sigma_m["N"]))

    @property
    def exit_status(self) -> int:
        return self.verdict.exit_status

    def to_dict(self) -> dict:
        return plain({"reference": self.reference, "mean_height": self.mean_height,
                      "sigma_apriori_m": self.sigma_apriori_m, "offsets_px": self.offsets_px,
                      "offset_gradients_px": self.gradients_px, "coarse": self.coarse,
                      "verdict": self.verdict.to_dict(), "sigma_m": self.sigma_m,
                      "expected_sigma_m": self.expected_sigma_m, "field": self.field,
                      "adjustment": self.adjustment, "patches": [asdict(p) for p in self.patches]})


@dataclass
class OrientRun:
    """What the steps of :func:`orient_from_dem` share: the project's scene and geoid, the
    a-priori settings, and what the steps find (the view offsets, the reference grid)."""

    scene: object
    reference_path: object
    geoid: object
    sigma_apriori_m: float
    sigma_height_m: float
    posting_m: float
    decimation: int
    progress: ProgressFn | None
    coarse: object = None         # step 1: the coarse offsets (CoarseOffsets)
    offsets: dict = None          # F−N and B−N at N's centre (N-space px), from step 1 (then 5)
    grads: dict = None            # their gradients over N (px per N pixel)
    ref: ReferenceGrid = None     # the reference DEM on the matching's grid
    n_field: object = None        # N's shift field once adjusted (step 5 matches with it)
    n_field_sigma_m: float = None  # its planimetric σ (m)
    prior_offset_px: float = 0.0  # the dense prior moved by this (matched px): the pull's measurement
    prior_field: tuple = (None, None)  # (field, σ) the last patches' priors were laid with
    pairs: bool = False           # match the pair DEMs F–N and N–B too (the second pass)

    @property
    def shape(self) -> tuple[int, int]:
        return self.scene.views["N"].shape

    @property
    def radius_m(self) -> float:
        """How far N's own error may put it from the reference (K_SIGMA σ)."""
        return K_SIGMA * self.sigma_apriori_m

    @property
    def n_sigma_m(self) -> float:
        """σ (m) of N's position where the patches' priors are taken: the a-priori geolocation
        σ, then the adjusted field's."""
        return self.sigma_apriori_m if self.n_field is None else self.n_field_sigma_m

    @property
    def n_weight(self) -> float:
        """N's weight between F and B along track: tan θ_F / (tan θ_F + tan θ_B)."""
        tanF, tanB = (self.scene.views[v].tan_theta for v in "FB")
        return tanF / (tanF + tanB)

    def offset_of(self, v: str, xy) -> np.ndarray:
        """View ``v``'s offset from N (px) at N positions ``xy`` (..., 2)."""
        rows, cols = self.shape
        return offset_at(self.offsets[v], self.grads[v], (cols / 2, rows / 2), xy)

    def distortion(self) -> Distortion:
        """The relative DEMs' height distortion along the track the adjustment allows for
        (:class:`~prismstation.core.orientation.field_model.Distortion`): the N-space flight direction at
        N's centre, ``t = ±1`` at the image's ends."""
        rows, cols = self.shape
        N = self.scene.views["N"]
        en = prism.ancillary_to_ground(self.scene, N, np.array([[cols / 2, rows / 2]]), self.ref.mean_h)
        d = prism.along_track_unit(self.scene, en)[0]
        return Distortion((cols / 2.0, rows / 2.0), max(rows, cols) / 2.0, tuple(float(v) for v in d))

    @property
    def distortion_sigma_m(self) -> float:
        """A-priori σ (m) of each term of the height distortion: F's and B's offsets may each
        vary across the scene by :data:`~prismstation.core.orientation.view_offsets.SIGMA_FIELD_PX` beyond
        what a constant describes; their difference is a parallax of √2 times that, ``c1`` m
        of height per pixel."""
        return float(prism.theoretical_c1(self.scene) * SIGMA_FIELD_PX * np.sqrt(2.0))

    def along(self) -> np.ndarray:
        """The flight direction on the map (unit E, N) at N's centre."""
        rows, cols = self.shape
        en = prism.ancillary_to_ground(self.scene, self.scene.views["N"], np.array([[cols / 2, rows / 2]]),
                                       self.ref.mean_h)
        t = self.scene.track.foot(en)[1].reshape(-1, 2)[0]
        return t / np.linalg.norm(t)


def orient_from_dem(project: Project, reference_path, *, sigma_apriori_m: float = SIGMA_APRIORI_M,
                    sigma_height_m: float = SIGMA_HEIGHT_M, patch_m: float = 4000.0,
                    posting_m: float = 30.0, decimation: int = 2, target_m: float = cond.TARGET_M,
                    gcps: ControlPoints | None = None, progress: ProgressFn | None = None) -> DemOrientation:
    """Orient ``project``'s triplet from the reference DEM at ``reference_path`` (see module
    doc). ``gcps``: ground control points (:func:`control_points`), observations of the same
    shift field adjusted with the DEM's cells: they fix its frame, the cells its shape.

    Raises InputError when the views cannot be related (step 1) or no patch matches; an
    orientation that cannot be trusted is not an error: it is ``result.verdict`` (exit status 3).
    """
    scene = project.scene
    if not scene.is_triplet:
        raise InputError("orientation from a DEM needs an N, F, B triplet")
    missing = [v.image for v in scene.views.values() if not v.image or not os.path.exists(v.image)]
    if missing:
        raise InputError("image not found (relocate the scene's images)", missing[0])
    if not 0 < sigma_apriori_m < math.inf:
        raise InputError(f"the a-priori geolocation σ must be a positive number of metres, got {sigma_apriori_m}")
    if not 0 < target_m < math.inf:
        raise InputError(f"the target σ must be a positive number of metres, got {target_m}")
    run = OrientRun(scene, reference_path, project_geoid(project), sigma_apriori_m, sigma_height_m,
                    posting_m, decimation, progress)
    relate_views(run)                                                   # 1.
    run.ref = read_reference(run)
    expected = expected_sigma(run)                                      # 2.
    pcs = match_patches(run, patch_m, progress_range=(0.25, 0.55))      # 3.
    cells, index = join_cells(pcs)
    checkpoint(progress, 0.55, "adjusting the shift field")
    fit = adjust(run, cells, len(index), start_field(run, cells), gcps)  # 4.
    record = run.coarse.to_dict()
    pull = None
    if fit:
        pcs, index, fit, record = second_pass(run, pcs, index, fit, patch_m, gcps)  # 5.
        refit = lambda cells, n: adjust(run, cells, n, fit.theta, gcps)  # noqa: E731
        cells, _ = join_cells(pcs)
        refit_from = lambda theta0: adjust(run, cells, len(index), theta0, gcps)  # noqa: E731
        pull = {"prior": unchecked.prior_pull(run, patch_m, fit, refit),
                "pairs": unchecked.pair_term(pcs, index, fit, refit),
                "start": unchecked.start_term(fit, refit_from, run.posting_m, run.sigma_apriori_m)}
    checkpoint(progress, 1.0, "done")
    return make_result(run, pcs, index, fit, expected, record, target_m, gcps, pull)  # 6.


def relate_views(run: OrientRun) -> None:
    """Step 1: F and B relative to N over the a-priori range; sets ``run.coarse``,
    ``run.offsets``, ``run.grads``."""
    coarse = coarse_view_offsets(run.scene, run.reference_path, run.geoid, sigma_apriori_m=run.sigma_apriori_m,
                                 progress=scaled(run.progress, 0.0, 0.25))
    bad = [v for v in "FB" if not coarse.ok(v)]
    if bad:
        why = "; ".join(dict.fromkeys(w.reason for w in coarse.windows if w.view in bad and w.reason))
        raise InputError(f"view {' and '.join(bad)} could not be found relative to N within "
                         f"{coarse.radius_px:.0f} px (a-priori σ {run.sigma_apriori_m:g} m per view): "
                         f"{why or 'no window matched'}", run.reference_path)
    run.offsets = {v: np.asarray(coarse.offsets_px[v], float) for v in "FB"}
    run.grads = {v: np.asarray(coarse.gradients_px[v], float) for v in "FB"}
    run.coarse = coarse


def prior_sigma(run: OrientRun) -> np.ndarray:
    """(9,) a-priori σ (m) of the field's terms: N's geolocation σ for every term (the field
    at the image's edge may differ from its centre by as much again, attitude drift)."""
    return np.full(9, float(run.sigma_apriori_m))


def expected_sigma(run: OrientRun, step_px: int | None = None) -> cond.SigmaSummary:
    """Step 2: the field's σ the terrain allows, from the reference's gradients where N's
    ancillary model puts its footprint: every reference cell a matched cell of a-priori σ
    :data:`~prismstation.core.orientation.conditioning.SIGMA_CELL_M`."""
    rows, cols = run.shape
    N = run.scene.views["N"]
    step = step_px or max(int(round(run.posting_m / N.pixel_size_m)), 1)
    step = max(step, int(np.ceil(max(rows, cols) / 400)))          # at most 400 × 400 samples
    x, y = np.meshgrid(np.arange(step / 2, cols, step), np.arange(step / 2, rows, step))
    xy = np.column_stack([x.ravel(), y.ravel()])
    en = prism.ancillary_to_ground(run.scene, N, xy, run.ref.mean_h)
    gy, gx = np.gradient(run.ref.filled.astype(float), run.posting_m)
    gx, gy = run.ref.at(gx, en), -run.ref.at(gy, en)
    ok = np.isfinite(gx) & np.isfinite(gy)
    basis = Basis.over(run.shape)
    cells_per_sample = (step * N.pixel_size_m / run.posting_m) ** 2
    w = cells_per_sample / (cond.SIGMA_CELL_M ** 2 * cond.a_priori_area(run.ref.cells))
    dist = run.distortion()
    info = cond.information(gx[ok], gy[ok], basis.phi(xy[ok, 0], xy[ok, 1]), w, dist.psi(xy[ok, 0], xy[ok, 1]))
    cov = cond.expected_cov(info, np.r_[prior_sigma(run), np.full(len(dist), run.distortion_sigma_m)])[:9, :9]
    lx, ly = cond.lattice(run.shape)
    p = basis.phi(lx, ly)
    Phi = np.einsum("kl,ni->nkli", np.eye(3), p).reshape(len(lx), 3, 9)
    return cond.summarise(Phi @ cov @ np.swapaxes(Phi, 1, 2), run.along())


def start_field(run: OrientRun, cells: Cells) -> np.ndarray:
    """The adjustment's start (9,): the whole mosaic of relative DEMs laid on the reference by
    an exhaustive search over the a-priori radius (:func:`prismstation.core.matching.coarse.dem_offset`)
    — a constant shift; where that finds nothing (a plane), the median height difference."""
    ref = run.ref
    mosaic = np.full(ref.dem.heights.shape, np.nan)
    mosaic[cells.row, cells.col] = cells.h
    t = (run.posting_m, 0.0, float(ref.lo[0]), 0.0, -run.posting_m, float(ref.hi[1]))
    theta = np.zeros(9)
    r = dem_offset(ref.dem.heights, mosaic, t, run.radius_m)
    if r and np.isfinite([r.dx, r.dy, r.dz]).all():
        theta[[0, 3, 6]] = r.dx, r.dy, r.dz
    else:
        diff = ref.dem.heights[cells.row, cells.col] - cells.h
        theta[6] = float(np.nanmedian(diff)) if np.isfinite(diff).any() else 0.0
    return theta


def adjust(run: OrientRun, cells: Cells, n_patches: int, theta0, gcps: ControlPoints | None):
    """Step 4: :func:`prismstation.core.orientation.field_adjust.adjust_field` over all cells (and the GCPs,
    observations of the field made with the run's current view offsets)."""
    obs = None
    if gcps is not None and len(gcps):
        obs = gcp_field_obs(run.scene, gcps.xy_f, gcps.xy_b, gcps.ground, gcps.sigma_m, run.offset_of,
                            run.n_weight, gcps.ids)
    return adjust_field(cells, run.ref.surface(), Basis.over(run.shape), theta0, n_patches=n_patches,
                        prior_sigma=prior_sigma(run), obs=obs, distortion=run.distortion(),
                        distortion_sigma=run.distortion_sigma_m)


def control_points(project: Project, ids=None, sigma_px: float = 0.3, survey_sigma_m=(1.0, 1.0)) -> ControlPoints:
    """The project's GCPs (or those in ``ids``) measured in F and B, as
    :class:`~prismstation.core.orientation.dem_orient.ControlPoints`: heights made ellipsoidal through the
    project's geoid; σ of each shift: its survey σ (``sigma_xy_m``, ``sigma_h_m``; where the
    point states none, ``survey_sigma_m`` (planimetric per component, height)) and its image
    measurements' (their ``sigma_px``, else ``sigma_px``) in quadrature."""
    scene = project.scene
    h = ellipsoidal_heights(project)
    gsd, c1 = scene.views["N"].pixel_size_m, prism.theoretical_c1(scene)
    rows = []
    for pid, p in project.points.items():
        mf, mb = project.measurements.get((pid, "F")), project.measurements.get((pid, "B"))
        if p.kind != "GCP" or pid not in h or mf is None or mb is None or (ids is not None and pid not in ids):
            continue
        spx = max(m.sigma_px if m.sigma_px is not None else sigma_px for m in (mf, mb))
        sxy = p.sigma_xy_m if p.sigma_xy_m is not None else survey_sigma_m[0]
        sh = p.sigma_h_m if p.sigma_h_m is not None else survey_sigma_m[1]
        rows.append((pid, (mf.x, mf.y), (mb.x, mb.y), (p.E, p.N, h[pid]),
                     (np.hypot(sxy, spx * gsd), np.hypot(sxy, spx * gsd), np.hypot(sh, c1 * spx * np.sqrt(2)))))
    if not rows:
        raise InputError("no GCP measured in both F and B to orient with the reference DEM")
    ids_, f, b, g, s = zip(*rows)
    return ControlPoints(tuple(ids_), np.array(f, float), np.array(b, float), np.array(g, float), np.array(s, float))


def second_pass(run: OrientRun, pcs, index, fit, patch_m: float, gcps):
    """Step 5: N's own error is now known to metres: step 1 again with the reference heights
    taken where N really looks (tens of metres off on slopes made its windows scatter by
    pixels, so the offsets' drift over N went unseen), every patch matched again with the new
    offsets and its prior taken where the field puts N, and the field adjusted again from the
    first one. Returns ``(pcs, index, fit, record)`` — the first pass's where the second
    fails; updates ``run.offsets``, ``run.grads``."""
    second = coarse_view_offsets(run.scene, run.reference_path, run.geoid, sigma_apriori_m=run.sigma_apriori_m,
                                 n_shift=lambda xy: fit.field(xy[:, 0], xy[:, 1])[..., :2],
                                 progress=scaled(run.progress, 0.55, 0.65))
    record = run.coarse.to_dict()
    if not all(second.ok(v) for v in "FB"):
        record["second_pass"] = "not used: " + ("; ".join(
            f"{w.view}: {w.reason}" for w in second.windows if w.reason) or "a view was not found")
        return pcs, index, fit, record
    old = run.offsets, run.grads
    run.offsets = {v: np.asarray(second.offsets_px[v], float) for v in "FB"}
    run.grads = {v: np.asarray(second.gradients_px[v], float) for v in "FB"}
    run.n_field, run.n_field_sigma_m = fit.field, field_plan_sigma(run, fit)
    run.pairs = True
    try:
        pcs2 = match_patches(run, patch_m, progress_range=(0.65, 0.8))
    except InputError as e:
        pcs2, why = None, str(e)
    finally:
        run.pairs = False
    if pcs2 is not None:
        cells2, index2 = join_cells(pcs2)
        checkpoint(run.progress, 0.8, "adjusting the shift field again")
        fit2 = adjust(run, cells2, len(index2), fit.theta, gcps)
        why = f"the adjustment after it failed ({fit2.reason})"
    prior = run.n_field, run.n_field_sigma_m
    run.n_field = None
    if pcs2 is None or not fit2:
        run.offsets, run.grads = old
        return pcs, index, fit, {**second.to_dict(), "first_pass": record, "second_pass": f"not used: {why}"}
    run.prior_field = prior
    return pcs2, index2, fit2, {**second.to_dict(), "first_pass": record}


def field_plan_sigma(run: OrientRun, fit) -> float:
    """The largest planimetric σ (m) of ``fit``'s field at a lattice over N (the a-priori σ
    where it is not finite)."""
    lx, ly = cond.lattice(run.shape)
    s = max(float(np.sqrt(np.linalg.eigvalsh(fit.cov_at(a, b)[:2, :2]).max())) for a, b in zip(lx, ly))
    return s if np.isfinite(s) else float(run.sigma_apriori_m)


def _patch_sigma(info: np.ndarray, limit: float) -> np.ndarray:
    """σ (m; E, N, h) a patch's cells alone give its shift, from their information ``info``
    (3, 3); NaN in a direction they fix worse than ``limit`` (a plane fixes its height only)."""
    w, v = np.linalg.eigh(info)
    weak = w <= max(w.max(), 1e-300) * 1e-9
    cov = (v[:, ~weak] / w[~weak]) @ v[:, ~weak].T
    s = np.sqrt(np.clip(np.diag(cov), 0, None))
    undetermined = (np.abs(v[:, weak]) > 0.1).any(1) if weak.any() else np.zeros(3, bool)
    return np.where((s <= limit) & ~undetermined, s, np.nan)


def offsets_along_sigma(run: OrientRun, record: dict) -> float:
    """σ (m) along track of every cell's N position from the view offsets' along-track error:
    a cell sits at ``pF − w·py·d``, so errors δF, δB of the offsets move all of them alike by
    ``(1 − w)·δF + w·δB`` along ``d`` — a shift the adjustment takes for N's own and cannot see.
    From the coarse step's windows (``record``, :meth:`CoarseOffsets.to_dict`):
    :func:`~prismstation.core.orientation.view_offsets.n_along_sigma_px`, where the reference heights'
    error, common to F and B in a window, cancels but for the windows they do not share."""
    rows, cols = run.shape
    N = run.scene.views["N"]
    en = prism.ancillary_to_ground(run.scene, N, np.array([[cols / 2, rows / 2]]), run.ref.mean_h)
    d = prism.along_track_unit(run.scene, en)[0]
    windows: dict = {"F": {}, "B": {}}
    for w in record.get("windows") or ():
        sx, sy = w.get("sigma_dx"), w.get("sigma_dy")
        if w.get("status") == "ok" and w.get("view") in windows and sx is not None and sy is not None:
            windows[w["view"]][tuple(w["n_window"])] = (float(sx), float(sy))
    par = {v: run.sigma_height_m * abs(run.scene.views[v].tan_theta) / N.pixel_size_m for v in "FB"}
    vf = {v: ((record.get("verdicts") or {}).get(v) or {}).get("variance_factor") for v in "FB"}
    s = n_along_sigma_px(windows, par, d, run.n_weight,
                         variance_factor={v: float(x) for v, x in vf.items() if x is not None})
    return s * N.pixel_size_m if np.isfinite(s) else 0.0   # (no offsets: nothing to add)


def make_result(run: OrientRun, pcs, index, fit, expected, record, target_m, gcps, pull=None) -> DemOrientation:
    """Step 6: the patches' record, the field's σ (with the prior's pull, :func:`prior_pull`, as
    a term common to the whole field), the verdict and the model."""
    offsets = {v: [float(c) for c in o] for v, o in run.offsets.items()}
    grads = {v: [[float(c) for c in row] for row in g] for v, g in run.grads.items()}
    where = {k: j for j, k in enumerate(index)}
    rejected = {index[j] for j in fit.rejected}
    patches = []
    for k, pc in enumerate(pcs):
        j = where.get(k)
        if j is None or not fit.used[j]:
            why = (pc.reason if j is None else
                   "a blunder: its shift departs from the other patches' field beyond its σ (χ² test)"
                   if k in rejected else "no cell left after the outlier test")
            s = np.full(3, np.nan) if j is None else fit.field(pc.x, pc.y) + np.nan_to_num(fit.shift[j])
            patches.append(PatchShift(pc.window, pc.x, pc.y, *s, *(np.nan,) * 3, pc.count, pc.valid_fraction,
                                      False, why, float(fit.T[j]) if j is not None else np.nan,
                                      int(fit.dof[j]) if j is not None else 0))
            continue
        s = fit.field(pc.x, pc.y) + fit.shift[j]
        sg = _patch_sigma(fit.info[j], 3 * run.sigma_apriori_m)
        patches.append(PatchShift(pc.window, pc.x, pc.y, *s, *sg, int(fit.cells[j]), pc.valid_fraction, True, "",
                                  float(fit.T[j]), int(fit.dof[j]), float(fit.spread[j]), float(fit.area[j])))
    used = sum(p.used for p in patches)
    if fit:
        lx, ly = cond.lattice(run.shape)
        along = run.along()
        covs = np.array([fit.cov_at(a, b) for a, b in zip(lx, ly)])
        if gcps is None or not len(gcps):      # GCPs observe the field through the same offsets
            covs[:, :2, :2] += offsets_along_sigma(run, record) ** 2 * np.outer(along, along)
        unchecked_note = unchecked.add_to_covariances(covs, fit.basis, pull, lx, ly, along)
        summary = cond.summarise(covs, along)
        verdict = cond.judge(summary, target_m, used, run.sigma_apriori_m, unchecked=unchecked_note)
    else:
        summary = cond.SigmaSummary(*(np.nan,) * 7)
        verdict = cond.OrientVerdict(cond.FAILED, f"NOT TRUSTED: {fit.reason}",
                                     "check the reference DEM covers the scene; a larger a-priori σ", target_m, None)
    source = "reference DEM" + (" and GCPs" if gcps is not None and len(gcps) else "")
    control = control_from_field(run.scene, fit.field, run.ref.mean_h, offsets, offset_gradients=grads,
                                 source=source)
    return DemOrientation(
        str(run.reference_path), tuple(patches), run.ref.mean_h, offsets, record, verdict,
        float(run.sigma_apriori_m), control, summary.to_dict(), grads,
        {"theta": fit.theta.tolist(), "centre": list(fit.basis.centre), "scale": fit.basis.scale,
         "terms": list(fit.basis.terms), "cov": np.where(np.isfinite(fit.cov), fit.cov, 0.0).tolist(),
         "offset": fit.offset.tolist(), "source": source},
        expected.to_dict(),
        {"sigma_b_m": fit.sigma_b.tolist(), "iterations": fit.iterations, "cells": int(np.sum(fit.cells)),
         "height_distortion": {"degrees": list(run.distortion().degrees), "terms_m": fit.delta.tolist(),
                               "sigma_m": np.sqrt(np.clip(np.diag(fit.cov)[12:], 0, None)).tolist(),
                               "a_priori_sigma_m": run.distortion_sigma_m},
         "rejected": [index[j] for j in fit.rejected], "gcp_observations": 0 if gcps is None else len(gcps),
         "reason": fit.reason, "prior_pull": (pull or {}).get("prior"), "pair_dems": (pull or {}).get("pairs"),
         "start": (pull or {}).get("start")})
