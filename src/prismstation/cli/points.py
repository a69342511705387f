"""``prismstation points IN -o OUT [--to-crs CRS]``: convert ground-control files.

Formats: the ground-point CSV of docs/formats.md, QGIS ``.points``, OpenDroneMap ``gcp_list.txt``,
Ames Stereo Pipeline ``.gcp`` (see :mod:`prismstation.io.pointfiles`). The input format comes from
its extension and content, the output format from the output's extension (``.txt`` = ODM) or
``--to``.
"""
from __future__ import annotations

import sys
from dataclasses import replace

from prismstation.errors import InputError
from prismstation.io import pointfiles as pfm
from prismstation.io.atomic import write_atomic
from prismstation.io.points import measurements_csv


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "points", help="convert ground points between CSV, QGIS .points, ODM gcp_list.txt, ASP .gcp",
        description=__doc__.splitlines()[0])
    p.add_argument("input", metavar="IN", help="point file to read")
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="point file to write")
    p.add_argument("--to-crs", metavar="CRS", help="transform ground coordinates to this CRS "
                   "(EPSG:xxxx, proj4, WKT, 'WGS84 UTM 29N')")
    p.add_argument("--crs", metavar="CRS", help="coordinate system of IN when it states none "
                   "(ground-point CSV) or to override it")
    p.add_argument("--from", dest="fmt_in", choices=pfm.FORMATS, help="format of IN")
    p.add_argument("--to", dest="fmt_out", choices=pfm.FORMATS, help="format of OUT")
    p.add_argument("--height", choices=("ellipsoidal", "orthometric"), default="ellipsoidal",
                   help="height kind of points whose file does not say (default ellipsoidal)")
    p.add_argument("--view", help="image (view) to write to a QGIS .points file, which holds one")
    p.add_argument("--measurements", metavar="M.csv",
                   help="also write the image measurements as docs/formats.md measurement CSV")
    p.set_defaults(func=run)


def run(args) -> int:
    pf = pfm.read_point_file(args.input, args.fmt_in, height=args.height)
    for text in pf.warnings:
        print(f"warning: {text}", file=sys.stderr)
    if args.crs:
        pfm.parse_crs(args.crs)
        pf = replace(pf, crs=args.crs, header=None)
    if args.to_crs:
        pfm.parse_crs(args.to_crs)
        try:
            pf = pfm.convert_point_file(pf, args.to_crs)
        except InputError as exc:  # a point of IN that cannot be converted: name IN
            raise InputError(exc.problem, exc.file or args.input, exc.line) from None
    pfm.write_point_file(pf, args.output, args.fmt_out, view=args.view)
    if args.measurements:
        write_atomic(args.measurements, measurements_csv(pf.measurements), keep_backup=False)
    print(f"{len(pf.points)} points, {len(pf.measurements)} measurements -> {args.output}")
    if str(args.output).lower().endswith(".csv") and pf.crs:
        print(f"note: the CSV states no CRS; its E, N are in {pf.crs}")
    return 0
