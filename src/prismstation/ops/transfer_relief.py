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
from prismstation.core.models.solution import Solution
from prismstation.ops.predict import ground_jacobian

RELIEF = "relief"
"""The status of a match whose σ, the relief's term in it, is above the largest accepted."""


def source_axes(sol: Solution, source: str, ground) -> np.ndarray:
    """``(2, 2)`` px per map metre of ``source`` at ``ground`` ``(E, N, h)``: what
    :func:`with_relief` carries the template's pixels to the ground with."""
    return ground_jacobian(sol, source, np.asarray(ground, float))[1][:, :2]


def with_relief(m: LsmResult, reference, xy, axes, ground, dh, height_of, sigma_dem: float,
                max_sigma: float) -> LsmResult:
    """``m`` (a match of a source view's point ``xy`` — in ``reference``'s pixels) with the
    relief the reference DEM shows within its template (:func:`relief_bias_px`).

    Where a uniformly weighted fit gave the position along the parallax (the template's, or
    its central part's: ``extra["along_half"]``) and that relief's displacement of the fit
    exceeds :data:`SIGNIFICANT` times what the reference's noise makes of it (its own σ, else
    ``sigma_dem`` m per post), the point is moved back by it (``extra["relief_shift"]``, px
    along the unit parallax) and its covariance gains that noise's figure and the relief the
    reference cannot see (:data:`UNSEEN_SHARE`). Elsewhere — a figure within its noise, or the
    fit weighted to the point's surroundings (whose relief is not the template's) — the figure
    less that noise is a σ term instead, the point not moved. The term is
    ``extra["relief_px"]``; a match whose σ then exceeds ``max_sigma`` px is refused
    (:data:`RELIEF`). ``axes``: :func:`source_axes`; ``ground``: the point's ``(E, N, h)`` on
    the reference DEM ``height_of``; ``dh``: px per metre of height in the matched view."""
    d = np.asarray(m.extra["d"], float)
    own = int(m.extra.get("along_half", m.extra["half"]))
    tpl = template(reference, xy[0], xy[1], own or int(m.extra["half"]))
    if tpl is None:
        return m
    bias, noise = relief_bias_px(axes, float(np.hypot(*dh)), ground, tpl, d, bool(np.any(m.extra["bend"])),
                                 height_of, sigma_dem)
    if own and abs(bias) > SIGNIFICANT * noise:
        sigma = float(np.hypot(noise, UNSEEN_SHARE * bias))
        m = replace(m, x=m.x - bias * d[0], y=m.y - bias * d[1],
                    extra={**m.extra, "relief_px": sigma, "relief_shift": float(bias)})
        return _with_relief_var(m, d, sigma * sigma, f"the reference DEM shows it, moved the point by {bias:+.2f} px "
                                f"along the parallax; the figure is uncertain by", sigma, max_sigma)
    b2 = max(bias * bias - noise * noise, 0.0)
    if b2 == 0.0:
        return replace(m, extra={**m.extra, "relief_px": 0.0})
    return _with_relief_var(replace(m, extra={**m.extra, "relief_px": float(np.sqrt(b2))}), d, b2,
                            "the reference DEM shows it, may move the point by", float(np.sqrt(b2)), max_sigma)


def _with_relief_var(m: LsmResult, d, var: float, what: str, move: float, max_sigma: float) -> LsmResult:
    """``m`` with ``var`` px² more along the unit parallax ``d`` in its covariance; refused
    (:data:`RELIEF`) when its σ then exceeds ``max_sigma`` px, the reason saying what showed the
    relief and what it did (``what``, ending before ``move`` px)."""
    cov = m.cov + var * np.outer(d, d)
    smax = float(np.sqrt(np.linalg.eigvalsh(cov)[-1]))
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
        if float(np.sqrt(np.linalg.eigvalsh(cov)[-1])) <= max_sigma:
            return replace(m2, cov=cov, extra={**m2.extra, "relief_px": scaled})
    return m


SIGNIFICANT = 3.0
"""The reference's figure of a template's relief moves a match only where it exceeds this many
times what the reference's noise makes of it: on smooth ground it is that noise alone (on the
other renderer's 3″ reference 0.26 px, as large as the figure), which would move every match
by it; noise passes 3 σ at 0.3 % of the matches."""
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
    w = (gu * d[0] + gv * d[1]) ** 2
    n = T.shape[0] // POOL_PX * POOL_PX
    lo = (T.shape[0] - n) // 2

    def pool(a, how):
        blocks = a[lo:lo + n, lo:lo + n].reshape(n // POOL_PX, POOL_PX, n // POOL_PX, POOL_PX)
        return how(blocks, axis=(1, 3)).ravel()

    w, uv = pool(w, np.sum), np.vstack([pool(u, np.mean), pool(v, np.mean)])
    # the pooled pixels on the ground: the source's own relief shift is the point's (a nadir
    # view), its image axes carried by the planar part of its Jacobian
    en = g[:2, None] + np.linalg.solve(axes, uv)
    h = np.asarray(height_of(np.vstack([en.T, g[None, :2]])), float)
    h0, h = h[-1], h[:-1]
    ok = np.isfinite(h)
    if not np.isfinite(h0) or ok.mean() < 0.75 or not np.any(w[ok] > 0):
        return 0.0, 0.0
    half = max(float(np.abs(uv).max()), 1.0)
    a, b = uv[0, ok] / half, uv[1, ok] / half
    A = np.vstack([np.ones_like(a), a, b] + ([a * a, a * b, b * b] if bend else [])).T
    wo = w[ok]
    N = A.T @ (A * wo[:, None])
    if np.linalg.cond(N) > 1e10:        # the texture fixes no patch (the match refuses it)
        return 0.0, 0.0
    beta = np.linalg.solve(N, (A * wo[:, None]).T)[0]                 # the fit at the point
    bias = k * float(beta @ (h[ok] - h0))
    # the reference's noise, white per post of its own grid, carried by the bilinear reading
    # between its posts: each post's share of the fitted value, less the point's own (heights
    # are relative to it), times the file's own noise (else ``sigma_dem``)
    grid = getattr(height_of, "grid", None)
    pts = np.hstack([en[:, ok], g[:2, None]])
    post = grid.source_pixels(pts.T) if hasattr(grid, "source_pixels") else None
    if post is None or not np.all(np.isfinite(post)):
        cell = np.asarray(getattr(grid, "source_cell_m", None) or (DEFAULT_CELL_M, DEFAULT_CELL_M), float)
        post = pts / cell[:, None]
    share = _post_shares(post - 0.5, np.append(beta, -1.0))
    own = getattr(grid, "source_noise_m", None)
    sigma = float(own) if own is not None and np.isfinite(own) else float(sigma_dem)
    noise = k * sigma * float(np.sqrt(np.sum(share ** 2)))
    return bias, noise


def _post_shares(p, weights) -> np.ndarray:
    """Each post's total weight in ``Σ weights_i · h(p_i)``, ``h`` bilinear between posts at
    integer coordinates; ``p`` ``(2, n)`` the points in post units (x, y), ``weights`` ``(n,)``."""
    f = np.floor(p)
    t = p - f
    f = f.astype(np.int64)
    ids, vals = [], []
    for dx, dy in ((0, 0), (1, 0), (0, 1), (1, 1)):
        ids.append((f[0] + dx) * 1_000_003 + (f[1] + dy))
        vals.append(weights * (t[0] if dx else 1.0 - t[0]) * (t[1] if dy else 1.0 - t[1]))
    _, inv = np.unique(np.concatenate(ids), return_inverse=True)
    return np.bincount(inv, weights=np.concatenate(vals))


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
