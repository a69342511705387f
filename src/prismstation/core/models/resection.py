"""Space resection of a frame image by collinearity, and the B/H ratio (docs/model.md §4; Subaryono et al., AVNIR).

Conventions
-----------
- Image points ``(x, y)`` in pixels: column, row, origin at the top-left corner of the top-left
  pixel (docs/model.md §1). They become photo coordinates in metres relative to the principal point
  ``(cx, cy)`` (pixels) with the photo y axis pointing up:
  ``xp = (x − cx)·pitch``, ``yp = −(y − cy)·pitch``.
- Ground points ``(X, Y, Z)`` in metres of a right-handed local or projected system, Z up.
- Exterior orientation ``(X0, Y0, Z0, ω, φ, κ)``: projection centre (metres) and the angles
  (radians) of the rotation ``M = R_κ·R_φ·R_ω`` (Wolf, *Elements of Photogrammetry*), with
  collinearity ``xp = −f·(m1·d)/(m3·d)``, ``yp = −f·(m2·d)/(m3·d)``, ``d = (X − X0, Y − Y0, Z − Z0)``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prismstation.core.adjustment.estimate import Normaliser, check_points, check_spread, condition_number, degenerate
from prismstation.core.models.rectify import fit_transform
from prismstation.errors import ModelError

PUSHBROOM_NOTE = ("The frame-camera (central projection) model is only an approximation for a "
                  "pushbroom image: its exterior orientation changes along the lines, so the "
                  "recovered position and angles are effective values for the whole scene.")
PARAM_NAMES = ("X0", "Y0", "Z0", "omega", "phi", "kappa")


def rotation_matrix(omega: float, phi: float, kappa: float) -> np.ndarray:
    """(3, 3) rotation ``M = R_κ·R_φ·R_ω`` (angles in radians), ground → photo axes."""
    so, co = np.sin(omega), np.cos(omega)
    sp, cp = np.sin(phi), np.cos(phi)
    sk, ck = np.sin(kappa), np.cos(kappa)
    return np.array([
        [cp * ck, so * sp * ck + co * sk, -co * sp * ck + so * sk],
        [-cp * sk, -so * sp * sk + co * ck, co * sp * sk + so * ck],
        [sp, -so * cp, co * cp],
    ])


@dataclass(frozen=True)
class FrameCamera:
    """Interior orientation: focal length (m), pixel pitch (m), principal point (pixels)."""

    focal_m: float
    pixel_m: float
    cx: float
    cy: float

    def to_photo(self, xy) -> np.ndarray:
        """(n, 2) pixels → (n, 2) photo coordinates in metres (y up)."""
        xy = np.asarray(xy, float)
        return np.column_stack([(xy[:, 0] - self.cx) * self.pixel_m,
                                -(xy[:, 1] - self.cy) * self.pixel_m])

    def to_pixels(self, p) -> np.ndarray:
        """(n, 2) photo coordinates (m, y up) → (n, 2) pixels."""
        p = np.asarray(p, float)
        return np.column_stack([p[:, 0] / self.pixel_m + self.cx, -p[:, 1] / self.pixel_m + self.cy])


def project(camera: FrameCamera, eo, xyz) -> np.ndarray:
    """Project (n, 3) ground points through exterior orientation ``eo`` (6,) to (n, 2) pixels."""
    eo = np.asarray(eo, float)
    d = np.asarray(xyz, float) - eo[:3]
    r = d @ rotation_matrix(*eo[3:]).T
    f = camera.focal_m
    return camera.to_pixels(np.column_stack([-f * r[:, 0] / r[:, 2], -f * r[:, 1] / r[:, 2]]))


@dataclass(frozen=True, eq=False)
class ResectionResult:
    """Exterior orientation from a space resection.

    Attributes
    ----------
    params : (6,) ``X0, Y0, Z0`` (m), ``ω, φ, κ`` (rad).
    sigma : (6,) standard deviations from ``σ0²·(JᵀJ)⁻¹`` (NaN without redundancy).
    cov : (6, 6) covariance of ``params``.
    sigma0_px : a-posteriori σ of one image coordinate (pixels).
    residuals_px : (n, 2) observed − computed image coordinates (pixels).
    start : (6,) the starting values.
    corrections : (k, 6) the Gauss–Newton correction applied at each iteration (Subaryono et al.'s
        Figures 4.1–4.2 plot these).
    history : (k + 1, 6) parameters after each iteration, starting values first.
    converged : whether corrections fell below the tolerance within the iterations allowed;
        the result is falsy when not, and ``reason`` says so (:mod:`prismstation.core.adjustment.estimate`).
    note : the pushbroom caveat, to show with the result.
    """

    params: np.ndarray
    sigma: np.ndarray
    cov: np.ndarray
    sigma0_px: float
    residuals_px: np.ndarray
    start: np.ndarray
    corrections: np.ndarray
    history: np.ndarray
    converged: bool
    camera: FrameCamera
    note: str = PUSHBROOM_NOTE

    def __bool__(self) -> bool:
        return bool(self.converged)

    @property
    def reason(self) -> str:
        return "" if self.converged else (f"did not converge in {len(self.corrections)} iterations "
                                          f"(σ0 {self.sigma0_px:.3g} px)")

    @property
    def position(self) -> np.ndarray:
        """(3,) projection centre ``X0, Y0, Z0`` (metres)."""
        return self.params[:3]

    def as_dict(self) -> dict:
        """JSON-ready summary (angles also in degrees)."""
        p, s = self.params, self.sigma
        eo = {k: float(v) for k, v in zip(PARAM_NAMES, p)}
        sd = {k: float(v) for k, v in zip(PARAM_NAMES, s)}
        for k, i in (("omega", 3), ("phi", 4), ("kappa", 5)):
            eo[k + "_deg"], sd[k + "_deg"] = float(np.degrees(p[i])), float(np.degrees(s[i]))
        return {
            "eo": eo, "sigma": sd, "sigma0_px": self.sigma0_px,
            "rmse_px": float(np.sqrt(np.mean((self.residuals_px ** 2).sum(axis=1)))),
            "converged": self.converged, "iterations": int(len(self.corrections)),
            "start": dict(zip(PARAM_NAMES, map(float, self.start))),
            "history": [dict(zip(PARAM_NAMES, map(float, h))) for h in self.history],
            "corrections": [dict(zip(PARAM_NAMES, map(float, c))) for c in self.corrections],
            "residuals_px": self.residuals_px.tolist(),
            "camera": {"focal_m": self.camera.focal_m, "pixel_m": self.camera.pixel_m,
                       "cx": self.camera.cx, "cy": self.camera.cy},
            "note": self.note,
        }


def vertical_start(camera: FrameCamera, xy, xyz) -> np.ndarray:
    """Starting EO: a vertical camera (ω = φ = 0) above the points, with scale, κ and the
    plan position from a 2-D similarity between photo and ground coordinates."""
    p = camera.to_photo(xy)
    xyz = np.asarray(xyz, float)
    zp = p[:, 0] + 1j * p[:, 1]
    zg = xyz[:, 0] + 1j * xyz[:, 1]
    zp_c, zg_c = zp - zp.mean(), zg - zg.mean()
    c = np.vdot(zp_c, zg_c) / np.vdot(zp_c, zp_c).real     # zg ≈ c·zp + t
    t = zg.mean() - c * zp.mean()
    scale = abs(c)
    return np.array([t.real, t.imag, xyz[:, 2].mean() + scale * camera.focal_m, 0.0, 0.0,
                     float(np.angle(c))])


def angles_of(M: np.ndarray) -> tuple[float, float, float]:
    """``(ω, φ, κ)`` (radians) of a rotation ``M = R_κ·R_φ·R_ω`` (inverse of :func:`rotation_matrix`)."""
    phi = float(np.arcsin(np.clip(M[2, 0], -1.0, 1.0)))
    return float(np.arctan2(-M[2, 1], M[2, 2])), phi, float(np.arctan2(-M[1, 0], M[0, 0]))


def homography_start(camera: FrameCamera, xy, xyz) -> np.ndarray:
    """Starting EO from the plane-to-image homography (ground points taken on their mean
    height): ``H ∝ [m1 m2 t]`` with ``m1``, ``m2`` the first two columns of ``M``. Handles
    tilted views where a vertical start fails; needs ≥ 4 points, not three on a line."""

    xyz = np.asarray(xyz, float)
    q = camera.to_photo(xy) / -camera.focal_m                 # (r1/r3, r2/r3)
    a = fit_transform("projective", xyz[:, :2], q).params
    H = np.array([[a[0], a[1], a[2]], [a[3], a[4], a[5]], [a[6], a[7], 1.0]])
    lam = 2.0 / (np.linalg.norm(H[:, 0]) + np.linalg.norm(H[:, 1]))
    r3 = lam * (H[2] @ np.column_stack([xyz[:, :2], np.ones(len(xyz))]).T)
    if np.median(r3) > 0:                                     # points must lie in front: r3 < 0
        lam = -lam
    m1, m2, t = lam * H[:, 0], lam * H[:, 1], lam * H[:, 2]
    U, _, Vt = np.linalg.svd(np.column_stack([m1, m2, np.cross(m1, m2)]))
    M = U @ Vt
    zm = xyz[:, 2].mean()
    centre = np.array([0.0, 0.0, zm]) - M.T @ t
    return np.array([*centre, *angles_of(M)])


def _jacobian(camera, eo, xyz, f0):
    dist = max(1.0, float(np.linalg.norm(eo[:3] - xyz.mean(axis=0))))
    J = np.empty((f0.size, 6))
    for k in range(6):
        h = 1e-6 * dist if k < 3 else 1e-7
        d = np.zeros(6)
        d[k] = h
        J[:, k] = (project(camera, eo + d, xyz).ravel() - project(camera, eo - d, xyz).ravel()) / (2 * h)
    return J


def _cost(camera, eo, xy, xyz) -> float:
    with np.errstate(all="ignore"):
        c = float(np.sum((project(camera, eo, xyz) - xy) ** 2))
    return c if np.isfinite(c) else np.inf


def resect(camera: FrameCamera, xy, xyz, start=None, *, max_iterations: int = 20,
           tol_m: float = 1e-4, tol_rad: float = 1e-9) -> ResectionResult:
    """Space resection by Gauss–Newton on the collinearity equations.

    Parameters
    ----------
    camera : interior orientation.
    xy : (n, 2) measured image points in pixels (n ≥ 3; ≥ 4 for standard deviations).
    xyz : (n, 3) ground points in metres, spread in plan (else
        :class:`~prismstation.errors.DegenerateGeometry`, as for too few points).
    start : (6,) starting EO; default :func:`homography_start` (≥ 4 points), falling back
        to :func:`vertical_start`. A step that raises the residuals is halved (up to 10 times).
    max_iterations, tol_m, tol_rad : stop after this many iterations or when every
        position correction is below ``tol_m`` and every angle correction below ``tol_rad``.
    """
    xy = np.asarray(xy, float)
    xyz = np.asarray(xyz, float)
    if xy.ndim != 2 or xy.shape[1] != 2 or xyz.ndim != 2 or xyz.shape[1] != 3 or len(xy) != len(xyz):
        raise ModelError("resection needs (n, 2) image points and (n, 3) ground points, same n")
    n = len(xy)
    check_points(n, 3, "resection")
    if not (np.all(np.isfinite(xy)) and np.all(np.isfinite(xyz))):
        raise ModelError("resection: non-finite coordinates")
    check_spread(Normaliser.of(xyz[:, :2]).fwd(xyz[:, :2]), "resection", "ground points")
    if start is not None:
        eo = np.asarray(start, float).copy()
    else:
        eo = vertical_start(camera, xy, xyz)
        if n >= 4:
            try:
                h = homography_start(camera, xy, xyz)
                if _cost(camera, h, xy, xyz) < _cost(camera, eo, xy, xyz):
                    eo = h
            except ModelError:
                pass
    start_eo = eo.copy()
    hist, corr = [eo.copy()], []
    converged = False
    obs = xy.ravel()
    for _ in range(max_iterations):
        f0 = project(camera, eo, xyz).ravel()
        J = _jacobian(camera, eo, xyz, f0)
        if not np.all(np.isfinite(J)):
            raise ModelError("resection diverged (a ground point lies in the camera plane)")
        D = 1.0 / np.linalg.norm(J, axis=0)        # column scaling: metres vs radians
        U, s, Vt = np.linalg.svd(J * D, full_matrices=False)
        if s[-1] <= 1e-12 * s[0]:
            k = condition_number(J * D)
            raise degenerate(f"resection: the points do not determine the orientation "
                             f"(condition number {k:.3g})", k)
        dx = D * (Vt.T @ ((U.T @ (obs - f0)) / s))
        c0 = float(np.sum((obs - f0) ** 2))
        for _ in range(10):                  # step halving keeps Gauss–Newton from diverging
            if _cost(camera, eo + dx, xy, xyz) <= c0 * (1 + 1e-12) + 1e-18:
                break
            dx = dx / 2
        eo = eo + dx
        corr.append(dx)
        hist.append(eo.copy())
        if np.all(np.abs(dx[:3]) < tol_m) and np.all(np.abs(dx[3:]) < tol_rad):
            converged = True
            break
    f0 = project(camera, eo, xyz).ravel()
    v = obs - f0
    dof = 2 * n - 6
    J = _jacobian(camera, eo, xyz, f0)
    D = 1.0 / np.linalg.norm(J, axis=0)
    _, s, Vt = np.linalg.svd(J * D, full_matrices=False)
    Ninv = D[:, None] * ((Vt.T / s ** 2) @ Vt) * D[None, :]
    if dof > 0:
        s0 = float(np.sqrt(v @ v / dof))
        cov = Ninv * s0 ** 2
    else:
        s0, cov = float("nan"), np.full((6, 6), np.nan)
    eo[3:] = (eo[3:] + np.pi) % (2 * np.pi) - np.pi
    return ResectionResult(eo, np.sqrt(np.diag(cov)), cov, s0, v.reshape(-1, 2), start_eo,
                           np.array(corr).reshape(-1, 6), np.array(hist), converged, camera)


@dataclass(frozen=True)
class BaseHeight:
    """Stereo base ``B = |XR − XL|`` (3-D, m), height ``H = (ZL + ZR)/2`` (m) and ``B/H``."""

    base_m: float
    height_m: float
    b_over_h: float


def base_height(left_xyz, right_xyz) -> BaseHeight:
    """B, H and B/H of two sensor positions ``(X, Y, Z)`` in metres (Subaryono et al., §2.2)."""
    left = np.asarray(left_xyz, float).reshape(3)
    right = np.asarray(right_xyz, float).reshape(3)
    if not (np.all(np.isfinite(left)) and np.all(np.isfinite(right))):
        raise ModelError("B/H needs finite sensor positions")
    b = float(np.linalg.norm(right - left))
    h = float((left[2] + right[2]) / 2.0)
    if h == 0:
        raise ModelError("B/H undefined: the mean sensor height is zero")
    return BaseHeight(b, h, b / h)
