"""Sampling a grid at many scattered points."""
from __future__ import annotations

from prismstation.core.lazy_cv2 import cv2  # imported at first use: start-up saving
import numpy as np


def remap_points(src: np.ndarray, col, row, interpolation=None) -> np.ndarray:
    """``src`` sampled at continuous indices (``col``, ``row``; cell centres at integers) of
    any shape, through ``cv2.remap`` (1/32-pixel weights: fine for rendering and for heights of
    a reference DEM); the border is replicated. The points are laid out in rows of 4,096 and
    remapped 4,096 rows at a time (cv2 takes maps of fewer than 32,767 rows). ``interpolation``:
    an OpenCV flag, default ``cv2.INTER_LINEAR``."""
    if interpolation is None:
        interpolation = cv2.INTER_LINEAR
    shape = np.shape(col)
    col = np.asarray(col, dtype=np.float32).ravel()
    row = np.asarray(row, dtype=np.float32).ravel()
    n = col.size
    width = 4096
    m = -(-n // width) if n else 1
    pad = m * width - n
    mc = np.pad(col, (0, pad)).reshape(m, width)
    mr = np.pad(row, (0, pad)).reshape(m, width)
    out = np.empty((m, width), dtype=src.dtype)
    for r0 in range(0, m, 4096):   # cv2 wants < 32767 rows
        out[r0:r0 + 4096] = cv2.remap(src, mc[r0:r0 + 4096], mr[r0:r0 + 4096], interpolation,
                                      borderMode=cv2.BORDER_REPLICATE)
    return out.ravel()[:n].reshape(shape)
