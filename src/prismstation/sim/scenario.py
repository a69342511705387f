"""The simulated acquisition: orbit, the three views, their attitude errors and product grids.

Numbers follow seed 000 (Gonçalves): PRISM at Hs = 691 650 m, 2.5 m pixels, along-track
angles 26.4° (F) and 26.8° (B), a scene in Portugal (UTM 29N around E 540 km, N 4560 km),
F shifted ~4 px across track relative to N (Table 2), bias shifts of tens of metres.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from prismstation.sim import geometry as geo

CRS = "EPSG:32629"
CENTRE = (540000.0, 4560000.0)
ALTITUDE = 691650.0
SPEED = 6800.0
PIXEL = 2.5
GEOID = 55.0
TRACK_DISTANCE = 12000.0  # scene centre to ground track (m), left of the flight direction
ANGLES_DEG = {"N": 0.0, "F": 26.4, "B": 26.8}
SIGNS = {"N": 0.0, "F": 1.0, "B": -1.0}
HEADING_DEG = {"descending": 192.0, "ascending": 348.0}
#: target across-track offsets (px) of F and B relative to N at the scene centre (Table 2)
ACROSS_TARGET_PX = {"F": -4.0, "B": 0.3}


@dataclass(frozen=True)
class Scenario:
    """Everything geometric about one simulated triplet."""

    orbit: geo.Orbit
    views: dict[str, geo.View]
    size: int
    north_up: bool
    pass_direction: str
    platform: geo.Attitude
    alignment: dict[str, dict[str, float]] = field(default_factory=dict)
    grid_shift_px: dict[str, tuple[float, float]] = field(default_factory=dict)

    def theta(self, name: str) -> float:
        return self.views[name].theta


def product_affine(orbit: geo.Orbit, size: int, north_up: bool, shift=(0.0, 0.0)):
    """``map_to_image`` (A1..A6) of a ``size``² product of 2.5 m pixels centred on CENTRE:
    rows along the flight direction (1B2-R) or north-up (1B2-G); ``shift`` (px) moves the
    image content by (dx, dy)."""
    p = orbit.pixel
    c = np.asarray(CENTRE)
    if north_up:
        oe, on = c[0] - size / 2 * p, c[1] + size / 2 * p
        coeffs = [1 / p, 0.0, 0.0, -1 / p, -oe / p, on / p]
    else:
        a, t = orbit.a, orbit.t
        o = c - size / 2 * p * (a + t)
        coeffs = [a[0] / p, a[1] / p, t[0] / p, t[1] / p, -(o @ a) / p, -(o @ t) / p]
    coeffs[4] += shift[0]
    coeffs[5] += shift[1]
    return tuple(float(v) for v in coeffs)


def image_to_map_transform(map_to_image) -> tuple[float, ...]:
    """GDAL geotransform ``(c, a, b, f, d, e)``: ``E = c + a·x + b·y``, ``N = f + d·x + e·y``."""
    a1, a2, a3, a4, a5, a6 = map_to_image
    m = np.linalg.inv([[a1, a2], [a3, a4]])
    off = -m @ np.array([a5, a6])
    return (float(off[0]), float(m[0, 0]), float(m[0, 1]),
            float(off[1]), float(m[1, 0]), float(m[1, 1]))


def build_scenario(rng, size: int, north_up: bool = False, ascending: bool = False) -> Scenario:
    """Draw attitude errors and product grids; solve the F and B roll alignments so that
    the across-track offsets relative to N at the centre equal :data:`ACROSS_TARGET_PX`."""
    pass_direction = "ascending" if ascending else "descending"
    heading = np.radians(HEADING_DEG[pass_direction])
    a = np.array([-np.cos(heading), np.sin(heading)])
    orbit = geo.Orbit(track_origin=tuple(np.asarray(CENTRE) - TRACK_DISTANCE * a),
                      heading=float(heading), altitude=ALTITUDE, speed=SPEED, pixel=PIXEL,
                      tan_beta0=TRACK_DISTANCE / ALTITUDE, col0=size / 2)
    platform = geo.Attitude(roll=float(rng.normal(0, 3e-5)), pitch=float(rng.normal(0, 3e-5)),
                            yaw=float(rng.choice([-1, 1]) * rng.uniform(2e-4, 5e-4)),
                            roll_rate=float(rng.normal(0, 5e-7)),
                            pitch_rate=float(rng.normal(0, 5e-7)))
    alignment = {"N": {"roll": 0.0, "pitch": 0.0, "yaw": 0.0}}
    shifts = {"N": (0.0, 0.0)}
    for name in ("F", "B"):
        alignment[name] = {"roll": 0.0, "pitch": float(rng.normal(0, 1e-5)),
                           "yaw": float(rng.normal(0, 1e-5))}
        shifts[name] = (float(rng.uniform(-6, 6)), float(rng.uniform(-6, 6)))

    def make_view(name, align):
        theta = SIGNS[name] * np.radians(ANGLES_DEG[name])
        att = geo.Attitude(roll=platform.roll + align["roll"],
                           pitch=platform.pitch + align["pitch"],
                           yaw=platform.yaw + align["yaw"],
                           roll_rate=platform.roll_rate, pitch_rate=platform.pitch_rate)
        tau0 = -ALTITUDE * np.tan(theta) / SPEED - size / 2 * orbit.line_period
        return geo.View(name, float(theta), float(tau0), att,
                        product_affine(orbit, size, north_up, shifts[name]))

    centre = np.array([[CENTRE[0], CENTRE[1], 0.0]])
    views = {"N": make_view("N", alignment["N"])}
    for name in ("F", "B"):
        off0 = geo.across_offset_px(orbit, make_view(name, alignment[name]), views["N"], centre)
        trial = dict(alignment[name], roll=1e-5)
        off1 = geo.across_offset_px(orbit, make_view(name, trial), views["N"], centre)
        alignment[name]["roll"] = float(1e-5 * (ACROSS_TARGET_PX[name] - off0[0])
                                        / (off1[0] - off0[0]))
        views[name] = make_view(name, alignment[name])
    return Scenario(orbit, views, size, north_up, pass_direction, platform, alignment, shifts)
