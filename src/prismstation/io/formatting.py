"""Numbers as text, the one way every report, command and window part writes them
(:func:`fixed`; JSON values are made safe by :func:`prismstation.io.jsonfile.plain`)."""
from __future__ import annotations

import math

#: what a number that is not there (None, NaN, ±inf) is written as
DASH = "—"


def fixed(v, nd: int = 2, sign: bool = False) -> str:
    """``v`` with ``nd`` decimals (``sign``: always with its sign); :data:`DASH` for None and
    non-finite floats; ints and bools as they are."""
    if v is None or isinstance(v, bool) or isinstance(v, int):
        return DASH if v is None else str(v)
    if not math.isfinite(v):
        return DASH
    return f"{v:+.{nd}f}" if sign else f"{v:.{nd}f}"
