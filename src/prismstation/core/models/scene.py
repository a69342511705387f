"""A product as the model sees it: its views (for the PRISM model each with its ancillary
affine, beside the ground track and the satellite altitude) and the sensor model they follow."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from prismstation.core.adjustment.affine import Affine2D

#: sign of the along-track relief shift of each view: forward ahead, backward behind (docs/model.md §2)
LOOK_SIGN = {"F": 1.0, "B": -1.0}


def reference_view(names, default: str = "N") -> str:
    """The reference view among ``names`` (view names, or a dict keyed by them): N when
    present, else the first; ``default`` when there is none."""
    names = list(names)
    return "N" if "N" in names else (names[0] if names else default)


@dataclass(frozen=True, eq=False)
class GroundTrack:
    """Sub-satellite points ``(K, 2)`` in map metres, in flight order (K ≥ 2).

    The first and last segments are extended indefinitely, so every map point has a foot.
    """

    points: np.ndarray

    def __post_init__(self):
        p = np.asarray(self.points, dtype=float)
        p.setflags(write=False)
        object.__setattr__(self, "points", p)

    @cached_property
    def _segments(self) -> tuple[np.ndarray, ...]:
        """What :meth:`foot` needs of the track alone: segment starts ``a`` and vectors ``d``,
        squared lengths, unit directions, and the bounds of the position along a segment
        (the first and last segments extended)."""
        a = self.points[:-1]
        d = self.points[1:] - a
        L2 = np.einsum("ij,ij->i", d, d)
        lo = np.zeros(len(d)); hi = np.ones(len(d))
        lo[0], hi[-1] = -np.inf, np.inf
        return a, d, L2, d / np.sqrt(L2)[:, None], lo, hi

    def foot(self, en) -> tuple[np.ndarray, np.ndarray]:
        """Nearest track point and unit flight direction for map points ``en`` ``(..., 2)``.

        Returns ``(foot, t)``, both ``(..., 2)``.
        """
        en = np.asarray(en, dtype=float)
        q = en.reshape(-1, 2)
        a, d, L2, unit, lo, hi = self._segments
        s = np.einsum("nij,ij->ni", q[:, None, :] - a[None], d) / L2  # (n, K-1)
        if len(d) == 1:  # one segment, extended both ways: the foot is on its line
            f, t = a[0] + s * d[0], np.repeat(unit, len(q), axis=0)
        else:
            s = np.clip(s, lo, hi)
            feet = a[None] + s[..., None] * d[None]
            k = np.argmin(np.einsum("nik,nik->ni", q[:, None] - feet, q[:, None] - feet), axis=1)
            f, t = feet[np.arange(len(q)), k], unit[k]
        return f.reshape(en.shape), t.reshape(en.shape)

    def mean_direction(self) -> np.ndarray:
        d = self.points[-1] - self.points[0]
        return d / np.hypot(*d)


@dataclass(frozen=True, eq=False)
class View:
    """One image of the product.

    ``map_to_image`` maps map metres ``(E, N)`` at the ellipsoid to image pixels (eq. 1).
    ``along_track_angle_deg`` is the viewing angle at the ground, positive for F and B.
    """

    name: str
    map_to_image: Affine2D
    pixel_size_m: float
    along_track_angle_deg: float = 0.0
    image: str | None = None
    shape: tuple[int, int] | None = None  # (rows, cols)

    @property
    def look_sign(self) -> float:
        return LOOK_SIGN.get(self.name, 0.0)

    @property
    def tan_theta(self) -> float:
        return math.tan(math.radians(self.along_track_angle_deg))

    def footprint(self) -> np.ndarray:
        """Map ``(E, N)`` ``(4, 2)`` of the image corners at the ellipsoid, relief ignored (an
        unknown shape counts as 20,000 px square)."""
        rows, cols = self.shape if self.shape else (20000, 20000)
        px = np.array([[0, 0], [cols, 0], [0, rows], [cols, rows]], float)
        return self.map_to_image.inverse()(px)


@dataclass(frozen=True, eq=False)
class Scene:
    """A product: ``views`` (name → view, of one sensor model), the map ``crs`` (a string for
    pyproj, projected, metres) and, for the PRISM model, the ``track`` and the
    ``satellite_altitude_m`` (None for a model that needs neither). ``sensor`` is the class of
    the views' sensor model (:mod:`prismstation.core.models.sensor`; the reader of the scene file
    chooses it, :mod:`prismstation.core.models.sensors`)."""

    crs: str
    satellite_altitude_m: float | None
    track: GroundTrack | None
    views: dict
    geoid_undulation_m: float | None = None
    extra: dict = field(default_factory=dict)
    sensor: type | None = None

    def __post_init__(self):
        if self.sensor is None:
            raise TypeError("a Scene needs its sensor model (core/models/sensors.py: MODELS)")

    @property
    def reference_view(self) -> str:
        """N when the scene has it, else its first view (:func:`reference_view`)."""
        return reference_view(self.views)

    @property
    def is_triplet(self) -> bool:
        """A PRISM N, F, B triplet (views of that name along a ground track)."""
        return self.track is not None and all(v in self.views for v in "NFB")
