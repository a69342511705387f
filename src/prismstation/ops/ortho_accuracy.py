"""The expected planimetric accuracy of an orthoimage: where a ground feature appears in it is
off by what the orientation leaves in the view's geolocation and by the DEM's height error
carried sideways along the view's rays.

``σ_expected = √(σ_orientation² + (σ_DEM · tan θ)²)``, metres, RMS radial (√(σ_E² + σ_N²)):

* ``σ_orientation`` — the fitted bias's parameter covariance at image points over the view
  (the sensor model's ``bias_cov``, px²) carried to the ground through the model's derivative
  ``∂(x, y)/∂(E, N)``, RMS over a 5 × 5 lattice of the image. Beside it, the fit's own check
  points in the view (their image residuals in metres): measurement noise included, the
  empirical figure a formal σ is held to;
* ``tan θ`` — how far a ground point's image moves sideways per metre of height:
  ``|(∂(x, y)/∂(E, N))⁻¹ · ∂(x, y)/∂h|`` at the image's centre, from the model itself (a PRISM
  F or B view ~0.5, a near-nadir view ~0.02; an RPC's from its own geometry);
* ``σ_DEM`` — the DEM's height σ: as given; else measured on the project (RMS of DEM − known
  height at its points with ground coordinates, at least three inside the DEM:
  :func:`prismstation.ops.predict.dem_sigma`); else the a-priori σ of an SRTM-class DEM
  (:data:`~prismstation.ops.predict.DEFAULT_DEM_SIGMA_M`). A constant height's σ is the
  spread of the known heights about it.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from prismstation.ops.predict import DEFAULT_DEM_SIGMA_M, dem_sigma

#: image points per side of the lattice the orientation's σ is averaged over
LATTICE = 5


@dataclass(frozen=True)
class OrthoAccuracy:
    """The expected planimetric accuracy of one view's ortho (module docstring); metres, RMS
    radial; None where it cannot be told (``notes`` say why)."""

    expected_sigma_m: float | None
    orientation_sigma_m: float | None
    off_nadir_tan: float
    dem_sigma_m: float | None
    dem_sigma_source: str
    check_rmse_m: float | None
    check_count: int
    notes: tuple = ()

    def as_dict(self) -> dict:
        d = asdict(self)
        d["notes"] = list(self.notes)
        return d


def expected_accuracy(sol, view: str, heights, ground: dict, *, dem_sigma_m: float | None = None,
                      window=None) -> OrthoAccuracy:
    """The :class:`OrthoAccuracy` of ``view``'s ortho on ``heights``
    (:class:`~prismstation.ops.ortho_tiles.Heights`). ``ground``: id → ``(E, N, h)`` of the
    project's known points (ellipsoidal); ``dem_sigma_m`` the DEM's σ if the operator knows it;
    ``window`` ``(col, row, w, h)`` the part of the image the ortho shows (default all of it)."""
    model = sol.model
    notes = []
    v = sol.scene.views[view]
    rows, cols = v.shape if v.shape else (1000, 1000)
    c0, r0, w, h = window if window is not None else (0, 0, cols, rows)
    u = (np.arange(LATTICE) + 0.5) / LATTICE
    xy = np.stack(np.meshgrid(c0 + w * u, r0 + h * u), axis=-1).reshape(-1, 2)
    hm = float(sol.mean_height)
    en = model.image_to_ground(view, xy, hm)
    ok = np.isfinite(en).all(axis=1)
    _, J = model.partials(view, en[ok], np.full(int(ok.sum()), hm))
    Jen = J[:, :, :2]
    # tan θ at the centre (the lattice's middle point)
    mid = len(J) // 2
    tan = float(np.hypot(*np.linalg.solve(Jen[mid], J[mid, :, 2]))) if len(J) else math.nan

    orientation = None
    if not model.fitted(view):
        notes.append(f"view {view}'s geolocation is not fitted (no bias): its accuracy is the product's own")
    else:
        C = model.bias_cov(view, xy[ok])
        if not np.any(C):
            notes.append(f"view {view} has no bias covariance (held fixed as the datum, or fitted without "
                         "redundancy): the orientation's σ is not known")
        else:
            Ji = np.linalg.inv(Jen)
            Cg = Ji @ C @ np.swapaxes(Ji, -1, -2)
            orientation = float(np.sqrt(np.mean(np.trace(Cg, axis1=-2, axis2=-1))))

    icp = sol.stats.image.get(view, {}).get("ICP")
    check_n = int(icp.m.n) if icp is not None else 0
    check = float(icp.m.planimetric_rms) if check_n else None

    if dem_sigma_m is not None:
        sigma_h, source = float(dem_sigma_m), "given"
    else:
        pts = np.array(list(ground.values()), float).reshape(-1, 3)
        hv = heights.at(pts[:, :2]) if len(pts) else np.zeros(0)
        inside = np.isfinite(hv)
        if inside.sum() >= 3:
            sigma_h = dem_sigma(lambda _: hv[inside], {k: g for (k, g), i in zip(ground.items(), inside) if i})
            source = f"measured: RMS of the heights − the known heights at {int(inside.sum())} points"
        elif heights.path is not None:
            sigma_h, source = DEFAULT_DEM_SIGMA_M, "a-priori (an SRTM-class DEM; fewer than 3 known points in it)"
        else:
            sigma_h, source = None, "not known (a constant height and fewer than 3 known points)"
    expected = None
    if orientation is not None and sigma_h is not None and math.isfinite(tan):
        expected = math.hypot(orientation, sigma_h * tan)
    return OrthoAccuracy(expected, orientation, tan, sigma_h, source, check, check_n, tuple(notes))
