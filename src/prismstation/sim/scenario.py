"""The simulated acquisition: orbit, the three views, their attitude errors and product grids.

Numbers follow Gonçalves (2008): PRISM at Hs = 691 650 m, 2.5 m pixels, along-track angles
26.4° (F) and 26.8° (B), a scene in Portugal (UTM 29N around E 540 km, N 4560 km) unless the
terrain comes from a real DEM, which puts the scene's centre where it sits in that DEM (in the
UTM zone there; ``build_scenario(centre=...)``).

Two grids per view. The *render grid* (``View.map_to_image``) is the product's true
pixel ↔ nominal-ground relation: the image is rendered through it and the truth's image
coordinates follow from it. The *published grid* (``Scenario.published``) is what the product's
ancillary data claim (the GeoTIFF geotransform or scene.json ``map_to_image``): it is off by the
view's geolocation error. The errors are drawn per view, independently (:func:`draw_geolocation_errors`):
along- and across-track components each uniform in ``[−max, +max]`` metres (orientation studies
of PRISM triplets report shifts of about 50 m before calibration, ±10 m after). They are
exact at the scene centre at h = 0; elsewhere the attitude drift and yaw of each view (drawn
independently, :data:`DRIFT_SIGMA_RAD_S`) make them vary by metres across the scene.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

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
VIEW_NAMES = ("N", "F", "B")
HEADING_DEG = {"descending": 192.0, "ascending": 348.0}
#: default bound (m) of each component of a view's geolocation error (uniform in ±bound)
GEOLOCATION_ERROR_M = 50.0
#: σ (rad/s) of each view's own roll and pitch drift rates (≈0.7 m/s on the ground: a few
#: metres over a full 5 s scene), on top of the platform's common drift
DRIFT_SIGMA_RAD_S = 1e-6


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
    #: per view (along, across) geolocation error (m) at the scene centre, h = 0
    geolocation_error_m: dict[str, tuple[float, float]] = field(default_factory=dict)
    #: per view the published map_to_image (A1..A6): the render grid off by that error
    published: dict[str, tuple[float, ...]] = field(default_factory=dict)
    #: map position (E, N) of the scene centre (metres, in the scene's CRS)
    centre: tuple[float, float] = CENTRE

    def theta(self, name: str) -> float:
        return self.views[name].theta


def product_affine(orbit: geo.Orbit, size: int, north_up: bool, shift=(0.0, 0.0),
                   centre=CENTRE):
    """``map_to_image`` (A1..A6) of a ``size``² product of 2.5 m pixels centred on ``centre``
    (E, N): rows along the flight direction (1B2-R) or north-up (1B2-G); ``shift`` (px) moves
    the image content by (dx, dy)."""
    p = orbit.pixel
    c = np.asarray(centre, dtype=float)
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


def draw_geolocation_errors(rng, max_m: float, views=("N", "F", "B")) -> dict:
    """Per view an independent ``(along, across)`` error (m), each component uniform in
    ``[−max_m, +max_m]`` (along = flight direction, across = 90° to its left)."""
    if not (np.isfinite(max_m) and 0 <= max_m <= 1000):
        raise ValueError(f"geolocation error bound must be 0..1000 m, got {max_m}")
    return {v: (float(rng.uniform(-max_m, max_m)), float(rng.uniform(-max_m, max_m)))
            for v in views}


def true_ground_at_centre(orbit: geo.Orbit, view: geo.View, size: int) -> np.ndarray:
    """Where the TRUE ray of the image centre pixel meets h = 0 (E, N)."""
    o, d = geo.pixel_rays(orbit, view, np.array([size / 2, size / 2]))
    return geo.ray_at_height(o, d, 0.0)


def publish(orbit: geo.Orbit, view: geo.View, size: int, along: float, across: float):
    """The published ``map_to_image`` of ``view``: its render grid moved so that the published
    map position of the image centre is ``along·t + across·a`` metres off the true ground
    point it shows at h = 0."""
    a1, a2, a3, a4, a5, a6 = view.map_to_image
    centre = np.array([size / 2, size / 2])
    claimed = geo.image_to_map(view, centre)
    target = true_ground_at_centre(orbit, view, size) + along * orbit.t + across * orbit.a
    c = target - claimed                          # published position = render position + c
    return (a1, a2, a3, a4, float(a5 - (a1 * c[0] + a2 * c[1])),
            float(a6 - (a3 * c[0] + a4 * c[1])))


def geolocation_error_at(orbit: geo.Orbit, view: geo.View, published, xy) -> np.ndarray:
    """Published map position of image points ``xy`` (..., 2) minus the true ground point
    they show at h = 0 (E, N metres, shape (..., 2))."""
    o, d = geo.pixel_rays(orbit, view, xy)
    claimed = geo.image_to_map(geo.View(view.name, 0.0, 0.0, geo.Attitude(), tuple(published)), xy)
    return claimed - geo.ray_at_height(o, d, 0.0)


def build_scenario(rng, size: int, north_up: bool = False, ascending: bool = False,
                   geolocation_error_m: float = GEOLOCATION_ERROR_M, errors: dict | None = None,
                   centre=CENTRE, attitude_accel: float = 0.0) -> Scenario:
    """Draw attitude errors (a common platform part plus each view's own alignment and drift),
    product grids, and each view's geolocation error (``errors`` {view: (along, across)} m if
    given, else :func:`draw_geolocation_errors` with bound ``geolocation_error_m``). The scene
    is centred on ``centre`` (E, N metres); the draws do not depend on it. ``attitude_accel``
    (rad/s²): σ of each view's own roll and pitch acceleration (attitude not linear in time;
    drawn last, so that the other draws are those of a scene without it)."""
    centre = (float(centre[0]), float(centre[1]))
    pass_direction = "ascending" if ascending else "descending"
    heading = np.radians(HEADING_DEG[pass_direction])
    a = np.array([-np.cos(heading), np.sin(heading)])
    orbit = geo.Orbit(track_origin=tuple(np.asarray(centre) - TRACK_DISTANCE * a),
                      heading=float(heading), altitude=ALTITUDE, speed=SPEED, pixel=PIXEL,
                      tan_beta0=TRACK_DISTANCE / ALTITUDE, col0=size / 2)
    platform = geo.Attitude(roll=float(rng.normal(0, 3e-5)), pitch=float(rng.normal(0, 3e-5)),
                            yaw=float(rng.choice([-1, 1]) * rng.uniform(2e-4, 5e-4)),
                            roll_rate=float(rng.normal(0, 5e-7)),
                            pitch_rate=float(rng.normal(0, 5e-7)))
    alignment, shifts = {}, {}
    for name in VIEW_NAMES:
        alignment[name] = {k: float(rng.normal(0, 1e-5)) for k in ("roll", "pitch", "yaw")}
        alignment[name].update(roll_rate=float(rng.normal(0, DRIFT_SIGMA_RAD_S)),
                               pitch_rate=float(rng.normal(0, DRIFT_SIGMA_RAD_S)))
        shifts[name] = (0.0, 0.0) if name == "N" else (float(rng.uniform(-6, 6)),
                                                       float(rng.uniform(-6, 6)))
    if errors is None:
        errors = draw_geolocation_errors(rng, geolocation_error_m, VIEW_NAMES)
    if not (np.isfinite(attitude_accel) and 0 <= attitude_accel <= 1e-4):
        raise ValueError(f"attitude acceleration σ must be 0..1e-4 rad/s², got {attitude_accel}")
    for name in VIEW_NAMES:
        accel = rng.normal(0, attitude_accel, 2) if attitude_accel > 0 else (0.0, 0.0)
        alignment[name].update(roll_accel=float(accel[0]), pitch_accel=float(accel[1]))

    def make_view(name, align):
        theta = SIGNS[name] * np.radians(ANGLES_DEG[name])
        att = geo.Attitude(roll=platform.roll + align["roll"],
                           pitch=platform.pitch + align["pitch"],
                           yaw=platform.yaw + align["yaw"],
                           roll_rate=platform.roll_rate + align["roll_rate"],
                           pitch_rate=platform.pitch_rate + align["pitch_rate"],
                           roll_accel=align["roll_accel"], pitch_accel=align["pitch_accel"])
        tau0 = -ALTITUDE * np.tan(theta) / SPEED - size / 2 * orbit.line_period
        if att.roll_accel or att.pitch_accel:
            att = replace(att, accel_time=float(tau0 + size / 2 * orbit.line_period))
        return geo.View(name, float(theta), float(tau0), att,
                        product_affine(orbit, size, north_up, shifts[name], centre))

    # frame F and B around the ground N sees: the roll alignment cancels the across-track
    # offset the yaw makes 345 km ahead/behind (a framing choice of the product; where the
    # product CLAIMS its pixels are is set below by the geolocation errors)
    centre_enh = np.array([[centre[0], centre[1], 0.0]])
    views = {"N": make_view("N", alignment["N"])}
    for name in ("F", "B"):
        off0 = geo.across_offset_px(orbit, make_view(name, alignment[name]), views["N"], centre_enh)
        trial = dict(alignment[name], roll=alignment[name]["roll"] + 1e-5)
        off1 = geo.across_offset_px(orbit, make_view(name, trial), views["N"], centre_enh)
        alignment[name]["roll"] += float(1e-5 * -off0[0] / (off1[0] - off0[0]))
        views[name] = make_view(name, alignment[name])
    errors = {v: (float(errors[v][0]), float(errors[v][1])) for v in VIEW_NAMES}
    published = {v: publish(orbit, views[v], size, *errors[v]) for v in VIEW_NAMES}
    return Scenario(orbit, views, size, north_up, pass_direction, platform, alignment, shifts,
                    errors, published, centre)
