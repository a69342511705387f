"""The relief within a transfer's template that its patch cannot follow, as the reference DEM
shows it (:func:`relief_bias_px`): the displacement it gives the match, moved back, and what
the reference cannot tell of it, a term of the point's σ along the parallax
(:func:`with_relief`); a match that term refuses is made again with a smaller template
(:func:`smaller_on_relief`).

An affine patch (and its bend along the parallax) follows a plane (and a quadratic) of
heights over the template; the rest of the relief moves the search image's texture along the
parallax by ``k·Δh`` (``k`` px per metre of height), and the fit places the point where the
texture's information is, not at the point: on steep relief with few edges (field parcels)
that is pixels. Coordinates: image ``x`` = column, ``y`` = row, pixels (docs/model.md §1).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from prismstation.core.matching.lsm import LsmResult, refine, template
from prismstation.core.matching.lsm_sigma import largest_sigma
from prismstation.core.models.solution import Solution
from prismstation.ops.predict import ground_jacobian

RELIEF = "relief"
"""The status of a match whose σ, the relief's term in it, is above the largest accepted."""


def source_axes(sol: Solution, source: str, ground) -> np.ndarray:
    """``(2, 2)`` px per map metre of ``source`` at ``ground`` ``(E, N, h)``: what
    :func:`with_relief` carries the template's pixels to the ground with."""
    return ground_jacobian(sol, source, np.asarray(ground, float))[1][:, :2]


def with_relief(m: LsmResult, reference, xy, axes, ground, dh, height_of, sigma_dem: float,
                max_sigma: float, shares: dict | None = None) -> LsmResult:
    """``m`` (a match of a source view's point ``xy`` — in ``reference``'s pixels) with the
    relief the reference DEM shows within its template (:func:`relief_bias_px`).

    Where a uniformly weighted fit gave the position along the parallax (the template's, or
    its central part's: ``extra["along_half"]``), the point is moved back by the displacement
    that relief gives that fit, shrunk by the share of the reference's figures about the point
    that is relief rather than its noise (:func:`relief_signal_share`; ``extra["relief_shift"]``,
    px along the unit parallax), and its covariance gains the noise left in that move (its own
    σ, else ``sigma_dem`` m per post), the relief the reference cannot see
    (:data:`UNSEEN_SHARE` of the move) and the figure's unmoved rest as a σ term. Where the fit
    weighted to the point's surroundings gave it (its relief is not the template's), or on
    smooth ground (a share of 0), the figure less its noise is a σ term only. The term is
    ``extra["relief_px"]``; a match whose σ then exceeds ``max_sigma`` px is refused
    (:data:`RELIEF`). ``axes``: :func:`source_axes`; ``ground``: the point's ``(E, N, h)`` on
    the reference DEM ``height_of``; ``dh``: px per metre of height in the matched view;
    ``shares``: the point's shares of relief by template half size, kept for its other views."""
    d = np.asarray(m.extra["d"], float)
    own = int(m.extra.get("along_half", m.extra["half"]))
    tpl = template(reference, xy[0], xy[1], own or int(m.extra["half"]))
    if tpl is None:
        return m
    bend = bool(np.any(m.extra["bend"]))
    bias, noise = relief_bias_px(axes, float(np.hypot(*dh)), ground, tpl, d, bend, height_of, sigma_dem)
    b2 = max(bias * bias - noise * noise, 0.0)
    gain = 0.0
    if own and bias:
        shares = {} if shares is None else shares
        if own not in shares:
            shares[own] = relief_signal_share(axes, ground, own, height_of, sigma_dem)
        gain = shares[own]
    if gain > 0.0:
        # the figure, shrunk by the share of it that is relief about the point, moves the point;
        # the σ holds the noise left in that move, the relief the reference cannot see and, as
        # a figure the point is not moved by, the rest
        shift = gain * bias
        var = gain * noise * noise + (UNSEEN_SHARE * shift) ** 2 + (1.0 - gain) ** 2 * b2
        m = replace(m, x=m.x - shift * d[0], y=m.y - shift * d[1],
                    extra={**m.extra, "relief_px": float(np.sqrt(var)), "relief_shift": float(shift)})
        return _with_relief_var(m, d, var, f"the reference DEM shows it, moved the point by {shift:+.2f} px along "
                                f"the parallax ({gain:.0%} of its figure); what is left may move it by",
                                float(np.sqrt(var)), max_sigma)
    if b2 == 0.0:
        return replace(m, extra={**m.extra, "relief_px": 0.0})
    return _with_relief_var(replace(m, extra={**m.extra, "relief_px": float(np.sqrt(b2))}), d, b2,
                            "the reference DEM shows it, may move the point by", float(np.sqrt(b2)), max_sigma)


def _with_relief_var(m: LsmResult, d, var: float, what: str, move: float, max_sigma: float) -> LsmResult:
    """``m`` with ``var`` px² more along the unit parallax ``d`` in its covariance; refused
    (:data:`RELIEF`) when its σ then exceeds ``max_sigma`` px, the reason saying what showed the
    relief and what it did (``what``, ending before ``move`` px)."""
    cov = m.cov + var * np.outer(d, d)
    smax = largest_sigma(cov)
    if smax <= max_sigma:
        return replace(m, cov=cov)
    return replace(m, cov=cov, status=RELIEF, reason=f"the relief within the template, as {what} {move:.2f} px "
                   f"along the parallax: σ {smax:.2f} px above {max_sigma:.2f}")


def smaller_on_relief(m: LsmResult, reference, xy, window, halves, shape, relief: tuple, max_sigma: float,
                      max_shape_change: float) -> LsmResult:
    """A match refused for its template's relief (:data:`RELIEF`), made again from where it
    ended with the smaller template sizes ``halves`` (the largest first) until one is kept.
    Its own relief term (:func:`with_relief`) is taken from the reference DEM, whose cells see
    less and less of a smaller template's relief: the refused template's term, scaled by the
    sizes' ratio (linear: between a rough surface's power under 1 and a smooth one's square),
    is kept in its σ along the parallax where it is the larger. ``xy``: the point in
    ``reference``; ``window``: ``(array, col0, row0)`` of the matched view about the match;
    ``shape``: the predicted shape to start from; ``relief``: ``(axes, ground, dh, height_of,
    sigma_dem)`` as :func:`with_relief` takes them. Returns ``m`` when no size is kept."""
    win, c0, r0 = window
    if m.status != RELIEF or win is None:
        return m
    d = np.asarray(m.extra["d"], float)
    big, bias = int(m.extra["half"]), float(m.extra.get("relief_px", 0.0))
    for half in sorted((h for h in halves if h < big), reverse=True):
        scaled = bias * (2 * half + 1) / (2 * big + 1)
        if scaled > max_sigma:
            continue        # the scaled term alone takes its σ along the unit parallax past the limit
        m2 = refine(reference, xy[0], xy[1], win, (m.x - c0, m.y - r0), shape, parallax=d, half=half,
                    max_sigma=max_sigma, max_shape_change=max_shape_change)
        if not m2.ok:
            continue
        m2 = with_relief(replace(m2, x=m2.x + c0, y=m2.y + r0, extra={**m2.extra, "along": m.extra.get("along")}),
                         reference, xy, *relief, max_sigma)
        if not m2.ok:
            continue
        own = m2.extra.get("relief_px", 0.0)
        if scaled <= own:
            return m2
        cov = m2.cov + (scaled ** 2 - own ** 2) * np.outer(d, d)
        if largest_sigma(cov) <= max_sigma:
            return replace(m2, cov=cov, extra={**m2.extra, "relief_px": scaled})
    return m


UNSEEN_SHARE = 0.3
"""σ of the reference DEM's figure of a template's relief (:func:`relief_bias_px`) beyond what
its noise makes of it, as a share of the figure: the relief finer than its posts, which it
cannot show, grows with what it shows (on the tuning scenes' 3″ and 90 m references, against
the same figure from the true terrain: 0.17–0.35)."""
#: the cell (m) of a reference DEM whose own is not known: SRTM's 3″
DEFAULT_CELL_M = 90.0
#: template pixels per side pooled into one height sample (the relief varies over tens of metres)
POOL_PX = 4


def relief_bias_px(axes, k: float, ground, template, d, bend: bool, height_of,
                   sigma_dem: float = 0.0) -> tuple[float, float]:
    """``(bias, noise)`` px: the displacement along the parallax direction ``d`` (unit, in the
    matched view) that the reference DEM's relief within ``template`` leaves at the point — the
    displacement ``k·(h(u, v) − h(0, 0))`` of the template's pixels (pooled
    :data:`POOL_PX` square), fitted by the patch's model (a plane in ``u, v``; with ``bend`` a
    quadratic) weighted by the template's information along the parallax (its squared gradient
    along ``d``), at the point — and the σ of that figure that the reference's white noise
    gives: post by post of its own grid, bilinear between them as the DEM is read, of its own
    σ (:attr:`~prismstation.io.dem.DemGrid.source_noise_m`), else ``sigma_dem`` m.
    ``axes``: the source's px per map metre (:func:`source_axes`); ``k``: px along ``d`` per
    metre of height in the matched view; ``ground``: the point's ``(E, N, h)``;
    ``template``: ``(T, u, v)`` of :func:`prismstation.core.matching.lsm.template`;
    ``height_of``: the reference DEM (map metres ``(n, 2)`` → ellipsoidal metres). ``(0, 0)``
    where the DEM has no height at the point or under more than a quarter of the template, or
    where the texture fixes no patch."""
    T, u, v = template
    g = np.asarray(ground, float)
    gv, gu = np.gradient(np.asarray(T, float))
    w, uv = _pooled((gu * d[0] + gv * d[1]) ** 2, u, v)
    # the pooled pixels on the ground: the source's own relief shift is the point's (a nadir
    # view), its image axes carried by the planar part of its Jacobian
    en = g[:2, None] + np.linalg.solve(axes, uv)
    h = np.asarray(height_of(np.vstack([en.T, g[None, :2]])), float)
    h0, h = h[-1], h[:-1]
    ok = np.isfinite(h)
    if not np.isfinite(h0) or ok.mean() < 0.75:
        return 0.0, 0.0
    beta = _fit_at_point(uv[:, ok], w[ok], bend)
    if beta is None:
        return 0.0, 0.0
    bias = k * float(beta @ (h[ok] - h0))
    return bias, k * _noise_m(height_of, np.hstack([en[:, ok], g[:2, None]]), np.append(beta, -1.0), sigma_dem)


SIGNAL_POOL_PX = 8
"""Template pixels per side pooled into one height sample for that share (20 m: the reference's
posts lie 70–90 m apart)."""
SIGNAL_REACH = 2
"""The templates about a point whose relief figures give its share of relief
(:func:`relief_signal_share`): this many a side, one template apart (a 5 × 5 square)."""


def relief_signal_share(axes, ground, half: int, height_of, sigma_dem: float = 0.0) -> float:
    """How much of the reference DEM's relief figure (:func:`relief_bias_px`) about the point
    is relief rather than the reference's noise: the Wiener gain ``r / (1 + r)`` in [0, 1],
    ``r`` the ratio of the figures' mean square less their noise's to their noise's — the
    figure (the relief beyond a plane) taken for a template of ``half`` px with its information
    spread evenly, at the point and at the templates about it (:data:`SIGNAL_REACH`), each with
    its own noise (it varies by a third with where the posts fall). On smooth ground the figures
    are the noise alone (0); where the reference shows relief well beyond its noise, near 1.
    Arguments as :func:`relief_bias_px`; 0 where the DEM has no height at the point."""
    k = np.arange(-half, half + 1, dtype=float)
    v, u = np.meshgrid(k, k, indexing="ij")
    w, uv = _pooled(np.ones_like(u), u, v, SIGNAL_POOL_PX)
    ring = range(-SIGNAL_REACH, SIGNAL_REACH + 1)
    offsets = (2 * half + 1) * np.array([(i, j) for j in ring for i in ring], float).T      # (2, q) px
    q = offsets.shape[1]
    centres = np.asarray(ground, float)[:2, None] + np.linalg.solve(axes, offsets)          # (2, q) m
    pixels = centres[:, :, None] + np.linalg.solve(axes, uv)[:, None, :]                     # (2, q, P) m
    h = np.asarray(height_of(np.vstack([pixels.reshape(2, -1).T, centres.T])), float)
    H, h0 = h[:-q].reshape(q, -1), h[-q:]
    rows = np.isfinite(h0) & np.all(np.isfinite(H), axis=1)
    beta = _fit_at_point(uv, w, False)
    if not rows[q // 2] or beta is None:
        return 0.0
    figure2 = float(np.mean(((H[rows] - h0[rows, None]) @ beta) ** 2))
    pts = np.concatenate([pixels, centres[:, :, None]], axis=2)[:, rows].reshape(2, -1)
    noise2 = float(np.mean(_noise_m(height_of, pts, np.append(beta, -1.0), sigma_dem, int(rows.sum())) ** 2))
    if noise2 <= 0:
        return 1.0 if figure2 > 0 else 0.0
    r = max(figure2 - noise2, 0.0) / noise2
    return r / (1.0 + r)


def _pooled(w, u, v, block: int = POOL_PX):
    """``(w, uv)``: the pixel weights ``w`` summed and the offsets ``u, v`` ``(n, n)`` averaged
    over ``block`` px square blocks (the template's central ``⌊n / block⌋`` blocks a side):
    ``(m,)`` and ``(2, m)``."""
    n = w.shape[0] // block * block
    lo = (w.shape[0] - n) // 2

    def pool(a, how):
        blocks = a[lo:lo + n, lo:lo + n].reshape(n // block, block, n // block, block)
        return how(blocks, axis=(1, 3)).ravel()

    return pool(w, np.sum), np.vstack([pool(u, np.mean), pool(v, np.mean)])


def _fit_at_point(uv, w, bend: bool):
    """``(m,)``: each pooled pixel's weight in the patch model's weighted least-squares fit
    (a plane in ``u, v``; with ``bend`` a quadratic) read at the point; None where the weights
    fix no such fit."""
    if not np.any(w > 0):
        return None
    half = max(float(np.abs(uv).max()), 1.0)
    a, b = uv / half
    A = np.vstack([np.ones_like(a), a, b] + ([a * a, a * b, b * b] if bend else [])).T
    N = A.T @ (A * w[:, None])
    if np.linalg.cond(N) > 1e10:        # the texture fixes no patch (the match refuses it)
        return None
    return np.linalg.solve(N, (A * w[:, None]).T)[0]


def _noise_m(height_of, pts, weights, sigma_dem: float, groups: int = 1):
    """σ (m) of ``Σ weights_i · h(pts_i)`` (``pts`` ``(2, n)`` map metres) that the reference's
    noise gives: white per post of its own grid, carried by the bilinear reading between its
    posts (each post's share of the sum), of the file's own σ, else ``sigma_dem``; with
    ``groups``, ``(groups,)`` of as many such sums, their points consecutive."""
    grid = getattr(height_of, "grid", None)
    post = grid.source_pixels(pts.T) if hasattr(grid, "source_pixels") else None
    if post is None or not np.all(np.isfinite(post)):
        cell = np.asarray(getattr(grid, "source_cell_m", None) or (DEFAULT_CELL_M, DEFAULT_CELL_M), float)
        post = pts / cell[:, None]
    share = _post_shares(post - 0.5, np.tile(weights, groups), groups)
    own = getattr(grid, "source_noise_m", None)
    sigma = float(own) if own is not None and np.isfinite(own) else float(sigma_dem)
    out = sigma * np.sqrt(np.sum(share ** 2, axis=1))
    return float(out[0]) if groups == 1 else out


def _post_shares(p, weights, groups: int = 1) -> np.ndarray:
    """``(groups, posts)``: each post's total weight in ``Σ weights_i · h(p_i)``, ``h`` bilinear
    between posts at integer coordinates, for each of ``groups`` sums of equal length; ``p``
    ``(2, n)`` the points in post units (x, y), ``weights`` ``(n,)``, the groups consecutive."""
    f = np.floor(p)
    t = p - f
    f = f.astype(np.int64)
    lo = f.min(axis=1)
    cols, rows = (f.max(axis=1) - lo + 2)
    group = np.repeat(np.arange(groups), p.shape[1] // groups)
    ids, vals = [], []
    for dx, dy in ((0, 0), (1, 0), (0, 1), (1, 1)):
        ids.append((group * rows + f[1] - lo[1] + dy) * cols + f[0] - lo[0] + dx)
        vals.append(weights * (t[0] if dx else 1.0 - t[0]) * (t[1] if dy else 1.0 - t[1]))
    return np.bincount(np.concatenate(ids), weights=np.concatenate(vals),
                       minlength=groups * rows * cols).reshape(groups, -1)


def shared_relief(found: dict, dh: dict, max_sigma: float) -> dict:
    """``found`` (view → :class:`~prismstation.ops.transfer.Transfer`) with each match's
    relief share of its σ along the parallax raised to the mean of the views' (in metres).

    The relief within the source template moves the point in every view by one height: by
    ``k·Δh`` px along each view's parallax (``k`` = ``|dh[view]|``, px per metre of height).
    What a match's σ along the parallax holds beyond its noise (``extra["noise_along"]``) is
    that relief as its own image let the blocks and the central fit see it — an estimate of
    one quantity, which on weak texture one view may miss where the other sees it. Their mean
    (in m², a larger template's scaled down by the sizes' ratio as :func:`smaller_on_relief`
    scales it) is the better estimate; a view's own is kept where it is the larger (a σ is
    never lowered). A match whose σ then exceeds ``max_sigma`` px is refused
    (:data:`RELIEF`)."""
    ok = {v: t for v, t in found.items() if t.ok and "noise_along" in t.match.extra
          and float(np.hypot(*dh[v])) > 1e-6}
    if len(ok) < 2:
        return found
    rel, unit = {}, {}
    for v, t in ok.items():
        d = np.asarray(t.match.extra["d"], float)
        unit[v] = d / np.hypot(*d)
        var = float(unit[v] @ t.match.cov @ unit[v]) - t.match.extra["noise_along"] ** 2
        rel[v] = max(var, 0.0) / float(np.hypot(*dh[v])) ** 2          # m²
    out = dict(found)
    for v, t in ok.items():
        size = 2 * int(t.match.extra["half"]) + 1
        seen = {w: rel[w] * min(1.0, size / (2 * int(ok[w].match.extra["half"]) + 1)) ** 2 for w in ok}
        mean = sum(seen.values()) / len(seen)
        if mean <= rel[v]:
            continue
        k2 = float(np.hypot(*dh[v])) ** 2
        others = " and ".join(w for w in ok if w != v)
        out[v] = replace(t, match=_with_relief_var(t.match, unit[v], (mean - rel[v]) * k2,
                                                   f"the match in {others} shows it, may move the point by",
                                                   float(np.sqrt(mean * k2)), max_sigma))
    return out
