"""``prismstation bh --left X Y Z --right X Y Z [--json OUT]``: base, height and B/H.

``B = |XR − XL|`` (3-D), ``H = (ZL + ZR) / 2`` (Subaryono et al.). A position may also be taken from
the JSON a ``prismstation resection --json`` wrote (``--left-resection`` / ``--right-resection``).
"""
from __future__ import annotations

import math

from prismstation.errors import InputError
from prismstation.io.jsonfile import line_of, read_json, write_json
from prismstation.io.ranges import MAP_M
from prismstation.ops.resection import base_height


def register(sub) -> None:
    p = sub.add_parser("bh", help="base, height and B/H ratio of two sensor positions")
    left = p.add_mutually_exclusive_group(required=True)
    left.add_argument("--left", type=float, nargs=3, metavar=("X", "Y", "Z"))
    left.add_argument("--left-resection", metavar="JSON", help="output of resection --json")
    right = p.add_mutually_exclusive_group(required=True)
    right.add_argument("--right", type=float, nargs=3, metavar=("X", "Y", "Z"))
    right.add_argument("--right-resection", metavar="JSON", help="output of resection --json")
    p.add_argument("--json", metavar="OUT", help="write base_m, height_m, b_over_h")
    p.set_defaults(func=run)


def _from_resection(path) -> list[float]:
    data, text = read_json(path)
    eo = data.get("eo")
    if not isinstance(eo, dict):
        raise InputError("no \"eo\" object (expected the output of resection --json)", file=path)
    try:
        return [float(eo[k]) for k in ("X0", "Y0", "Z0")]
    except (KeyError, TypeError, ValueError):
        raise InputError("\"eo\" lacks numeric X0, Y0, Z0", file=path, line=line_of(text, "eo")) from None


def run(args) -> int:
    left = args.left or _from_resection(args.left_resection)
    right = args.right or _from_resection(args.right_resection)
    for side, xyz in (("left", left), ("right", right)):
        if not all(math.isfinite(v) and abs(v) <= MAP_M for v in xyz):
            raise InputError(f"--{side} {' '.join(f'{v:g}' for v in xyz)}: a camera position needs three "
                             f"finite coordinates within ±{MAP_M:g} m")
    bh = base_height(left, right)
    print(f"B   = {bh.base_m:.1f} m")
    print(f"H   = {bh.height_m:.2f} m")
    print(f"B/H = {bh.b_over_h:.6f}")
    if args.json:
        write_json(args.json, {"base_m": bh.base_m, "height_m": bh.height_m,
                               "b_over_h": bh.b_over_h, "left": list(left), "right": list(right)})
    return 0
