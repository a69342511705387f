"""Matches captured from the transfer benchmark's scenes (``*.npz`` beside this file): the N
template, the search window, the start and shape the transfer gave, the point's exact position,
refined again as the transfer refined them."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from prismstation.core.matching.lsm import refine


def refine_captured(name: str):
    """``(data, result)``: the capture ``name`` and :func:`~prismstation.core.matching.lsm.refine`
    of it (σ limit 0.5 px, the capture's shape allowance)."""
    f = np.load(Path(__file__).parent / name)
    x, y = f["point"]
    r = refine(f["reference"].astype(np.float64), float(x), float(y), f["search"].astype(np.float64), f["t0"],
               f["A0"], parallax=f["parallax"], half=int(f["half"]), max_sigma=0.5,
               max_shape_change=float(f["max_shape_change"]))
    return f, r
