"""A point-sampled template's statistics (:func:`template_stats`: its noise, where its edges
lie between samples, its pixels' weights) and its last fit, on both images low-passed
(:func:`smoothed_shift`): the sub-pixel pull of two views' pixel grids taken out of a
least-squares match (:mod:`prismstation.core.matching.lsm`; docs/matching.md, the pull of two
pixel grids).

Coordinates as there (docs/model.md §1): image ``x`` = column, ``y`` = row, pixels.
"""
from __future__ import annotations

import threading
from collections import OrderedDict

import numpy as np

from prismstation.core.matching.lsm_fit import OK, Fit, template
from prismstation.core.matching.lsm_sigma import noise_sigma, sampling_px
from prismstation.core.matching.lsm_spline import low_pass, search_spline

POINT_SAMPLED = 0.03
"""The template's gradient-weighted mean σ (px) of where its edges lie between their samples
(:func:`edge_sigma`) above which its images are taken as point-sampled: 0.003–0.027 px on the
simulator's blurred views (medians and 90 % points), 0.04–0.25 px (10 % points and medians) on
its point-sampled ones and on another renderer's."""
MAX_PULL = 1.0
"""The farthest (px) the low-passed fit may move: each view's samples place an edge within half
a pixel of where it is, so the two views misplace it by a pixel at most; a fit that moves
farther has left for another minimum, and its shift is not taken (on the tuning scenes the
largest taken was 0.82 px)."""
PULL_SHARE = 0.5
"""σ of the low-passed fit's shift (:func:`smoothed_shift`) as a share of the shift, in its
direction: the shift takes most of the pull out but not all, and a large one holds more than the
pull (on the tuning scenes, with it taken, the error across the parallax was 0.4–0.8 of shifts
over 0.15 px, at z 1.3–2.4 without this term)."""
SAMPLED_SMOOTH = 0.6
"""σ (px) of the Gaussian low-pass of both images in a point-sampled template's last fit
(:func:`smoothed_shift`): from about 0.55 px of blur on, the spline places an edge between
its samples where they put it (the table behind
:func:`~prismstation.core.matching.lsm_sigma.sampling_px`)."""


def edge_sigma(gx, gy, aliasing) -> float:
    """The mean, weighted by a template's squared gradients ``gx``, ``gy`` (``(n, n)``, grey
    values per px), of the σ (px) ``aliasing`` (``(ex, ey)``,
    :func:`~prismstation.core.matching.lsm_sigma.sampling_px`) gives its pixels along x and y."""
    energy = float((gx * gx + gy * gy).sum())
    return float((gx * gx * aliasing[0] + gy * gy * aliasing[1]).sum()) / energy if energy > 0 else 0.0


def smoothed_shift(reference, x: float, y: float, search, fit: Fit, bend: bool, run_args):
    """``(shift (2,) px, iterations)``: how far ``fit`` (converged on the point-sampled images)
    moves when both images are low-passed by a Gaussian of :data:`SAMPLED_SMOOTH` px and it is
    fitted again from its end (the same parameters, pixel weights and pixels: the whole template
    or a weighted part of it, as ``lsm._refit`` made it); zero where that fit fails or moves
    farther than :data:`MAX_PULL`.
    ``run_args``: ``(max_iter, t0, max_move, A0inv, max_shape_change)`` of
    :meth:`~prismstation.core.matching.lsm_fit.Fit.run`.

    Sampled without blur, an edge lies anywhere between two samples, and the spline between
    them is not the edge: a patch matched on such samples is drawn by a sub-pixel amount that
    depends on where the two views' pixel grids fall on each other (the fraction of the shift
    between them). Across the parallax, where the views' grids run parallel at the same spacing,
    that fraction is the same over the whole template and the error does not average out: on
    point-sampled scenes of two simulators it followed ``0.10–0.14·sin(2π·fraction)`` px. The
    low-pass makes the spline a faithful interpolant of what the samples show, and each edge
    then counts by its samples' own place."""
    m = int(np.ceil(3 * SAMPLED_SMOOTH))
    tpl = template(reference, x, y, fit.half + m)
    # it moves by tenths of a pixel and its shape by a few per cent: room for 2 px and 5 %
    spline = search_spline(search, fit.t, fit.A, fit.half, 2.0 + 3 * SAMPLED_SMOOTH + 0.05 * fit.half,
                           SAMPLED_SMOOTH)
    if tpl is None or spline is None:
        return np.zeros(2), 0
    T = low_pass(tpl[0], SAMPLED_SMOOTH)[m:-m, m:-m]
    smoothed = Fit(T, fit.u.reshape(T.shape), fit.v.reshape(T.shape), spline, fit.d, fit.half, fit.w)
    smoothed.t, smoothed.A, smoothed.c = fit.t.copy(), fit.A.copy(), fit.c.copy()
    smoothed.g0, smoothed.g1 = fit.g0, fit.g1          # one low-pass on both: the radiometry holds
    smoothed.pw = fit.pw
    part = smoothed if fit.keep is None else smoothed.subset(fit.keep)
    max_iter, _, _, A0inv, max_shape_change = run_args
    status, _, it = part.run(bend, max_iter, fit.t.copy(), MAX_PULL, A0inv, max_shape_change)
    return (part.t - fit.t if status == OK else np.zeros(2)), it


_STATS: OrderedDict = OrderedDict()
_STATS_LOCK = threading.Lock()
STATS_KEPT = 4
"""Templates whose statistics :func:`template_stats` keeps (a point's matches in its other
views use the same template)."""


def template_stats(T):
    """``(noise, aliasing, (gu, gv), edges, pw)`` of the template ``T`` ``(n, n)``: the image
    noise σ (:func:`noise_sigma`, grey values), where its point-sampled edges lie
    (:func:`sampling_px`, px), its gradients (grey values per px), their mean edge σ
    (:func:`edge_sigma`, px) and the pixels' weights in the fit ``(n²,)`` (None: uniform) —
    a pixel on a point-sampled edge weighted by the inverse of its variance, the noise's plus
    the edge's unknown place in both views (gradient × σ), so the texture that samples place
    well counts more. Kept for the last :data:`STATS_KEPT` templates (by their grey values):
    the F and B matches of a point share one."""
    key = (T.shape, T.tobytes())
    with _STATS_LOCK:
        if key in _STATS:
            _STATS.move_to_end(key)
            return _STATS[key]
    noise = noise_sigma(T)
    aliasing = sampling_px(T, noise)
    gv, gu = np.gradient(T)
    edges = edge_sigma(gu, gv, aliasing)
    pw = None
    if noise > 0 and (aliasing[0].any() or aliasing[1].any()):
        edge_var = 2.0 * ((gu * aliasing[0]) ** 2 + (gv * aliasing[1]) ** 2)
        pw = (noise ** 2 / (noise ** 2 + edge_var)).ravel()
    out = (noise, aliasing, (gu, gv), edges, pw)
    with _STATS_LOCK:
        _STATS[key] = out
        while len(_STATS) > STATS_KEPT:
            _STATS.popitem(last=False)
    return out
