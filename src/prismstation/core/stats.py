"""Residual statistics per component (MODEL.md §2, the paper's Tables 1–3)."""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np


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
