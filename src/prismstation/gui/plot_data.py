"""What the live plots draw, as flat arrays, from a Solution or from a report dict (no Qt).

Conventions: parallax ``py`` in pixels (F−B, along track in N space), heights ellipsoidal metres,
image positions ``(x column, y row)`` pixels, residuals measured − predicted pixels.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from prismstation.core.models.scene import reference_view
from prismstation.gui.sensors import parts_of


def _arr(values) -> np.ndarray:
    return np.asarray(values, dtype=float).reshape(-1)


def _xy(values) -> np.ndarray:
    return np.asarray(values, dtype=float).reshape(-1, 2)


def vector_view(bias: dict, asked: str | None = None) -> str:
    """The view whose residual vectors are drawn: ``asked`` when the fit has it, else the
    reference view, unless that is held fixed (the datum of a fit without GCPs, as the first
    of several images with RPCs): then the first view that is fitted. ``bias``: view → its fit
    (an object with ``fixed``, or a report's dict with ``"fixed"``)."""
    if asked in bias:
        return asked

    def fixed(v) -> bool:
        b = bias[v]
        return bool(b.get("fixed") if isinstance(b, dict) else getattr(b, "fixed", False))
    ref = reference_view(bias)
    if ref in bias and not fixed(ref):
        return ref
    return next((v for v in bias if not fixed(v)), ref)


@dataclass(frozen=True)
class PlotData:
    """Everything the four plots draw, as flat arrays.

    Attributes
    ----------
    gcp_py, gcp_h, icp_py, icp_h : (n,) arrays
        F−B parallax (pixels) and known ellipsoidal height (metres) of GCPs / ICPs that have both.
    gcp_ids, icp_ids : tuples of str, the ids of those points (same order).
    c0, c1, c1_theory : float or None
        Parallax line ``h = c0 + c1·py`` (metres, pixels); ``c1_theory`` of eq. 4.
    view : str, the view of the residual vectors (:func:`vector_view`: the reference view, N
        for a triplet, unless it is held fixed; or the one asked for).
    vec_gcp_xy, vec_gcp_v, vec_icp_xy, vec_icp_v : (n, 2) arrays
        Measured image position (x column, y row, pixels) and residual (measured − predicted).
    vec_tie_xy, vec_tie_v, vec_tie_ids : the same for tie points, where the model fits them
        (``ties``: a model whose points are intersected from rays, the RPC model).
    std_ids : tuple of str, the fitted points with a standardised residual (GCPs; and tie
        points with ``ties``); ``std_values`` (n,) their values (on the normal scale: one
        threshold for every fit, :mod:`prismstation.gui.fit_checks`).
    blunders : tuple of str, the ids of the flagged points. ``threshold``: the blunder threshold.
    image_shape : (rows, cols) of the view, or None.
    """

    gcp_py: np.ndarray = field(default_factory=lambda: np.zeros(0))
    gcp_h: np.ndarray = field(default_factory=lambda: np.zeros(0))
    icp_py: np.ndarray = field(default_factory=lambda: np.zeros(0))
    icp_h: np.ndarray = field(default_factory=lambda: np.zeros(0))
    gcp_ids: tuple = ()
    icp_ids: tuple = ()
    c0: float | None = None
    c1: float | None = None
    c1_theory: float | None = None
    view: str = "N"
    vec_gcp_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    vec_gcp_v: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    vec_icp_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    vec_icp_v: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    vec_gcp_ids: tuple = ()
    vec_icp_ids: tuple = ()
    std_ids: tuple = ()
    std_values: np.ndarray = field(default_factory=lambda: np.zeros(0))
    blunders: tuple = ()
    threshold: float = 3.29
    image_shape: tuple | None = None
    vec_tie_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    vec_tie_v: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    vec_tie_ids: tuple = ()
    ties: bool = False

    @classmethod
    def from_columns(cls, ids, kinds, py, h, xy, v, std, blunder, *, parallax=None, view="N",
                     threshold=3.29, image_shape=None, ties: bool = False) -> "PlotData":
        """From arrays over ``n`` points, NaN where a point has no value: ``ids``, ``kinds``
        (n,), parallax ``py`` (n,) px, known height ``h`` (n,) m, measured position ``xy`` and
        residual ``v`` (n, 2) px in ``view``, standardised residual ``std`` (n,), ``blunder``
        (n,) bool. ``ties``: tie points are fitted points (their vectors and standardised
        residuals are drawn); ``parallax``: ``(c0, c1, c1_theory)`` or None."""
        ids = np.asarray(ids, dtype=object).reshape(-1)
        kinds = np.asarray(kinds, dtype=object).reshape(-1)
        py, h, std = _arr(py), _arr(h), _arr(std)
        xy, v = _xy(xy), _xy(v)
        fitted = (kinds == "GCP") | ((kinds == "TIE") & ties)
        drawn = (kinds == "GCP") | (kinds == "ICP") | fitted  # a tie point: where it is fitted
        has_h = np.isfinite(py) & np.isfinite(h)
        has_v = np.isfinite(xy).all(axis=1) & np.isfinite(v).all(axis=1)
        has_s = fitted & np.isfinite(std)
        sel = {k: kinds == k for k in ("GCP", "ICP", "TIE")}
        hg, hi = sel["GCP"] & has_h, sel["ICP"] & has_h
        vg, vi, vt = (sel[k] & has_v & drawn for k in ("GCP", "ICP", "TIE"))
        c0, c1, c1t = (None, None, None) if parallax is None else parallax
        return cls(py[hg], h[hg], py[hi], h[hi], tuple(ids[hg]), tuple(ids[hi]), c0, c1, c1t, view,
                   xy[vg], v[vg], xy[vi], v[vi], tuple(ids[vg]), tuple(ids[vi]), tuple(ids[has_s]),
                   std[has_s], tuple(ids[np.asarray(blunder, bool).reshape(-1) & drawn]), float(threshold),
                   image_shape, xy[vt], v[vt], tuple(ids[vt]), bool(ties))

    @classmethod
    def from_solution(cls, sol, view: str | None = None) -> "PlotData":
        """From a :class:`~prismstation.core.models.solution.Solution` (``None`` gives empty plots); the
        residual vectors of ``view`` (default: :func:`vector_view`)."""
        if sol is None:
            return cls()
        view, c = vector_view(sol.bias, view), sol.columns
        nan2 = np.full((len(c), 2), np.nan)
        line = parts_of(sol.scene.sensor).plot_line(sol)
        v = sol.scene.views[view]
        return cls.from_columns(c.ids, c.kinds, c.parallax, c.ground_est[:, 2] - c.ground_residual[:, 2],
                                c.measured.get(view, nan2), c.residual.get(view, nan2), c.std_residual,
                                c.blunder, parallax=line, view=view, threshold=sol.settings.blunder_threshold,
                                image_shape=getattr(v, "shape", None),
                                ties=sol.scene.sensor.height_source != "parallax")

    @classmethod
    def from_report(cls, report: dict) -> "PlotData":
        """From the dict of :func:`prismstation.io.report.report_dict` (or its JSON)."""
        bias = report.get("model", {}).get("bias", {})
        view = vector_view(bias)
        pts = report.get("points", [])
        nan = float("nan")

        def num(v):
            return nan if v is None else v

        def pair(p, key):
            xy = (p.get(key) or {}).get(view)
            return (nan, nan) if xy is None else xy
        h = [nan if p.get("h_est") is None or p.get("dh") is None else p["h_est"] - p["dh"] for p in pts]
        par = report.get("model", {}).get("parallax")
        line = None if not par else (par.get("c0"), par.get("c1"), par.get("c1_theoretical"))
        thr = (report.get("settings") or {}).get("blunder_threshold", 3.29)
        ties = report.get("model", {}).get("height_source", "parallax") != "parallax"
        return cls.from_columns([p["id"] for p in pts], [p["kind"] for p in pts],
                                [num(p.get("parallax_px")) for p in pts], h,
                                [pair(p, "measured") for p in pts], [pair(p, "residual_px") for p in pts],
                                [num(p.get("std_residual")) for p in pts],
                                [bool(p.get("blunder")) for p in pts], parallax=line, view=view,
                                threshold=thr, ties=ties)


def auto_exaggeration(data: PlotData) -> float:
    """A 1-2-5 factor that draws the median residual vector ~4 % of the image (or points')
    extent, the longest at most ~35 %."""
    v = np.vstack([data.vec_gcp_v, data.vec_icp_v, data.vec_tie_v])
    xy = np.vstack([data.vec_gcp_xy, data.vec_icp_xy, data.vec_tie_xy])
    if len(v) == 0:
        return 100.0
    length = np.hypot(v[:, 0], v[:, 1])
    longest, median = float(np.nanmax(length)), float(np.nanmedian(length))
    extent = float(np.nanmax(np.ptp(xy, axis=0))) if len(xy) > 1 else 1000.0
    if data.image_shape:
        extent = max(extent, float(max(data.image_shape)))
    if not np.isfinite(longest) or longest <= 0:
        return 100.0
    raw = min(0.04 * extent / max(median, 1e-9), 0.35 * extent / longest)
    exp = np.floor(np.log10(raw))
    mant = raw / 10 ** exp
    step = 1 if mant < 2 else 2 if mant < 5 else 5
    return float(step * 10 ** exp)


def segments(xy: np.ndarray, v: np.ndarray, k: float) -> tuple[np.ndarray, np.ndarray]:
    """x, y arrays ``(2n,)`` of ``[start, start + k·v]`` pairs (for ``connect='pairs'``)."""
    seg = np.empty((2 * len(xy), 2))
    seg[0::2] = xy
    seg[1::2] = xy + k * v
    return seg[:, 0], seg[:, 1]


def line_x(data: PlotData) -> np.ndarray:
    """``[x0, x1]`` parallax span for the lines: the data ±5 %, from 0 when all are positive."""
    py = np.concatenate([data.gcp_py, data.icp_py])
    if py.size == 0:
        return np.zeros(0)
    lo, hi = float(py.min()), float(py.max())
    pad = 0.05 * max(hi - lo, 1.0)
    return np.array([min(lo - pad, 0.0) if lo >= 0 else lo - pad, hi + pad])


def data_ranges(d: PlotData, vector_segments=(), std_range=((0, 1), (0, 4))) -> dict:
    """``{plot: ((x0, x1), (y0, y1))}`` framing what each plot draws of ``d`` (plots with data
    only): the points and lines of the height plots (5 % margin), the image of the vectors
    (or the points and ``vector_segments``, ``(n, 2)`` arrays, when its shape is unknown) and
    ``std_range`` for the standardised residuals."""
    out = {}
    x = line_x(d)
    if x.size:
        ys, ys5 = [d.gcp_h, d.icp_h], [np.zeros(1)]
        if d.c0 is not None and d.c1 is not None:
            ys.append(d.c0 + d.c1 * x)
            if d.c1_theory is not None:
                ys5.append(d.c0 + (d.c1 - d.c1_theory) * x)
        if d.c1_theory is not None:
            ys.append(d.c1_theory * x)
            ys5 += [d.gcp_h - d.c1_theory * d.gcp_py, d.icp_h - d.c1_theory * d.icp_py]
        for name, acc in (("height", ys), ("height_minus_theory", ys5)):
            y = np.concatenate(acc)
            y = y[np.isfinite(y)]
            if y.size:
                pad = 0.05 * max(np.ptp(y), 1.0)
                out[name] = ((x[0], x[1]), (y.min() - pad, y.max() + pad))
    if d.image_shape:
        r, c = d.image_shape[:2]
        out["vectors"] = ((-0.03 * c, 1.03 * c), (-0.03 * r, 1.03 * r))
    else:
        pts = [a for a in (d.vec_gcp_xy, d.vec_icp_xy, d.vec_tie_xy, *vector_segments) if len(a)]
        if pts:
            a = np.vstack(pts)
            lo, hi = a.min(axis=0), a.max(axis=0)
            pad = 0.05 * max(float(np.max(hi - lo)), 1.0)
            out["vectors"] = ((lo[0] - pad, hi[0] + pad), (lo[1] - pad, hi[1] + pad))
    out["std_residuals"] = std_range
    return out


def blunder_text(ids: list[str], most: int = 3) -> str:
    """The flagged ids for the plot's label: the first ``most`` and how many more (the summary
    line under the plots names them all)."""
    return ", ".join(ids[:most]) + (f" +{len(ids) - most}" if len(ids) > most else "")
