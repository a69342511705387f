"""``simulate()``: a synthetic PRISM 1B2 triplet with its truth, in the formats of docs/formats.md."""
from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

import numpy as np

from prismstation.errors import InputError
from prismstation.sim import render, writer
from prismstation.sim.dem_terrain import open_dem_terrain
from prismstation.sim.points import choose_points
from prismstation.sim.scenario import (ALTITUDE, ANGLES_DEG, CENTRE, CRS, GEOID, PIXEL,
                                       build_scenario, image_to_map_transform)
from prismstation.sim.scene_terrain import check_terrain, grid_over, make_terrain, scene_relief
from prismstation.sim.terrain import Grid, hillshade
from prismstation.sim.texture import MOTTLED, ParcelTexture, make_texture

__all__ = ["simulate", "scene_relief"]

TEXTURE_SPACING = 2.5
PSF_SIGMA_PX = 0.6
IMAGE_NOISE_DN = 1.2
VIEWS = ("N", "F", "B")
TEXTURES = ("fields", "parcels", "mottled")


def _check_rendering(psf_px, noise_dn, texture, attitude_accel, jpeg_quality, terrain_wavelength_m):
    if not (np.isfinite(psf_px) and 0 <= psf_px <= 5):
        raise InputError(f"--psf-px must be between 0 and 5 pixels, got {psf_px}")
    if not (np.isfinite(noise_dn) and 0 <= noise_dn <= 50):
        raise InputError(f"--noise-dn must be between 0 and 50, got {noise_dn}")
    if texture not in TEXTURES:
        raise InputError(f"--texture must be one of {', '.join(TEXTURES)}, got {texture!r}")
    if not (np.isfinite(attitude_accel) and 0 <= attitude_accel <= 1e-4):
        raise InputError(f"--attitude-accel must be between 0 and 1e-4 rad/s², got {attitude_accel}")
    if jpeg_quality is not None and not (1 <= int(jpeg_quality) <= 100):
        raise InputError(f"--jpeg-quality must be between 1 and 100, got {jpeg_quality}")
    if terrain_wavelength_m is not None and not (np.isfinite(terrain_wavelength_m) and 200 <= terrain_wavelength_m <= 50000):
        raise InputError(f"--terrain-wavelength-m must be between 200 and 50000, got {terrain_wavelength_m}")


def _check(size, n_gcp, n_icp, n_tie, noise_px, survey_sigma_xy, survey_sigma_h):
    if not 256 <= size <= 30000:
        raise InputError(f"--size must be between 256 and 30000 pixels, got {size}")
    for name, v in (("GCPs", n_gcp), ("ICPs", n_icp), ("tie points", n_tie)):
        if v < 0 or v > 999:
            raise InputError(f"number of {name} must be 0..999, got {v}")
    if n_gcp + n_icp + n_tie > size * size / 2000:
        raise InputError(f"{n_gcp + n_icp + n_tie} points do not fit in a {size} px image")
    for name, v in (("--noise-px", noise_px), ("survey sigma xy", survey_sigma_xy),
                    ("survey sigma h", survey_sigma_h)):
        if not (np.isfinite(v) and 0 <= v <= 100):
            raise InputError(f"{name} must be between 0 and 100, got {v}")


def simulate(outdir, *, size=2000, seed=0, n_gcp=9, n_icp=41, n_tie=20, noise_px=0.3,
             survey_sigma_xy=0.5, survey_sigma_h=1.0, north_up=False, ascending=False,
             map_to_image_in_json=False, geolocation_error_m=50.0, geolocation_errors=None,
             terrain="fractal", terrain_dem=None, terrain_centre=None, relief_scale=1.0,
             psf_px=PSF_SIGMA_PX, noise_dn=IMAGE_NOISE_DN, texture="fields", attitude_accel=0.0,
             jpeg_quality=None, terrain_wavelength_m=None, progress=None) -> dict:
    """Write a synthetic ALOS-PRISM 1B2 triplet with known truth into ``outdir``.

    Parameters
    ----------
    outdir : str or Path, created if absent.
    size : pixels per side of each image (2.5 m pixels). The fractal relief spans 0–1400 m
        orthometric at 14,000 px, less on smaller scenes (``scene_relief``).
    seed : everything is deterministic given the arguments.
    n_gcp, n_icp, n_tie : numbers of points; ties appear only in ``measurements.csv``.
    noise_px : σ (px) of the Gaussian measurement noise per image coordinate.
    survey_sigma_xy, survey_sigma_h : σ (m) of the surveyed ground coordinates' noise.
    north_up : 1B2-G grid instead of the path-oriented 1B2-R grid.
    ascending : ascending pass (heading 348°) instead of descending (192°).
    map_to_image_in_json : write each view's ``map_to_image`` into scene.json and leave the
        TIFFs without georeferencing.
    geolocation_error_m : bound (m) of each view's independent geolocation error: along- and
        across-track components each drawn uniform in ``[−bound, +bound]`` (0: exact
        ancillary geolocation at the scene centre). See :mod:`prismstation.sim.scenario`.
    geolocation_errors : optional ``{view: (along_m, across_m)}`` instead of drawing them.
    terrain : ``"fractal"`` (ridges and valleys), ``"smooth"`` (rolling hills, 6 % mean slope)
        or ``"dem"`` (``terrain_dem``, a real DEM of orthometric heights in any CRS: the scene
        is centred on its point ``terrain_centre`` (x, y in the DEM's CRS; default its centre),
        in the UTM zone there). See :mod:`prismstation.sim.scene_terrain`.
    relief_scale : heights scaled by this factor (0 < f ≤ 1) about their mean over the
        ground N sees.
    psf_px : σ (px) of the Gaussian point spread (0: none — each pixel one point of the
        ground, sharp edges alias).
    noise_dn : σ (DN) of the images' Gaussian noise.
    texture : ``"fields"`` (field patchworks, hedges, roads, forest on a 2.5 m grid) or
        ``"parcels"`` (flat parcels with hard edges, no texture inside; see
        :class:`prismstation.sim.texture.ParcelTexture`) or ``"mottled"`` (larger parcels of
        lower contrast with a faint grain inside, :data:`prismstation.sim.texture.MOTTLED`).
    attitude_accel : σ (rad/s²) of each view's own roll and pitch acceleration: attitude not
        linear in time (0: linear drift only).
    jpeg_quality : JPEG quality (1–100) the images go through (8 × 8 block noise), or None.
    terrain_wavelength_m : the smooth terrain's shortest wavelength (m; default 1,200): longer
        makes hills that are nearly a plane over a few kilometres.
    progress : optional ``callable(fraction)``.

    Returns
    -------
    dict of name → Path: ``N``, ``F``, ``B``, ``scene``, ``points``, ``measurements``,
    ``truth``, ``truth_dem``.
    """
    _check(size, n_gcp, n_icp, n_tie, noise_px, survey_sigma_xy, survey_sigma_h)
    _check_rendering(psf_px, noise_dn, texture, attitude_accel, jpeg_quality, terrain_wavelength_m)
    if terrain_wavelength_m is not None and terrain != "smooth":
        raise InputError("--terrain-wavelength-m is the smooth terrain's; add --terrain smooth")
    report = progress or (lambda f: None)
    if not (np.isfinite(geolocation_error_m) and 0 <= geolocation_error_m <= 1000):
        raise InputError(f"--geolocation-error-m must be between 0 and 1000, got {geolocation_error_m}")
    check_terrain(terrain, terrain_dem is not None, relief_scale)
    placed, crs, centre = None, CRS, CENTRE
    if terrain_dem is not None:
        placed = open_dem_terrain(terrain_dem, terrain_centre)
        crs, centre = placed.scene_crs, placed.centre
    elif terrain_centre is not None:
        raise InputError("--terrain-centre places the scene in a --terrain-dem; there is none")
    ss = np.random.SeedSequence(seed)
    r_att, r_terrain, r_texture, r_points, r_noise, r_render = (
        np.random.default_rng(s) for s in ss.spawn(6))
    scenario = build_scenario(r_att, size, north_up, ascending, geolocation_error_m,
                              geolocation_errors, centre, attitude_accel)

    # terrain (ellipsoidal heights) and its derived grids; nothing is written before it is made
    land = make_terrain(scenario, terrain, r_terrain, placed, relief_scale, terrain_wavelength_m)
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    lo, hi, h_min, h_max = land.lo, land.hi, land.h_min, land.h_max
    ortho_grid = land.ortho
    ortho, e0, n0, dem_spacing = ortho_grid.values, ortho_grid.e0, ortho_grid.n0, ortho_grid.spacing
    dem = Grid((ortho + GEOID).astype(np.float32), e0, n0, dem_spacing)
    shade = Grid(hillshade(ortho, dem_spacing), e0, n0, dem_spacing)
    gy, gx = np.gradient(ortho, dem_spacing)
    slope = Grid(np.hypot(gx, gy).astype(np.float32), e0, n0, dem_spacing)
    del gx, gy
    report(0.03)

    te0, tn0, tshape = grid_over(lo, hi, TEXTURE_SPACING)
    kind = texture
    if kind in ("parcels", "mottled"):
        texture = ParcelTexture(r_texture, (te0, tn0), shade=shade, **(MOTTLED if kind == "mottled" else {}))
    else:
        texture = make_texture(r_texture, te0, tn0, tshape, TEXTURE_SPACING, ortho_grid, shade,
                               slope, progress=lambda f: report(0.03 + 0.12 * f))
    del shade, slope

    # images
    paths = {}
    block = int(max(64, min(512, 4_000_000 // size)))
    block -= block % 64 if block > 64 else 0
    sampler = render.dem_sampler(dem)
    for k, name in enumerate(VIEWS):
        view = scenario.views[name]
        path = out / f"{name}.tif"
        gt = None if map_to_image_in_json else image_to_map_transform(scenario.published[name])
        rng = np.random.default_rng(r_render.integers(2 ** 63))
        with writer.product_writer(path, size, gt, crs, overviews=size > 4096) as write:
            for r0 in range(0, size, block):
                r1 = min(size, r0 + block)
                rows = render.render_rows(scenario.orbit, view, size, r0, r1, dem, texture,
                                          h_min, h_max, psf_px, noise_dn, rng, sampler=sampler)
                rows = render.to_uint8(rows)
                write(rows if jpeg_quality is None else render.jpeg_blocks(rows, jpeg_quality), r0)
                report(0.15 + 0.8 * (k + r1 / size * 0.9) / 3)
        paths[name] = path
    del texture

    points = choose_points(r_points, scenario, dem, n_gcp, n_icp, n_tie)
    paths.update(_write_tables(out, scenario, crs, dem, land.info, points, r_noise, noise_px,
                               survey_sigma_xy, survey_sigma_h, map_to_image_in_json,
                               dict(seed=seed, size=size, n_gcp=n_gcp, n_icp=n_icp,
                                    n_tie=n_tie, noise_px=noise_px,
                                    survey_sigma_xy=survey_sigma_xy,
                                    survey_sigma_h=survey_sigma_h, north_up=north_up,
                                    ascending=ascending,
                                    map_to_image_in_json=map_to_image_in_json,
                                    geolocation_error_m=geolocation_error_m,
                                    terrain=terrain, relief_scale=relief_scale, psf_px=psf_px,
                                    noise_dn=noise_dn, texture=kind, attitude_accel=attitude_accel,
                                    jpeg_quality=jpeg_quality,
                                    terrain_wavelength_m=terrain_wavelength_m)))
    report(1.0)
    return paths


def _ground_track(scenario):
    s = scenario.size
    o = scenario.orbit
    taus = [v.tau0 for v in scenario.views.values()]
    t0 = min(taus) - 2.0
    t1 = max(taus) + s * o.line_period + 2.0
    return [[round(float(v), 3) for v in o.sub_satellite(t)] for t in (t0, 0.0, t1)]


def _write_tables(out, scenario, crs, dem, terrain, points, rng, noise_px, sxy, sh, m2i_json,
                  args):
    paths = {}
    dem_path = out / "truth_dem.tif"
    writer.write_grid(dem_path, dem, crs)
    paths["truth_dem"] = dem_path

    views_json = {}
    for name in VIEWS:
        v = {"image": f"{name}.tif", "pixel_size_m": PIXEL,
             "along_track_angle_deg": ANGLES_DEG[name]}
        if m2i_json:
            v["map_to_image"] = list(scenario.published[name])
        views_json[name] = v
    scene = {"format": "prismstation-scene/1", "crs": crs, "satellite_altitude_m": ALTITUDE,
             "ground_track": _ground_track(scenario), "views": views_json,
             "geoid_undulation_m": GEOID,
             "product_level": "1B2G" if scenario.north_up else "1B2R",
             "pass": scenario.pass_direction, "generator": "prismstation simulate"}
    paths["scene"] = out / "scene.json"
    writer.write_json(paths["scene"], scene)

    rows, meas, truth_points = [], [], []
    for p in points:
        entry = {"id": p.id, "kind": p.kind, "E": p.E, "N": p.N, "h": p.h, "H": p.h - GEOID,
                 "image": {k: list(v) for k, v in p.xy.items()}, "measured": {}}
        if p.kind != "TIE":
            de, dn = rng.normal(0, sxy, 2) if sxy else (0.0, 0.0)
            es, ns = p.E + de, p.N + dn
            hs = p.h - GEOID + (rng.normal(0, sh) if sh else 0.0)
            entry["surveyed"] = {"E": es, "N": ns, "H": hs}
            rows.append([p.id, f"{es:.3f}", f"{ns:.3f}", f"{hs:.3f}", p.kind, "orthometric",
                         sxy, sh])
        for name in VIEWS:
            x, y = p.xy[name]
            if noise_px:
                x, y = x + rng.normal(0, noise_px), y + rng.normal(0, noise_px)
            entry["measured"][name] = [x, y]
            meas.append([p.id, name, f"{x:.4f}", f"{y:.4f}"])
        truth_points.append(entry)
    paths["points"] = out / "points.csv"
    writer.write_csv(paths["points"], ["id", "E", "N", "H", "kind", "height", "sigma_xy_m",
                                       "sigma_h_m"], rows)
    paths["measurements"] = out / "measurements.csv"
    writer.write_csv(paths["measurements"], ["id", "view", "x", "y"], meas)

    o = scenario.orbit
    stats = {}
    for name in ("F", "B"):
        if points:
            d = published_across_px(scenario, name, points)
            stats[f"across_{name}_minus_N_px"] = {"mean": float(d.mean()), "std": float(d.std())}
    truth = {
        "format": "prismstation-sim-truth/1", "arguments": args,
        "constants": {"crs": crs, "centre": list(scenario.centre), "altitude_m": ALTITUDE,
                      "speed_m_s": o.speed, "pixel_m": PIXEL, "geoid_undulation_m": GEOID,
                      "heading_deg": float(np.degrees(o.heading)),
                      "track_origin": list(o.track_origin), "tan_beta0": o.tan_beta0,
                      "col0": o.col0, "ifov_rad": o.ifov, "line_period_s": o.line_period,
                      "image_noise_dn": args["noise_dn"], "psf_sigma_px": args["psf_px"],
                      "relief_m": float(dem.values.max() - GEOID)},
        "platform_attitude": asdict(scenario.platform),
        "views": {name: {"theta_rad": v.theta, "tau0_s": v.tau0,
                         "attitude": {f: getattr(v.attitude, f) for f in
                                      ("roll", "pitch", "yaw", "roll_rate", "pitch_rate",
                                       "roll_accel", "pitch_accel", "accel_time")},
                         "alignment": scenario.alignment[name],
                         "grid_shift_px": list(scenario.grid_shift_px[name]),
                         "map_to_image": list(v.map_to_image),
                         "published_map_to_image": list(scenario.published[name]),
                         "geolocation_error_m": _error_entry(scenario, name),
                         "geotransform": list(image_to_map_transform(scenario.published[name]))}
                  for name, v in scenario.views.items()},
        "geolocation_error_bound_m": args["geolocation_error_m"],
        "dem": {"file": "truth_dem.tif", "heights": "ellipsoidal", "spacing_m": dem.spacing},
        "terrain": terrain,
        "statistics": stats,
        "points": truth_points,
    }
    paths["truth"] = out / "truth.json"
    writer.write_json(paths["truth"], truth)
    return paths


def _error_entry(scenario, name) -> dict:
    along, across = scenario.geolocation_error_m[name]
    e = along * scenario.orbit.t + across * scenario.orbit.a
    return {"along": along, "across": across, "E": float(e[0]), "N": float(e[1]),
            "where": "scene centre, h = 0; published minus true"}


def published_across_px(scenario, name: str, points) -> np.ndarray:
    """The across-track offset (px) of ``name`` relative to N as the fit reports it: each
    point's true image position in ``name`` carried into N image space through the PUBLISHED
    grids, minus its true N position, along ``(d_y, −d_x)`` of the N-space flight direction."""
    def m2i(c, en):
        return np.stack([c[0] * en[..., 0] + c[1] * en[..., 1] + c[4],
                         c[2] * en[..., 0] + c[3] * en[..., 1] + c[5]], axis=-1)

    def i2m(c, xy):
        m = np.linalg.inv([[c[0], c[1]], [c[2], c[3]]])
        return (np.asarray(xy) - [c[4], c[5]]) @ m.T

    pn, pv = scenario.published["N"], scenario.published[name]
    xn = np.array([p.xy["N"] for p in points])
    xv = np.array([p.xy[name] for p in points])
    d = np.array([[pn[0], pn[1]], [pn[2], pn[3]]]) @ scenario.orbit.t
    d /= np.linalg.norm(d)
    cross = np.array([d[1], -d[0]])
    return (m2i(pn, i2m(pv, xv)) - xn) @ cross
