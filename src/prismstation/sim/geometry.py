"""Rigorous pushbroom geometry of the simulator (numpy only: no rasterio, no cv2).

A flat map plane (E, N metres, ``up`` = height h, ellipsoidal metres) under a satellite on a
straight horizontal track at altitude ``Hs``. Unit vectors on the map: ``t`` = flight
direction, ``a`` = across track, 90° to the left of ``t`` (``a = (-cos ψ, sin ψ)`` for the
heading ψ clockwise from north); ``a`` is also the +x (column) axis of a path-oriented 1B2-R
product whose +y (row) axis is ``t``.

Body frame: ``x_b = a``, ``y_b = t``, ``z_b`` = down (right-handed). A raw pixel is a
continuous ``(line, col)``: the line fixes the time ``tau = view.tau0 + line · dt`` (s, 0 when
the nadir line sees the scene centre at h = 0), the column the detector whose nominal look
vector in the body frame is ``(tanβ0 + (col − col0)·ifov, tanθ, 1)``. The true look vector is
that one rotated by the view's attitude error ``R(τ) = Rz(yaw)·Rx(pitch)·Ry(roll)``.

The 1B2 product: a raw pixel projected with the NOMINAL orientation onto h = 0 gives the map
point ``G``; the product grid then maps ``G`` affinely to image ``(x, y)`` (docs/model.md §1).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

import numpy as np


@dataclass(frozen=True)
class Attitude:
    """Attitude error of one view: angles (rad) at τ = 0, drift rates (rad/s) and accelerations
    (rad/s²: attitude that is not linear in time, ``½·a·(τ − accel_time)²``, about the time
    ``accel_time`` (s) the view sees its scene's centre)."""

    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0
    roll_rate: float = 0.0
    pitch_rate: float = 0.0
    roll_accel: float = 0.0
    pitch_accel: float = 0.0
    accel_time: float = 0.0

    def angles(self, tau):
        """``(roll, pitch, yaw)`` at time(s) ``tau`` (s)."""
        tau = np.asarray(tau, dtype=float)
        q = 0.5 * (tau - self.accel_time) ** 2
        return (self.roll + self.roll_rate * tau + self.roll_accel * q,
                self.pitch + self.pitch_rate * tau + self.pitch_accel * q, self.yaw)


@dataclass(frozen=True)
class Orbit:
    """Platform and sensor constants shared by the three views.

    ``track_origin`` is the sub-satellite point (E, N) at τ = 0; ``heading`` radians clockwise
    from north; ``altitude`` Hs and ``speed`` v in m and m/s; ``pixel`` the nominal GSD (m).
    """

    track_origin: tuple[float, float]
    heading: float
    altitude: float = 691650.0
    speed: float = 6800.0
    pixel: float = 2.5
    tan_beta0: float = 0.0
    col0: float = 0.0

    @property
    def t(self) -> np.ndarray:
        return np.array([np.sin(self.heading), np.cos(self.heading)])

    @property
    def a(self) -> np.ndarray:
        return np.array([-np.cos(self.heading), np.sin(self.heading)])

    @property
    def line_period(self) -> float:
        return self.pixel / self.speed

    @property
    def ifov(self) -> float:
        return self.pixel / self.altitude

    def sub_satellite(self, tau) -> np.ndarray:
        """Sub-satellite point(s) ``(..., 2)`` at time(s) ``tau``."""
        tau = np.asarray(tau, dtype=float)[..., None]
        return np.asarray(self.track_origin) + self.speed * tau * self.t


@dataclass(frozen=True)
class View:
    """One line sensor: signed along-track look angle ``theta`` (rad, + ahead), the time of
    raw line 0 ``tau0`` (s), its true ``attitude`` error, and the product's ``map_to_image``
    ``(A1..A6)``: ``x = A1·E + A2·N + A5``, ``y = A3·E + A4·N + A6``."""

    name: str
    theta: float
    tau0: float
    attitude: Attitude
    map_to_image: tuple[float, float, float, float, float, float]

    def with_attitude(self, attitude: Attitude) -> "View":
        return replace(self, attitude=attitude)


# ------------------------------------------------------------------ rotations
def _rotate(x, y, z, roll, pitch, yaw, inverse=False):
    """Apply ``Rz(yaw)·Rx(pitch)·Ry(roll)`` (or its transpose) to body vectors."""
    cr, sr, cp, sp, cy, sy = (np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch),
                              np.cos(yaw), np.sin(yaw))
    if not inverse:
        x, z = x * cr + z * sr, -x * sr + z * cr            # roll about the along axis
        y, z = y * cp + z * sp, -y * sp + z * cp            # pitch about the across axis
        x, y = x * cy - y * sy, x * sy + y * cy             # yaw about the vertical
    else:
        x, y = x * cy + y * sy, -x * sy + y * cy
        y, z = y * cp - z * sp, y * sp + z * cp
        x, z = x * cr - z * sr, x * sr + z * cr
    return x, y, z


# ------------------------------------------------------------------ nominal product geometry
def raw_time(orbit: Orbit, view: View, line) -> np.ndarray:
    return view.tau0 + np.asarray(line, dtype=float) * orbit.line_period


def raw_line(orbit: Orbit, view: View, tau) -> np.ndarray:
    return (np.asarray(tau, dtype=float) - view.tau0) / orbit.line_period


def nominal_ground(orbit: Orbit, view: View, line, col, h=0.0) -> np.ndarray:
    """Map point ``(..., 2)`` where the NOMINAL ray of raw ``(line, col)`` meets height ``h``."""
    tau = raw_time(orbit, view, line)
    tan_x = orbit.tan_beta0 + (np.asarray(col, dtype=float) - orbit.col0) * orbit.ifov
    lam = (orbit.altitude - np.asarray(h, dtype=float))[..., None]
    return (orbit.sub_satellite(tau)
            + lam * (tan_x[..., None] * orbit.a + np.tan(view.theta) * orbit.t))


def nominal_raw(orbit: Orbit, view: View, en) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`nominal_ground` at h = 0: map ``(..., 2)`` → raw ``(line, col)``."""
    d = np.asarray(en, dtype=float) - np.asarray(orbit.track_origin)
    along = d @ orbit.t
    across = d @ orbit.a
    tau = (along - orbit.altitude * np.tan(view.theta)) / orbit.speed
    col = (across / orbit.altitude - orbit.tan_beta0) / orbit.ifov + orbit.col0
    return raw_line(orbit, view, tau), col


def map_to_image(view: View, en) -> np.ndarray:
    """Product affine: map ``(..., 2)`` → image ``(..., 2)`` (x = column, y = row)."""
    a1, a2, a3, a4, a5, a6 = view.map_to_image
    en = np.asarray(en, dtype=float)
    return np.stack([a1 * en[..., 0] + a2 * en[..., 1] + a5,
                     a3 * en[..., 0] + a4 * en[..., 1] + a6], axis=-1)


def image_to_map(view: View, xy) -> np.ndarray:
    """Inverse of :func:`map_to_image`."""
    a1, a2, a3, a4, a5, a6 = view.map_to_image
    det = a1 * a4 - a2 * a3
    xy = np.asarray(xy, dtype=float)
    x, y = xy[..., 0] - a5, xy[..., 1] - a6
    return np.stack([(a4 * x - a2 * y) / det, (-a3 * x + a1 * y) / det], axis=-1)


# ------------------------------------------------------------------ true rays
def true_ray(orbit: Orbit, view: View, line, col):
    """Origin ``(..., 3)`` and direction ``(..., 3)`` (E, N, up; ``dir_up = −1``) of the TRUE
    line of sight of raw ``(line, col)``."""
    tau = raw_time(orbit, view, line)
    col = np.asarray(col, dtype=float)
    tau, col = np.broadcast_arrays(tau, col)
    bx = orbit.tan_beta0 + (col - orbit.col0) * orbit.ifov
    by = np.full_like(bx, np.tan(view.theta))
    bx, by, bz = _rotate(bx, by, np.ones_like(bx), *view.attitude.angles(tau))
    a, t = orbit.a, orbit.t
    dxy = (bx / bz)[..., None] * a + (by / bz)[..., None] * t
    direction = np.concatenate([dxy, -np.ones_like(bx)[..., None]], axis=-1)
    origin = np.concatenate([orbit.sub_satellite(tau), np.full_like(bx, orbit.altitude)[..., None]],
                            axis=-1)
    return origin, direction


def ray_at_height(origin, direction, h) -> np.ndarray:
    """Map point ``(..., 2)`` of a ray (``direction[..., 2] = −1``) at height ``h``."""
    lam = (origin[..., 2] - np.asarray(h, dtype=float))[..., None]
    return origin[..., :2] + lam * direction[..., :2]


def true_raw(orbit: Orbit, view: View, enh, tol: float = 1e-12, max_iter: int = 30):
    """Raw ``(line, col)`` whose TRUE ray passes through the 3-D points ``enh`` ``(..., 3)``.

    Newton on the time τ (the along-track focal-plane condition ``q_y / q_z = tanθ``), then
    the column from the across-track component. Converges to ~1e-12 s (1e-9 line).
    """
    enh = np.asarray(enh, dtype=float)
    p, h = enh[..., :2], enh[..., 2]
    rel0 = p - np.asarray(orbit.track_origin)
    along0, across = rel0 @ orbit.t, rel0 @ orbit.a
    down = orbit.altitude - h
    tan_t = np.tan(view.theta)

    def sensor(tau):
        qx, qy, qz = _rotate(across, along0 - orbit.speed * tau, down,
                             *view.attitude.angles(tau), inverse=True)
        return qx, qy, qz

    def f(tau):
        _, qy, qz = sensor(tau)
        return qy / qz - tan_t

    tau = (along0 - down * tan_t) / orbit.speed
    step = 1e-3
    for _ in range(max_iter):
        fv = f(tau)
        deriv = (f(tau + step) - f(tau - step)) / (2 * step)
        dtau = fv / deriv
        tau = tau - dtau
        if np.all(np.abs(dtau) < tol):
            break
    qx, _, qz = sensor(tau)
    col = (qx / qz - orbit.tan_beta0) / orbit.ifov + orbit.col0
    return raw_line(orbit, view, tau), col


def image_coords(orbit: Orbit, view: View, enh) -> np.ndarray:
    """Product image ``(..., 2)`` (x, y pixels) of 3-D points ``enh`` ``(..., 3)`` (E, N, h)."""
    line, col = true_raw(orbit, view, enh)
    return map_to_image(view, nominal_ground(orbit, view, line, col, 0.0))


def pixel_rays(orbit: Orbit, view: View, xy):
    """TRUE rays ``(origin, direction)`` seen by product pixels ``xy`` ``(..., 2)``: image →
    map at h = 0 → nominal raw (line, col) → true line of sight."""
    line, col = nominal_raw(orbit, view, image_to_map(view, xy))
    return true_ray(orbit, view, line, col)


# ------------------------------------------------------------------ terrain intersection
def intersect_terrain(origin, direction, sample: Callable, h_min: float, h_max: float,
                      tol: float = 1e-3, max_iter: int = 60) -> np.ndarray:
    """First-found intersection ``(..., 3)`` of rays with the terrain ``h = sample(E, N)``.

    Safeguarded root finding on ``g(h) = sample(ray(h)) − h`` inside the bracket
    ``[h_min − 1, h_max + 1]`` (``g > 0`` below, ``< 0`` above the surface): secant steps
    (the first a fixed-point step), bisection whenever a step leaves the bracket, so steep
    slopes where the fixed point diverges still converge. Only unconverged rays iterate.
    """
    shape = origin.shape[:-1]
    o = origin.reshape(-1, 3)
    d = direction.reshape(-1, 3)
    n = o.shape[0]
    # horizontal position at height h: base + (top − h)·slope_xy (direction has d_z = −1)
    ox, oy, top = o[:, 0].copy(), o[:, 1].copy(), o[:, 2].copy()
    dx, dy = d[:, 0] / -d[:, 2], d[:, 1] / -d[:, 2]
    lo = np.full(n, h_min - 1.0)
    hi = np.full(n, h_max + 1.0)
    h = np.full(n, 0.5 * (h_min + h_max))
    h_prev = np.full(n, np.nan)
    g_prev = np.full(n, np.nan)
    out = np.empty(n)
    idx = np.arange(n)
    for _ in range(max_iter):
        lam = top - h
        g = sample(ox + lam * dx, oy + lam * dy) - h
        done = np.abs(g) < tol
        out[idx[done]] = h[done]
        keep = ~done
        if not keep.any():
            idx = idx[:0]
            break
        if done.any():
            idx, h, g, lo, hi, h_prev, g_prev, ox, oy, top, dx, dy = (
                v[keep] for v in (idx, h, g, lo, hi, h_prev, g_prev, ox, oy, top, dx, dy))
        lo = np.where(g > 0, h, lo)
        hi = np.where(g <= 0, h, hi)
        with np.errstate(divide="ignore", invalid="ignore"):
            cand = h - g * (h - h_prev) / (g - g_prev)
        cand = np.where(np.isfinite(cand), cand, h + g)
        bad = ~((cand > lo) & (cand < hi))
        cand = np.where(bad, 0.5 * (lo + hi), cand)
        h_prev, g_prev, h = h, g, cand
    if idx.size:  # bracket collapsed below tol without |g| < tol (discontinuous sampler)
        out[idx] = h
    en = ray_at_height(o, d, out)
    return np.concatenate([en, out[:, None]], axis=-1).reshape(*shape, 3)


def across_offset_px(orbit: Orbit, view: View, ref: View, enh) -> np.ndarray:
    """Across-track offset (pixels, along ``a``) of the apparent h = 0 positions of points
    ``enh`` in ``view`` minus ``ref`` (the paper's Table 2 ``Δx``)."""
    g1 = nominal_ground(orbit, view, *true_raw(orbit, view, enh))
    g0 = nominal_ground(orbit, ref, *true_raw(orbit, ref, enh))
    return (g1 - g0) @ orbit.a / orbit.pixel
