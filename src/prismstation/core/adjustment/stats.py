"""Residual statistics per component (docs/model.md §2, the paper's Tables 1–3), and the one
NMAD (:func:`nmad`)."""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass

import numpy as np


#: NMAD = this × the median absolute deviation: σ of a normal distribution
NMAD_FACTOR = 1.4826


def nmad(values) -> float:
    """Normalised median absolute deviation ``1.4826·median|v − median v|`` of the finite
    ``values`` (any shape): a σ that outliers barely move (NaN when none is finite)."""
    v = np.asarray(values)        # no cast: float32 stays float32 (the same numbers as before)
    finite = np.isfinite(v)
    if not finite.all():          # no copy of an all-finite array (a DSM's 12 million cells: 96 MB)
        v = v[finite]
    if v.size == 0:
        return float("nan")
    return float(NMAD_FACTOR * np.median(np.abs(v - np.median(v))))


@dataclass(frozen=True)
class ComponentStats:
    """Statistics of one residual component over ``n`` points (NaN when ``n == 0``)."""

    n: int
    min: float
    max: float
    mean: float
    rms: float
    std: float

    @classmethod
    def of(cls, values) -> "ComponentStats":
        v = np.asarray(values, dtype=float)
        v = v[np.isfinite(v)]
        n = int(v.size)
        if n == 0:
            return cls(0, *(float("nan"),) * 5)
        # mean, std (ddof=1) and rms written out as numpy computes them: the same numbers
        # without the overhead of np.mean / np.std, which dominates for a few hundred values
        mean = float(v.sum()) / n
        d = v - mean
        std = math.sqrt(float((d * d).sum()) / (n - 1)) if n > 1 else float("nan")
        rms = math.sqrt(float((v * v).sum()) / n)
        return cls(n, float(v.min()), float(v.max()), mean, rms, std)

    def scaled(self, k: float) -> "ComponentStats":
        return ComponentStats(self.n, self.min * k, self.max * k, self.mean * k, self.rms * k, self.std * k)

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class VectorStats:
    """Statistics of 2-D residuals ``(n, 2)``: per component and planimetric RMS."""

    x: ComponentStats
    y: ComponentStats

    @classmethod
    def of(cls, xy) -> "VectorStats":
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        x, y = xy[:, 0], xy[:, 1]
        ok = np.isfinite(x) & np.isfinite(y)  # (np.all(..., axis=1) is slow on short rows)
        return cls(ComponentStats.of(x[ok]), ComponentStats.of(y[ok]))

    @property
    def n(self) -> int:
        return self.x.n

    @property
    def planimetric_rms(self) -> float:
        return float(np.hypot(self.x.rms, self.y.rms))

    def scaled(self, k: float) -> "VectorStats":
        return VectorStats(self.x.scaled(k), self.y.scaled(k))

    def to_dict(self) -> dict:
        return {"x": self.x.to_dict(), "y": self.y.to_dict(), "planimetric_rms": self.planimetric_rms}


@dataclass(frozen=True)
class ImageStats:
    """Image residuals of one view and one point kind, in pixels and in metres on the ground."""

    px: VectorStats
    m: VectorStats

    def __getitem__(self, unit: str) -> VectorStats:  # ``["px"]`` / ``["m"]`` as before
        return getattr(self, unit)

    def to_dict(self) -> dict:
        return {"px": self.px.to_dict(), "m": self.m.to_dict()}


@dataclass(frozen=True)
class FitStatistics(Mapping):
    """Tables 1–3 of the paper and their extensions (docs/model.md §2), per point kind
    (``"GCP"``, ``"ICP"``).

    ``image[view][kind]`` image residuals, ``ground[kind]`` planimetric ground residuals
    (estimated − known, metres), ``height[kind]`` height residuals of points with a
    parallax height (metres), ``across[view]`` across-track differences of F and B to N
    (pixels; triplets only). Also read as the mapping it replaces: keys ``image``,
    ``ground``, ``height``, ``F-N``, ``B-N`` (triplets) and ``reference_view``.
    """

    image: dict
    ground: dict
    height: dict
    across: dict
    reference_view: str

    def _items(self) -> dict:
        d = {"image": self.image, "ground": self.ground, "height": self.height}
        d.update({f"{v}-N": s for v, s in self.across.items()})
        d["reference_view"] = self.reference_view
        return d

    def __getitem__(self, key: str):
        return self._items()[key]

    def __iter__(self):
        return iter(self._items())

    def __len__(self) -> int:
        return len(self._items())
