"""``simulate()``: a synthetic PRISM 1B2 triplet with its truth, in the docs/formats.md formats."""
from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

import numpy as np

from prismstation.errors import InputError
from prismstation.sim import geometry as geo
from prismstation.sim import render, writer
from prismstation.sim.points import choose_points
from prismstation.sim.scenario import (ALTITUDE, ANGLES_DEG, CENTRE, CRS, GEOID, PIXEL,
                                       build_scenario, image_to_map_transform)
from prismstation.sim.terrain import Grid, hillshade, synthesize_relief
from prismstation.sim.texture import make_texture

RELIEF = 1400.0
TEXTURE_SPACING = 2.5
PSF_SIGMA_PX = 0.6
IMAGE_NOISE_DN = 1.2
VIEWS = ("N", "F", "B")


def scene_relief(size: int) -> float:
    """Relief (m) of a ``size`` px scene: 1400 m on a full 14,000 px (35 km) scene like the
    paper's; smaller scenes get less (∝ extent^0.35) so that slopes stay those of real hilly
    terrain instead of 1400 m walls in 5 km, which no stereo pair at ±26° could match."""
    return RELIEF * min(1.0, (size / 14000.0) ** 0.35)


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


def _ground_bbox(scenario, h_lo, h_hi, margin=250.0):
    """Map bounding box of everything any view's pixels can see between two heights."""
    s = scenario.size
    corners = np.array([[0, 0], [s, 0], [0, s], [s, s]], dtype=float)
    pts = []
    for view in scenario.views.values():
        o, d = geo.pixel_rays(scenario.orbit, view, corners)
        pts += [geo.ray_at_height(o, d, h) for h in (h_lo, h_hi)]
    pts = np.concatenate(pts)
    return pts.min(axis=0) - margin, pts.max(axis=0) + margin


def _grid_over(lo, hi, spacing):
    cols = int(np.ceil((hi[0] - lo[0]) / spacing))
    rows = int(np.ceil((hi[1] - lo[1]) / spacing))
    e0 = np.floor(lo[0] / spacing) * spacing
    n0 = np.ceil(hi[1] / spacing) * spacing
    return e0, n0, (rows + 1, cols + 1)


def simulate(outdir, *, size=2000, seed=0, n_gcp=9, n_icp=41, n_tie=20, noise_px=0.3,
             survey_sigma_xy=0.5, survey_sigma_h=1.0, north_up=False, ascending=False,
             map_to_image_in_json=False, geolocation_error_m=50.0, geolocation_errors=None,
             progress=None) -> dict:
    """Write a synthetic ALOS-PRISM 1B2 triplet with known truth into ``outdir``.

    Parameters
    ----------
    outdir : str or Path, created if absent.
    size : pixels per side of each image (2.5 m pixels). Relief spans 0–1400 m orthometric
        from 2000 px up; smaller test scenes scale it by ``size / 2000``.
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
    progress : optional ``callable(fraction)``.

    Returns
    -------
    dict of name → Path: ``N``, ``F``, ``B``, ``scene``, ``points``, ``measurements``,
    ``truth``, ``truth_dem``.
    """
    _check(size, n_gcp, n_icp, n_tie, noise_px, survey_sigma_xy, survey_sigma_h)
    report = progress or (lambda f: None)
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    ss = np.random.SeedSequence(seed)
    r_att, r_terrain, r_texture, r_points, r_noise, r_render = (
        np.random.default_rng(s) for s in ss.spawn(6))

    if not (np.isfinite(geolocation_error_m) and 0 <= geolocation_error_m <= 1000):
        raise InputError(f"--geolocation-error-m must be between 0 and 1000, got {geolocation_error_m}")
    scenario = build_scenario(r_att, size, north_up, ascending, geolocation_error_m,
                              geolocation_errors)
    relief = scene_relief(size)
    h_min, h_max = GEOID - 1.0, GEOID + relief + 1.0
    lo, hi = _ground_bbox(scenario, h_min - 50.0, h_max + 50.0)

    # terrain (ellipsoidal heights) and its derived grids
    dem_spacing = 5.0 if size <= 6000 else 10.0
    e0, n0, shape = _grid_over(lo, hi, dem_spacing)
    ortho = synthesize_relief(shape, dem_spacing, r_terrain, relief=relief)
    dem = Grid((ortho + GEOID).astype(np.float32), e0, n0, dem_spacing)
    ortho_grid = Grid(ortho, e0, n0, dem_spacing)
    shade = Grid(hillshade(ortho, dem_spacing), e0, n0, dem_spacing)
    gy, gx = np.gradient(ortho, dem_spacing)
    slope = Grid(np.hypot(gx, gy).astype(np.float32), e0, n0, dem_spacing)
    del gx, gy
    report(0.03)

    te0, tn0, tshape = _grid_over(lo, hi, TEXTURE_SPACING)
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
        with writer.product_writer(path, size, gt, CRS) as write:
            for r0 in range(0, size, block):
                r1 = min(size, r0 + block)
                rows = render.render_rows(scenario.orbit, view, size, r0, r1, dem, texture,
                                          h_min, h_max, PSF_SIGMA_PX, IMAGE_NOISE_DN, rng,
                                          sampler=sampler)
                write(render.to_uint8(rows), r0)
                report(0.15 + 0.8 * (k + r1 / size * 0.9) / 3)
        if size > 4096:
            writer.add_overviews(path, size)
        paths[name] = path
    del texture

    points = choose_points(r_points, scenario, dem, n_gcp, n_icp, n_tie)
    paths.update(_write_tables(out, scenario, dem, points, r_noise, noise_px,
                               survey_sigma_xy, survey_sigma_h, map_to_image_in_json,
                               dict(seed=seed, size=size, n_gcp=n_gcp, n_icp=n_icp,
                                    n_tie=n_tie, noise_px=noise_px,
                                    survey_sigma_xy=survey_sigma_xy,
                                    survey_sigma_h=survey_sigma_h, north_up=north_up,
                                    ascending=ascending,
                                    map_to_image_in_json=map_to_image_in_json,
                                    geolocation_error_m=geolocation_error_m)))
    report(1.0)
    return paths


def _ground_track(scenario):
    s = scenario.size
    o = scenario.orbit
    taus = [v.tau0 for v in scenario.views.values()]
    t0 = min(taus) - 2.0
    t1 = max(taus) + s * o.line_period + 2.0
    return [[round(float(v), 3) for v in o.sub_satellite(t)] for t in (t0, 0.0, t1)]


def _write_tables(out, scenario, dem, points, rng, noise_px, sxy, sh, m2i_json, args):
    paths = {}
    dem_path = out / "truth_dem.tif"
    writer.write_grid(dem_path, dem, CRS)
    paths["truth_dem"] = dem_path

    views_json = {}
    for name in VIEWS:
        v = {"image": f"{name}.tif", "pixel_size_m": PIXEL,
             "along_track_angle_deg": ANGLES_DEG[name]}
        if m2i_json:
            v["map_to_image"] = list(scenario.published[name])
        views_json[name] = v
    scene = {"format": "prismstation-scene/1", "crs": CRS, "satellite_altitude_m": ALTITUDE,
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
        "constants": {"crs": CRS, "centre": list(CENTRE), "altitude_m": ALTITUDE,
                      "speed_m_s": o.speed, "pixel_m": PIXEL, "geoid_undulation_m": GEOID,
                      "heading_deg": float(np.degrees(o.heading)),
                      "track_origin": list(o.track_origin), "tan_beta0": o.tan_beta0,
                      "col0": o.col0, "ifov_rad": o.ifov, "line_period_s": o.line_period,
                      "image_noise_dn": IMAGE_NOISE_DN, "psf_sigma_px": PSF_SIGMA_PX,
                      "relief_m": float(dem.values.max() - GEOID)},
        "platform_attitude": asdict(scenario.platform),
        "views": {name: {"theta_rad": v.theta, "tau0_s": v.tau0,
                         "attitude": {f: getattr(v.attitude, f) for f in
                                      ("roll", "pitch", "yaw", "roll_rate", "pitch_rate")},
                         "alignment": scenario.alignment[name],
                         "grid_shift_px": list(scenario.grid_shift_px[name]),
                         "map_to_image": list(v.map_to_image),
                         "published_map_to_image": list(scenario.published[name]),
                         "geolocation_error_m": _error_entry(scenario, name),
                         "geotransform": list(image_to_map_transform(scenario.published[name]))}
                  for name, v in scenario.views.items()},
        "geolocation_error_bound_m": args["geolocation_error_m"],
        "dem": {"file": "truth_dem.tif", "heights": "ellipsoidal", "spacing_m": dem.spacing},
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
