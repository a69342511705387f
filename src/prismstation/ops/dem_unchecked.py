"""What the DEM orientation's patches cannot check, measured per run and added to the field's σ.

Both terms are common to the whole field: every patch errs alike, so neither the patches'
scatter, their random shifts ``Σ_b`` nor the jackknife sees them (docs/orientation_engine.md,
step 6). Each is the field's change when the run's data are moved by one draw of the error:

* :func:`prior_pull` — the dense matcher's pull toward its prior (the prior moved);
* :func:`pair_term` — the relative DEMs' own height errors (the pair DEMs' disagreement);
* :func:`start_term` — where the adjustment was started (it may stay near wherever it starts).

:func:`add_to_covariances` adds them to the field's covariances at a lattice and says what was
added in the verdict's words.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from prismstation.core.orientation import conditioning as cond
from prismstation.errors import InputError
from prismstation.ops.dem_patches import join_cells, match_patches


#: how far the pull's measurement moves the dense prior (matched px): half the matcher's
#: candidate step, the most a pull that is periodic in the prior's error can change
PULL_OFFSET_PX = 0.5


def prior_pull(run, patch_m: float, fit, refit) -> dict:
    """How far the field follows the dense matcher's prior, measured: every patch matched again
    as the last pass matched it but with its prior moved by :data:`PULL_OFFSET_PX` matched
    pixels of parallax, the field adjusted again from ``fit`` (``refit(cells, n_patches)``).
    The matcher's sub-pixel value is drawn toward its whole-pixel candidates around the prior
    (most on sharp, point-sampled texture), and the prior is the reference laid where the
    ancillary model, or the first field,
    puts N: every patch is drawn alike, so their scatter and ``Σ_b`` never see it. The prior's
    a-priori error (the reference heights' σ over ``c1``, several pixels) exceeds the pull's
    period of one candidate, so the change is the pull's σ: ``{"offset_px", "theta_change"
    (9,) m, "reason"}`` (``theta_change`` None and ``reason`` why when it could not be measured)."""
    saved = run.n_field, run.n_field_sigma_m
    run.n_field, run.n_field_sigma_m = run.prior_field
    run.prior_offset_px = PULL_OFFSET_PX
    out = {"offset_px": PULL_OFFSET_PX, "theta_change": None, "reason": ""}
    try:
        pcs = match_patches(run, patch_m, progress_range=(0.8, 0.98))
        cells, index = join_cells(pcs)
        moved = refit(cells, len(index))
        if moved:
            out["theta_change"] = (moved.theta - fit.theta).tolist()
        else:
            out["reason"] = f"the adjustment with the prior moved failed ({moved.reason})"
    except InputError as e:
        out["reason"] = f"the patches with the prior moved did not match ({e})"
    finally:
        run.prior_offset_px = 0.0
        run.n_field, run.n_field_sigma_m = saved
    return out


def pair_term(pcs, index, fit, refit) -> dict:
    """The relative DEMs' own height errors at the scales the cells see (hundreds of metres),
    propagated into the field: the cells' heights moved by one draw of that error (the pair
    DEMs' disagreement, ``dh_pairs`` of :func:`prismstation.ops.dem_patches.match_patch`), the
    field adjusted again from ``fit`` (``refit(cells, n_patches)``). Correlated over the
    reference's cells and more, within a patch of nearly one slope it is a shift of the patch
    that its scatter about its own shift does not see. ``{"theta_change" (9,) m or None,
    "rms_m" (the draw's RMS), "reason"}``."""
    out = {"theta_change": None, "rms_m": None, "reason": ""}
    if not all("dh_pairs" in pcs[k].cells for k in index):
        out["reason"] = "the pair DEMs were not matched (the second pass was not used)"
        return out
    cells, _ = join_cells(pcs)
    dh = np.concatenate([pcs[k].cells["dh_pairs"] for k in index])
    out["rms_m"] = float(np.sqrt(np.mean(dh ** 2)))
    moved = refit(replace(cells, h=cells.h + dh), len(index))
    if moved:
        out["theta_change"] = (moved.theta - fit.theta).tolist()
    else:
        out["reason"] = f"the adjustment with the heights moved failed ({moved.reason})"
    return out


def start_term(fit, refit_from, kick_m: float, start_sigma_m: float) -> dict:
    """How far the field stays where the adjustment was started, measured: the adjustment run
    again from ``fit``'s field moved by ``±kick_m`` east and north (``refit_from(theta0)``), the
    ends' difference over ``2·kick_m`` the field's response ``K`` to its start (a column per
    horizontal component). Where the reference's gradients are mostly its noise, the
    cost has a ripple of one grid cell (the noise sampled bilinearly) over a relief trend too
    weak to leave it, and Gauss–Newton stays in the basin it starts in: the field then follows
    its start — the whole mosaic's search, whose σ is the a-priori one — by ``K``, the same
    in every patch, so neither their scatter nor ``Σ_b`` sees it. The term is ``K`` times
    ``start_sigma_m`` per component: ``{"kick_m", "start_sigma_m", "theta_change" (9,) m per
    component (two rows, the E and N starts' response times ``start_sigma_m``), "k" (2, 2),
    "reason"}`` (``theta_change`` None and ``reason`` why when it could not be measured)."""
    out = {"kick_m": float(kick_m), "start_sigma_m": float(start_sigma_m), "theta_change": None, "k": None,
           "reason": ""}
    ends = []
    for j in (0, 3):                                  # the field's constant east, then north
        pair = []
        for sign in (1.0, -1.0):
            theta0 = np.array(fit.theta, float)
            theta0[j] += sign * kick_m
            moved = refit_from(theta0)
            if not moved:
                out["reason"] = f"the adjustment started {kick_m:.0f} m away failed ({moved.reason})"
                return out
            pair.append(moved.theta)
        ends.append((pair[0] - pair[1]) / (2.0 * kick_m))
    resp = np.array(ends)                             # (2, 9): per unit of the start's E, N
    out["k"] = resp[:, [0, 3]].T.tolist()             # rows: the field's E, N; columns: the start's
    out["theta_change"] = (resp * start_sigma_m).tolist()
    return out


def add_to_covariances(covs: np.ndarray, basis, terms: dict | None, lx, ly, along) -> str:
    """Add each measured term of ``terms`` (``{"prior": …, "pairs": …, "start": …}``, as
    :func:`prior_pull`, :func:`pair_term` and :func:`start_term` return them) to ``covs`` (n, 3,
    3) at the lattice ``lx, ly`` as the outer product of the field's change (summed over the
    rows of a (k, 9) change), store each one's summary as ``"sigma_m"``; return what the verdict
    says of them ("" when none was measured or tried)."""
    added, missing = [], []
    for key, what in (("prior", "the matcher's pull toward its prior"),
                      ("pairs", "the relative DEMs' own errors, as the pair DEMs disagree"),
                      ("start", "where the adjustment was started")):
        term = (terms or {}).get(key)
        if term is None:
            continue
        if term["theta_change"] is None:
            missing.append(f"{what} was not measured: {term['reason']}")
            continue
        outer = np.zeros_like(covs)
        for change in np.atleast_2d(np.asarray(term["theta_change"], float)):
            dv = basis.predict(change, lx, ly)                               # (n, 3)
            outer += dv[:, :, None] * dv[:, None, :]
        covs += outer
        if key == "start":
            k = np.asarray(term["k"])
            stay = float(np.abs(np.diag(k)).max())
            if stay >= 0.5:          # more than half the way: the start, not the terrain, placed it
                what += (f" (started {term['kick_m']:.0f} m away, the adjustment stayed {100 * stay:.0f} % of "
                         "the way there: the terrain does not fix the field, it follows its start, the whole "
                         f"mosaic's search over the a-priori {term['start_sigma_m']:.0f} m)")
        term["sigma_m"] = cond.summarise(outer, along).to_dict()
        added.append(f"{term['sigma_m']['plan']:.1f} m planimetric, {term['sigma_m']['h']:.1f} m in height "
                     f"for {what}")
    said = ["σ includes " + "; ".join(added) + ", which the patches cannot check"] if added else []
    return "; ".join(said + missing)
