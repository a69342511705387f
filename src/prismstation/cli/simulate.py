"""``prismstation simulate OUTDIR [--seed N] [--size N] ...``: a synthetic PRISM 1B2 triplet.

Writes ``N.tif``, ``F.tif``, ``B.tif``, ``scene.json``, ``points.csv``, ``measurements.csv``
(docs/formats.md) and the truth: ``truth.json``, ``truth_dem.tif`` (ellipsoidal heights); with
``--reference`` also an SRTM-like reference DEM, ``srtm.tif`` (:mod:`prismstation.sim.reference`).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from prismstation.errors import InputError, PrismError, WriteError
from prismstation.io.geoid import GridGeoid, find_grid


def _one_line_error(prog: str):
    def error(message: str):
        print(f"{prog}: {message}", file=sys.stderr)
        raise SystemExit(2)
    return error


def register(sub) -> None:
    p = sub.add_parser("simulate", help="write a synthetic PRISM 1B2 triplet with its truth",
                       description=__doc__.splitlines()[0])
    p.add_argument("outdir", metavar="OUTDIR", help="folder to write into (created if absent)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--size", type=int, default=2000,
                   help="pixels per side of each image, 2.5 m pixels (default 2000; 14000 = full scene)")
    p.add_argument("--gcp", type=int, default=9, help="number of GCPs (default 9)")
    p.add_argument("--icp", type=int, default=41, help="number of ICPs (default 41)")
    p.add_argument("--ties", type=int, default=20, help="number of tie points (default 20)")
    p.add_argument("--noise-px", type=float, default=0.3,
                   help="σ of the image measurement noise, pixels (default 0.3)")
    p.add_argument("--survey-sigma-xy", type=float, default=0.5,
                   help="σ of the surveyed E, N noise, metres (default 0.5; 0 = exact)")
    p.add_argument("--survey-sigma-h", type=float, default=1.0,
                   help="σ of the surveyed height noise, metres (default 1.0; 0 = exact)")
    p.add_argument("--north-up", action="store_true", help="1B2-G north-up grid (default 1B2-R)")
    p.add_argument("--pass", dest="pass_direction", choices=["descending", "ascending"],
                   default="descending", help="orbit direction (default descending)")
    p.add_argument("--map-to-image-in-json", action="store_true",
                   help="write map_to_image into scene.json, TIFFs without georeferencing")
    p.add_argument("--geolocation-error-m", type=float, default=50.0, metavar="MAX",
                   help="bound of each view's own geolocation error, metres: along- and across-track "
                        "components drawn independently, uniform in [-MAX, +MAX] (default 50; 0 = exact)")
    p.add_argument("--terrain", choices=["fractal", "smooth", "dem"], default=None,
                   help="fractal: ridges and valleys (default); smooth: rolling hills, 6 %% mean "
                        "slope, nothing shorter than about 1 km; dem: from --terrain-dem")
    p.add_argument("--terrain-dem", metavar="DEM",
                   help="take the terrain from this DEM (SRTM .hgt, GeoTIFF; any CRS; heights "
                        "orthometric), bicubic; the scene moves there, into the UTM zone")
    p.add_argument("--terrain-centre", type=float, nargs=2, metavar=("X", "Y"),
                   help="where in the DEM the scene's centre sits, in the DEM's CRS (longitude "
                        "latitude for EPSG:4326; default the DEM's centre)")
    p.add_argument("--relief-scale", type=float, default=1.0, metavar="F",
                   help="scale the heights by F about their mean over the ground N sees, "
                        "0 < F <= 1 (default 1)")
    p.add_argument("--terrain-wavelength-m", type=float, default=None, metavar="M",
                   help="the smooth terrain's shortest wavelength, metres (default 1200; 5000: hills "
                        "that are nearly a plane over a few kilometres)")
    p.add_argument("--texture", choices=["fields", "parcels", "mottled"], default="fields",
                   help="fields: field patchworks with hedges, roads and forest (default); parcels: "
                        "flat parcels with hard edges and no texture inside; mottled: larger parcels "
                        "of lower contrast with a faint grain inside")
    p.add_argument("--psf-px", type=float, default=0.6, metavar="SIGMA",
                   help="σ of the sensor's Gaussian point spread, pixels (default 0.6; 0 = each pixel "
                        "one point of the ground: sharp edges alias)")
    p.add_argument("--noise-dn", type=float, default=1.2, metavar="SIGMA",
                   help="σ of the images' noise, DN (default 1.2)")
    p.add_argument("--attitude-accel", type=float, default=0.0, metavar="RAD_S2",
                   help="σ of each view's own roll and pitch acceleration, rad/s² (default 0: attitude "
                        "drifts linearly in time; 5e-7 bends F−B parallax by ~0.05 px over 10 km)")
    p.add_argument("--jpeg-quality", type=int, default=None, metavar="Q",
                   help="pass the images through JPEG at quality Q (1–100): 8 × 8 block noise as "
                        "compressed products carry (default: none)")
    p.add_argument("--reference", choices=["projected", "geographic"],
                   help="also write an SRTM-like reference DEM, srtm.tif: projected (90 m cells of "
                        "the scene's grid, the scene's constant geoid) or geographic (3\" cells of "
                        "EPSG:4326, heights through a geoid grid, as SRTM is shipped)")
    p.add_argument("--reference-noise-m", type=float, metavar="M",
                   help="σ of the reference's white noise per cell, metres (default 2 projected, "
                        "4 geographic)")
    p.add_argument("--reference-geoid", metavar="GRID",
                   help="geoid grid of the geographic reference's heights (default: the EGM96 "
                        "grid on PROJ's data paths)")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    p.error = _one_line_error("prismstation simulate")
    p.set_defaults(func=run)


def run(args) -> int:
    from prismstation.sim import simulate  # start-up: the simulator loads only to simulate

    out = Path(args.outdir)
    if out.exists() and not out.is_dir():
        raise InputError("exists and is not a folder", file=out)
    geoid = _reference_geoid(args)
    shown = [-1]

    def progress(fraction: float) -> None:
        pct = int(100 * fraction)
        if not args.quiet and pct // 5 != shown[0] // 5:
            shown[0] = pct
            print(f"\rsimulating {pct:3d}%", end="", file=sys.stderr, flush=True)

    try:
        paths = simulate(out, size=args.size, seed=args.seed, n_gcp=args.gcp, n_icp=args.icp,
                         n_tie=args.ties, noise_px=args.noise_px,
                         survey_sigma_xy=args.survey_sigma_xy,
                         survey_sigma_h=args.survey_sigma_h, north_up=args.north_up,
                         ascending=args.pass_direction == "ascending",
                         map_to_image_in_json=args.map_to_image_in_json,
                         geolocation_error_m=args.geolocation_error_m,
                         terrain=args.terrain or ("dem" if args.terrain_dem else "fractal"),
                         terrain_dem=args.terrain_dem, terrain_centre=args.terrain_centre,
                         relief_scale=args.relief_scale, psf_px=args.psf_px, noise_dn=args.noise_dn,
                         texture=args.texture, attitude_accel=args.attitude_accel,
                         jpeg_quality=args.jpeg_quality, terrain_wavelength_m=args.terrain_wavelength_m,
                         progress=progress)
    except PrismError:
        raise
    except OSError as exc:  # the folder itself (a file writer raises WriteError naming its file)
        raise WriteError(f"cannot write: {exc.strerror or exc}", out) from None
    finally:
        if not args.quiet and shown[0] >= 0:
            print(file=sys.stderr)
    if args.reference:
        paths["reference"] = _write_reference(args, paths, out / "srtm.tif", geoid)
    print(f"wrote {', '.join(sorted(p.name for p in paths.values()))} into {out}")
    print(describe_terrain(json.loads(paths["truth"].read_text(encoding="utf-8"))["terrain"]))
    if args.reference == "geographic":
        print(f"srtm.tif: 3\" EPSG:4326, orthometric through {geoid.describe()} (a project "
              f"reads it with new --geoid {geoid.path}; points.csv's orthometric heights use "
              f"the scene's constant geoid)")
    return 0


def _reference_geoid(args):
    """The geoid of a geographic reference, checked before anything is simulated."""
    noise = args.reference_noise_m
    if noise is not None and not (noise >= 0 and noise <= 100):
        raise InputError(f"--reference-noise-m must be between 0 and 100, got {noise}")
    if args.reference != "geographic":
        if args.reference_geoid:
            raise InputError("--reference-geoid is for --reference geographic")
        return None
    grid = args.reference_geoid or find_grid()
    if grid is None:
        raise InputError("a geographic reference needs a geoid grid (EGM96 egm96_15.gtx) and "
                         "none is on PROJ's data paths: give --reference-geoid GRID")
    if not Path(grid).is_file():
        raise InputError("geoid grid not found", file=grid)
    return GridGeoid(grid)


def _write_reference(args, paths, out: Path, geoid) -> Path:
    from prismstation.sim.reference import make_geographic_reference, make_reference_dem  # start-up: the simulator

    seed = args.seed + 1          # the reference's noise and voids: not the scene's draws
    if args.reference == "geographic":
        noise = 4.0 if args.reference_noise_m is None else args.reference_noise_m
        return make_geographic_reference(paths["truth_dem"], out, geoid, noise_m=noise, seed=seed)
    noise = 2.0 if args.reference_noise_m is None else args.reference_noise_m
    return make_reference_dem(paths["truth_dem"], out, noise_m=noise, seed=seed)


def describe_terrain(terrain: dict) -> str:
    """One line: the terrain's kind and statistics as ``truth.json`` stores them."""
    s = terrain["statistics"]
    where = ""
    if terrain["kind"] == "dem":
        where = (f" from {Path(terrain['file']).name} at {terrain['at'][0]:g} {terrain['at'][1]:g}"
                 f" ({terrain['scene_crs']}; {terrain['void_filled_pct']:g} % voids filled)")
    scaled = f", heights x{terrain['relief_scale']:g} about their mean" if terrain["relief_scale"] != 1 else ""
    return (f"terrain {terrain['kind']}{where}{scaled}: heights {s['height_min_m']:.0f}-"
            f"{s['height_max_m']:.0f} m orthometric (mean {s['height_mean_m']:.0f} m), mean slope "
            f"{s['mean_slope_pct']:.1f} %, slopes over 30 %: {s['slope_over_30pct_share_pct']:.1f} % "
            f"of the ground N sees ({s['slope_cell_m']:g} m cells)")
