"""Accuracy statistics: DSM minus reference, and image residuals per view (docs/model.md §5; Tadono et al. 2008).

DSM statistics are taken over the cells where both surfaces are finite (NaN marks no data).
Differences ``d = DSM − reference`` in metres; heights must be of one kind beforehand.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from prismstation.core.adjustment.stats import nmad
from prismstation.errors import ModelError

PERCENTILES = (5.0, 25.0, 50.0, 75.0, 95.0)
ABS_PERCENTILES = (68.3, 95.0)


@dataclass(frozen=True)
class DiffStats:
    """Statistics of a difference sample ``d`` (metres).

    ``bias`` = mean, ``sd`` = standard deviation with ``ddof=1`` (NaN for one value),
    ``rmse`` = sqrt(mean d²), ``nmad`` = 1.4826·median|d − median d|; ``percentiles`` of ``d``
    and ``abs_percentiles`` of ``|d|`` keyed by the percentage.
    """

    count: int
    bias: float
    sd: float
    rmse: float
    min: float
    max: float
    median: float
    nmad: float
    percentiles: dict = field(default_factory=dict)
    abs_percentiles: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        return {"count": self.count, "bias": self.bias, "sd": self.sd, "rmse": self.rmse,
                "min": self.min, "max": self.max, "median": self.median, "nmad": self.nmad,
                "percentiles": {_key(k): v for k, v in self.percentiles.items()},
                "abs_percentiles": {_key(k): v for k, v in self.abs_percentiles.items()}}


def _key(p: float) -> str:
    return f"p{p:g}"


def sample_stats(d, percentiles=PERCENTILES, abs_percentiles=ABS_PERCENTILES) -> DiffStats:
    """Statistics of the finite values of ``d`` (any shape). Empty → count 0, NaN elsewhere."""
    d = np.asarray(d, dtype=float).ravel()
    d = d[np.isfinite(d)]
    n = int(d.size)
    nan = float("nan")
    if n == 0:
        return DiffStats(0, nan, nan, nan, nan, nan, nan, nan,
                         {p: nan for p in percentiles}, {p: nan for p in abs_percentiles})
    med = float(np.median(d))
    return DiffStats(
        count=n,
        bias=float(d.mean()),
        sd=float(d.std(ddof=1)) if n > 1 else nan,
        rmse=float(np.sqrt(np.mean(d * d))),
        min=float(d.min()),
        max=float(d.max()),
        median=med,
        nmad=nmad(d),
        percentiles={p: float(v) for p, v in zip(percentiles, np.percentile(d, percentiles))},
        abs_percentiles={p: float(v) for p, v in
                         zip(abs_percentiles, np.percentile(np.abs(d), abs_percentiles))},
    )


@dataclass(frozen=True)
class DsmValidation:
    """DSM − reference statistics over all valid cells and, optionally, per mask class."""

    overall: DiffStats
    per_class: dict = field(default_factory=dict)   # class value (int) → DiffStats

    def as_dict(self) -> dict:
        out = self.overall.as_dict()
        if self.per_class:
            out["per_class"] = {str(k): v.as_dict() for k, v in sorted(self.per_class.items())}
        return out


def dsm_difference(dsm, reference) -> np.ndarray:
    """``dsm − reference`` (same-shape 2-D arrays, NaN = no data); NaN where either is invalid."""
    a = np.asarray(dsm, dtype=float)
    b = np.asarray(reference, dtype=float)
    if a.shape != b.shape:
        raise ModelError(f"DSM {a.shape} and reference {b.shape} are not on one grid")
    return a - b


def validate_dsm(dsm, reference, classes=None, class_nodata=None) -> DsmValidation:
    """Statistics of ``dsm − reference`` over the cells where both are finite.

    Parameters
    ----------
    dsm, reference : (rows, cols) heights in metres on one grid, NaN = no data.
    classes : optional (rows, cols) integer class mask; statistics per class value
        (cells equal to ``class_nodata`` are left out of the per-class figures).
    """
    d = dsm_difference(dsm, reference)
    overall = sample_stats(d)
    per = {}
    if classes is not None:
        c = np.asarray(classes)
        if c.shape != d.shape:
            raise ModelError(f"class mask {c.shape} is not on the DSM grid {d.shape}")
        ok = np.isfinite(d)
        if class_nodata is not None:
            ok &= c != class_nodata
        for value in np.unique(c[ok]):
            per[int(value)] = sample_stats(d[ok & (c == value)])
    return DsmValidation(overall, per)


@dataclass(frozen=True)
class ViewResidualSD:
    """One row of Tadono et al. (2008), Table 1: residual standard deviations in image space (pixels)."""

    view: str
    n_scenes: int
    n_points: int
    sd_x: float
    sd_y: float


def residual_sd_by_view(views, residuals, scenes=None) -> tuple[ViewResidualSD, ...]:
    """Standard deviation (``ddof=1``) of image residuals per view, x (column) and y (row).

    Parameters
    ----------
    views : (n,) view name of each residual (e.g. ``"N"``, ``"F"``, ``"B"``).
    residuals : (n, 2) image residuals in pixels.
    scenes : optional (n,) scene label of each residual, to count scenes per view.
    """
    views = np.asarray(views).astype(str)
    r = np.asarray(residuals, dtype=float)
    if r.ndim != 2 or r.shape[1] != 2 or len(r) != len(views):
        raise ModelError("residuals must be (n, 2) with one view name per row")
    sc = None if scenes is None else np.asarray(scenes).astype(str)
    out = []
    for v in dict.fromkeys(views):          # order of first appearance
        sel = (views == v) & np.all(np.isfinite(r), axis=1)
        rv = r[sel]
        n = len(rv)
        sd = rv.std(axis=0, ddof=1) if n > 1 else np.full(2, np.nan)
        n_sc = len(set(sc[sel])) if sc is not None else 1
        out.append(ViewResidualSD(str(v), n_sc, n, float(sd[0]), float(sd[1])))
    return tuple(out)


def histogram(d, bins: int = 50, clip_percent: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Histogram of the finite values of ``d`` for display: ``(counts (bins,), edges (bins+1,))``
    over the ``clip_percent`` … ``100 − clip_percent`` percentile range (outliers counted in
    the end bins)."""
    d = np.asarray(d, float).ravel()
    d = d[np.isfinite(d)]
    if d.size == 0:
        return np.zeros(bins, int), np.linspace(0.0, 1.0, bins + 1)
    lo, hi = np.percentile(d, [clip_percent, 100 - clip_percent])
    if hi <= lo:
        lo, hi = lo - 0.5, hi + 0.5
    counts, edges = np.histogram(np.clip(d, lo, hi), bins=bins, range=(lo, hi))
    return counts, edges


def hillshade(z, cellsize: float, azimuth_deg: float = 315.0, altitude_deg: float = 45.0) -> np.ndarray:
    """Shaded relief in [0, 1] of heights ``z`` (rows, cols; metres, NaN = no data) on square
    cells of ``cellsize`` metres, rows running south; light from ``azimuth_deg`` (clockwise
    from north) at ``altitude_deg`` above the horizon. NaN where ``z`` or a neighbour is NaN."""
    z = np.asarray(z, float)
    if z.ndim != 2 or min(z.shape) < 2 or not cellsize > 0:
        raise ModelError("hillshade needs a 2-D grid of at least 2 × 2 cells and a positive cell size")
    dz_dy_rows, dz_dx = np.gradient(z, cellsize)
    dz_dn = -dz_dy_rows                        # rows run south: northward slope is the negative
    az, alt = np.radians(azimuth_deg), np.radians(altitude_deg)
    lx, ly, lz = np.sin(az) * np.cos(alt), np.cos(az) * np.cos(alt), np.sin(alt)
    # unit normal of the surface (−∂z/∂E, −∂z/∂N, 1) / norm, dotted with the light direction
    shade = (-dz_dx * lx - dz_dn * ly + lz) / np.sqrt(1 + dz_dx ** 2 + dz_dn ** 2)
    return np.clip(shade, 0.0, 1.0)


#: the difference of two Laplacians (Immerkær 1996): nil on any surface linear in x or in y
#: (planes, quadratics), ``6σ`` of white noise of σ
_NOISE_MASK = np.array([[1.0, -2.0, 1.0], [-2.0, 4.0, -2.0], [1.0, -2.0, 1.0]])
#: the side (cells) of the windows the estimate reads on a larger grid: 4 × 4 of them spread
#: over it (the noise is the grid's everywhere; reading a 2²⁸-cell DSM whole would take seconds)
NOISE_WINDOW = 256


def white_noise_sigma(z) -> float:
    """σ of the white noise in a grid of heights ``z`` ``(rows, cols)`` (NaN: void), in the
    heights' units, cell by cell: ``√(π/2)/6 · mean|z ∗ M|`` (Immerkær's estimator, ``M`` the
    difference of two Laplacians) over the cells whose 3 × 3 neighbourhood is all heights and
    not all one (water, a constant fill) — on a grid over 4 :data:`NOISE_WINDOW` a side, in
    4 × 4 windows spread across it. Relief finer than three cells counts as noise (an upper
    bound on rough ground), and so does rounding to whole units (0.29); a flat plain rounded
    to whole units, its neighbourhoods mostly one height, reads high. NaN when fewer than 100
    cells qualify."""
    z = np.asarray(z, float)
    rows = _windows(z.shape[0])
    cols = _windows(z.shape[1])
    with np.errstate(over="ignore", invalid="ignore"):       # heights near the float limit: left out
        r = np.concatenate([_laplacians(z[a:b, c:d]).ravel() for a, b in rows for c, d in cols])
    r = r[np.isfinite(r)]
    if r.size < 100:
        return float("nan")
    return float(np.sqrt(np.pi / 2.0) / 6.0 * np.mean(np.abs(r)))


def _windows(n: int) -> list[tuple[int, int]]:
    """``(start, stop)`` of the windows along an axis of ``n`` cells: all of it, or 4 of
    :data:`NOISE_WINDOW` spread evenly."""
    if n <= 4 * NOISE_WINDOW:
        return [(0, n)]
    return [(int(a), int(a) + NOISE_WINDOW) for a in np.linspace(0, n - NOISE_WINDOW, 4)]


def _laplacians(z) -> np.ndarray:
    """``z ∗ M`` on the interior cells of ``z``: NaN where a neighbour is a void or where all
    nine are one height."""
    if min(z.shape) < 3:
        return np.empty(0)
    shifted = [z[i:z.shape[0] - 2 + i, j:z.shape[1] - 2 + j] for i in range(3) for j in range(3)]
    r = sum(m * a for m, a in zip(_NOISE_MASK.ravel(), shifted))
    flat = np.max(shifted, axis=0) == np.min(shifted, axis=0)
    return np.where(flat, np.nan, r)
