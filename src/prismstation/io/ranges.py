"""The range every number read must fall in: beyond it a value is a typo, a unit mix-up or a
hostile file, never a measurement, and is refused where it is read (one line naming the file,
the line and the value) rather than carried into a fit that ends in ``1e307`` residuals.

The bounds are wide on purpose — they say what is possible on Earth and in an image, not
what is usual for PRISM: map coordinates of a projected CRS in metres (the Earth is 4·10⁷ m
round), heights from below the Dead Sea to above Everest with margin, image coordinates of an
image of up to ten million pixels a side (within the image, one image size of margin, when the
image's size is known), standard deviations up to a kilometre or a thousand pixels.
"""
from __future__ import annotations

import math

#: |E|, |N| of a projected CRS, metres
MAP_M = 1e8
#: heights (orthometric or ellipsoidal), metres
HEIGHT_M = (-1000.0, 10000.0)
#: |x|, |y| in an image whose size is not known, pixels
IMAGE_PX = 1e7
#: a ground sample distance, metres
PIXEL_SIZE_M = (1e-3, 1000.0)
#: a satellite's altitude above the ground, metres (a low orbit to beyond geostationary)
ALTITUDE_M = (1e5, 5e7)
#: a geoid undulation, metres (the Earth's: −107 to +86)
UNDULATION_M = (-150.0, 150.0)
#: σ of a ground coordinate or height, metres; σ of an image measurement, pixels
SIGMA_M, SIGMA_PX = 1000.0, 1000.0


def _fmt(v) -> str:
    return f"{v:g}" if isinstance(v, (int, float)) else repr(v)


def within(value: float, lo: float, hi: float) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(value) and lo <= value <= hi


def check_map(E, N, H=None) -> str | None:
    """Why ``(E, N, H)`` (NaN: absent) cannot be a ground point, or None."""
    for name, v in (("E", E), ("N", N)):
        if not math.isnan(v) and not within(v, -MAP_M, MAP_M):
            return f"{name} = {_fmt(v)} is not a map coordinate (|{name}| ≤ {MAP_M:g} m)"
    if H is not None and not math.isnan(H) and not within(H, *HEIGHT_M):
        return f"H = {_fmt(H)} m is not a height on Earth ({HEIGHT_M[0]:g} to {HEIGHT_M[1]:g} m)"
    return None


def check_image(x, y, shape=None) -> str | None:
    """Why ``(x, y)`` cannot be a measurement in an image of ``shape`` (rows, columns; None:
    not known), or None: within the image and one image size around it."""
    if shape is None:
        for name, v in (("x", x), ("y", y)):
            if not within(v, -IMAGE_PX, IMAGE_PX):
                return f"{name} = {_fmt(v)} is not an image coordinate (|{name}| ≤ {IMAGE_PX:g} px)"
        return None
    h, w = shape
    if not (within(x, -w, 2 * w) and within(y, -h, 2 * h)):
        return f"({_fmt(x)}, {_fmt(y)}) is far outside the image ({w} × {h} px)"
    return None


def check_sigma(name: str, v, limit: float, unit: str) -> str | None:
    """Why ``v`` (None: absent) cannot be the σ ``name``, or None."""
    if v is None:
        return None
    if not within(v, 0.0, limit):
        return f"{name} = {_fmt(v)} is not a standard deviation (0 to {limit:g} {unit})"
    return None


def outside_images(scene, points, measurements) -> tuple[str, str] | None:
    """The first ``(id, why)`` among ``measurements`` far outside its view's image, or among
    the measured ``points`` with ground coordinates far from every view's footprint (farther
    than the footprint's own diagonal), else None. ``points``: id → GroundPoint."""
    for m in measurements:
        view = scene.views.get(m.view)
        why = check_image(m.x, m.y, getattr(view, "shape", None))
        if why:
            return m.id, f"view {m.view}: {why}"
    import numpy as np
    boxes = []
    for view in scene.views.values():
        try:
            fp = np.asarray(view.footprint(), float)
        except Exception:  # a view that cannot be placed: no test against it
            continue
        if np.all(np.isfinite(fp)):
            lo, hi = fp.min(0), fp.max(0)
            pad = float(np.hypot(*(hi - lo)))
            boxes.append((lo - pad, hi + pad))
    if not boxes:
        return None
    measured = {m.id for m in measurements}
    for pid in measured:
        p = points.get(pid)
        if p is None or not (math.isfinite(p.E) and math.isfinite(p.N)):
            continue
        if not any(lo[0] <= p.E <= hi[0] and lo[1] <= p.N <= hi[1] for lo, hi in boxes):
            return pid, (f"(E, N) = ({p.E:.1f}, {p.N:.1f}) is far from every image of the scene "
                         "(a coordinate typed wrong, or a point of another scene or CRS?)")
    return None
