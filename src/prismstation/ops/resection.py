"""Space resection of a frame image from ground points, and the base-to-height ratio of two
sensor positions (the ``resection`` and ``bh`` commands; docs/model.md §4).

Image coordinates ``(x, y)``: column, row in pixels; ground ``(E, N, H)`` metres.
"""
from __future__ import annotations

import numpy as np

from prismstation.core.models.resection import PARAM_NAMES, BaseHeight, FrameCamera, ResectionResult, base_height, resect
from prismstation.errors import InputError

__all__ = ["PARAM_NAMES", "BaseHeight", "ResectionResult", "base_height", "resect_points"]


def resect_points(pairs, *, focal_mm: float, pixel_um: float, principal_point: tuple[float, float],
                  max_iterations: int = 20, use_icp: bool = False, source=None) -> tuple[ResectionResult, np.ndarray]:
    """Resect the frame camera (``focal_mm``, ``pixel_um``, ``principal_point`` (cx, cy) in
    pixels) from the point pairs ``pairs`` (:class:`~prismstation.io.rectify_io.PointPairs`):
    the GCPs, and the ICPs too with ``use_icp``. Returns the result and the mask of the points
    used. Bad input (non-positive camera constants, a used point without height) raises
    :class:`InputError` (naming the file ``source``)."""
    if not (focal_mm > 0 and pixel_um > 0):
        raise InputError("--focal-mm and --pixel-um must be positive")
    if max_iterations < 1:
        raise InputError("--iterations must be at least 1")
    use = np.ones(len(pairs.ids), bool) if use_icp else ~pairs.is_check
    if np.any(np.isnan(pairs.h[use])):
        missing = [i for i, h, u in zip(pairs.ids, pairs.h, use) if u and np.isnan(h)]
        raise InputError(f"height H missing for point(s) {', '.join(missing[:5])}", file=source)
    cx, cy = principal_point
    cam = FrameCamera(focal_mm / 1000.0, pixel_um * 1e-6, cx, cy)
    xyz = np.column_stack([pairs.en[use], pairs.h[use]])
    return resect(cam, pairs.xy[use], xyz, max_iterations=max_iterations), use
