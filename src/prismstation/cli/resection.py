"""``prismstation resection POINTS.csv --focal-mm F --pixel-um P ...`` (docs/model.md §4;
:func:`prismstation.ops.resection.resect_points`).

Space resection of one view from ground points (``id,E,N,H``) and their image measurements,
by Gauss–Newton on the collinearity equations. Prints the exterior orientation with standard
deviations and each iteration's corrections; ``--json`` writes all of it.
"""
from __future__ import annotations

import numpy as np

from prismstation.io.jsonfile import write_json
from prismstation.io.rectify_io import read_point_pairs
from prismstation.io.windows import raster_header
from prismstation.ops.resection import PARAM_NAMES, resect_points


def register(sub) -> None:
    p = sub.add_parser("resection", help="space resection of a frame image (EO, σ, iteration history)")
    p.add_argument("points", help="ground points CSV (id,E,N,H[,kind]); with x,y columns "
                                  "when --measurements is not given")
    p.add_argument("--measurements", metavar="M.csv", help="image measurements CSV (id,view,x,y)")
    p.add_argument("--view", help="view whose measurements to use (default: the only one)")
    p.add_argument("--focal-mm", type=float, required=True, help="focal length (mm)")
    p.add_argument("--pixel-um", type=float, required=True, help="pixel pitch (µm)")
    pp = p.add_mutually_exclusive_group(required=True)
    pp.add_argument("--principal-point", type=float, nargs=2, metavar=("CX", "CY"),
                    help="principal point (pixels, column row)")
    pp.add_argument("--image-size", type=int, nargs=2, metavar=("W", "H"),
                    help="image width and height: principal point at the centre")
    pp.add_argument("--image", help="the image: principal point at its centre")
    p.add_argument("--iterations", type=int, default=20, help="maximum Gauss–Newton iterations")
    p.add_argument("--use-icp", action="store_true", help="also use ICPs (default: GCPs only)")
    p.add_argument("--json", metavar="OUT", help="write EO, σ and history as JSON")
    p.set_defaults(func=run)


def _principal_point(args) -> tuple[float, float]:
    if args.principal_point:
        return tuple(args.principal_point)
    if args.image_size:
        w, h = args.image_size
        return w / 2.0, h / 2.0
    width, height, _ = raster_header(args.image, "image")
    return width / 2.0, height / 2.0


def run(args) -> int:
    pairs = read_point_pairs(args.points, args.measurements, args.view)
    res, use = resect_points(pairs, focal_mm=args.focal_mm, pixel_um=args.pixel_um,
                             principal_point=_principal_point(args), max_iterations=args.iterations,
                             use_icp=args.use_icp, source=args.points)
    d = res.as_dict()
    print(f"space resection of {int(use.sum())} points, view {pairs.view or '-'}: "
          f"{'converged' if res.converged else 'NOT converged'} after {len(res.corrections)} iterations, "
          f"σ0 = {res.sigma0_px:.3f} px")
    for k in PARAM_NAMES:
        if k in ("omega", "phi", "kappa"):
            print(f"  {k:<6}{d['eo'][k + '_deg']:>16.6f} °  ± {d['sigma'][k + '_deg']:.6f} °")
        else:
            print(f"  {k:<6}{d['eo'][k]:>16.3f} m  ± {d['sigma'][k]:.3f} m")
    print("corrections per iteration (m, m, m, °, °, °):")
    for i, c in enumerate(res.corrections, 1):
        print(f"  {i:>3}" + "".join(f"{v:>14.4g}" for v in c[:3])
              + "".join(f"{v:>14.4g}" for v in np.degrees(c[3:])))
    print(f"note: {res.note}")
    if args.json:
        d["ids"] = [i for i, u in zip(pairs.ids, use) if u]
        d["view"] = pairs.view
        write_json(args.json, d)
    return 0
