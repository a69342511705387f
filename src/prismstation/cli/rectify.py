"""``prismstation rectify IMAGE POINTS.csv --transform KIND -o OUT.tif`` (docs/model.md §4).

Fits every image→map transform on the GCPs of one view, prints the side-by-side RMSE table
(GCPs and ICPs, as Subaryono et al.'s Table 4.1) and the chosen transform's residuals, and writes the
image rectified through the chosen transform as a GeoTIFF.
"""
from __future__ import annotations

from pathlib import Path

from prismstation.errors import InputError, ModelError
from prismstation.io.inputs import local_file
from prismstation.cli._common import end_progress, progress_printer
from prismstation.io.jsonfile import write_json
from prismstation.io.rectify_io import read_point_pairs
from prismstation.io.windows import raster_header
from prismstation.ops.rectify import KINDS, fit_transforms, format_rmse_table, rectify_raster


def register(sub) -> None:
    p = sub.add_parser("rectify", help="fit image-to-map transforms and write a rectified GeoTIFF")
    p.add_argument("image", help="raster to rectify (anything rasterio opens)")
    p.add_argument("points", help="ground points CSV (id,E,N[,H][,kind]); with x,y columns "
                                  "when --measurements is not given")
    p.add_argument("--measurements", metavar="M.csv", help="image measurements CSV (id,view,x,y)")
    p.add_argument("--view", help="view whose measurements to use (default: the only one)")
    p.add_argument("--transform", choices=KINDS, default="affine", help="transform to warp with")
    p.add_argument("-o", "--output", metavar="OUT.tif", help="rectified GeoTIFF to write")
    p.add_argument("--resolution", type=float, metavar="R", help="output cell size (output CRS units)")
    p.add_argument("--crs", help="output CRS (default: the points' CRS)")
    p.add_argument("--points-crs", help="CRS of the ground points (default: --crs, else the image's)")
    p.add_argument("--resampling", choices=("bilinear", "nearest"), default="bilinear")
    p.add_argument("--json", metavar="OUT", help="write the RMSE table and residuals as JSON")
    p.set_defaults(func=run)


def _points_crs(args):
    if args.points_crs:
        return args.points_crs
    if args.crs:
        return args.crs
    crs = raster_header(args.image, "image")[2]
    if crs is not None:
        return crs
    raise InputError("the image has no CRS: give the points' CRS with --points-crs or --crs",
                     file=args.image)


def run(args) -> int:
    local_file(args.image, "image")
    pairs = read_point_pairs(args.points, args.measurements, args.view)
    reports = fit_transforms(pairs)
    name = pairs.view or Path(args.image).stem
    print(f"{len(pairs.ids)} points ({int((~pairs.is_check).sum())} GCP, "
          f"{int(pairs.is_check.sum())} ICP), view {name}; planimetric RMSE:")
    print(format_rmse_table({name: reports}))
    chosen = next(r for r in reports if r.kind == args.transform)
    if not chosen.ok:
        raise ModelError(chosen.error)
    print(f"\nresiduals of {chosen.kind} (observed − computed, m):")
    print(f"{'id':<12}{'kind':<6}{'vE':>10}{'vN':>10}")
    for pid, icp, (vx, vy) in zip(pairs.ids, pairs.is_check, chosen.residuals):
        print(f"{pid:<12}{'ICP' if icp else 'GCP':<6}{vx:>10.3f}{vy:>10.3f}")
    if args.json:
        write_json(args.json, {
            "image": str(args.image), "view": pairs.view, "chosen": chosen.kind,
            "transforms": [{
                "kind": r.kind, "n_params": r.n_params, "n_gcp": r.n_gcp, "n_icp": r.n_icp,
                "rmse_gcp_m": r.rmse_gcp, "rmse_icp_m": r.rmse_icp,
                "rmse_gcp_xy_m": list(r.rmse_gcp_xy), "rmse_icp_xy_m": list(r.rmse_icp_xy),
                "sigma0_m": r.transform.sigma0 if r.ok else None,
                "params": r.transform.params if r.ok else None,
                "params_std": r.transform.std if r.ok else None,
                "error": r.error,
                "points": [{"id": i, "kind": "ICP" if c else "GCP", "vE": v[0], "vN": v[1]}
                           for i, c, v in zip(pairs.ids, pairs.is_check, r.residuals)],
            } for r in reports]})
    if args.output:
        res = rectify_raster(args.image, chosen.transform, args.output,
                             points_crs=_points_crs(args), out_crs=args.crs,
                             resolution=args.resolution, progress=progress_printer(f"writing {args.output}: "),
                             resampling=args.resampling)
        end_progress()
        print(f"\nwrote {res.path}: {res.width} x {res.height} cells of {res.resolution:g} "
              f"({res.crs}) through {chosen.kind}")
    return 0
