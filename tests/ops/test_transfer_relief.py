"""The relief within a transfer's template that its patch cannot follow, as the reference DEM
shows it (ops.transfer_relief): what a plane or a quadratic leaves (nothing), what a ridge
beside the template's edges leaves (its height times the parallax per metre), and what the
reference's own noise makes of it (the noise term: the file's own noise, at its own posts);
and the relief one view's match shows, shared with the other's (one height moves both)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from pyproj import Transformer
from rasterio.transform import from_origin
from scipy import ndimage

from prismstation.core.matching.lsm import LsmResult
from prismstation.io.dem import read_dem, write_dem
from prismstation.ops.reference_heights import DemHeights
from prismstation.ops.transfer import Transfer
from prismstation.ops.transfer_relief import (RELIEF, UNSEEN_SHARE, relief_bias_px, relief_signal_share, shared_relief,
                                              with_relief)

AXES = np.diag([0.4, -0.4])            # 2.5 m pixels, rows southwards
K = 0.18                               # px along the parallax per metre of height (B of PRISM)
D = np.array([0.0, 1.0])               # the parallax along the rows


def _template(half=24, edge_u=14.0):
    """A template whose only texture lies in a band of columns ``edge_u`` ± 6 px east of the
    point (a field's boundary, its furrows), flat elsewhere, and its pixels' offsets."""
    k = np.arange(-half, half + 1, dtype=float)
    v, u = np.meshgrid(k, k, indexing="ij")
    furrows = 110.0 + 30.0 * ((np.floor(u / 3.0) + np.floor(v / 3.0)) % 2)
    T = np.where(np.abs(u - edge_u) < 6.0, furrows, 110.0)
    return T, u, v


def _heights(f):
    return lambda en: f(np.asarray(en, float)[:, 0], np.asarray(en, float)[:, 1])


def test_a_plane_leaves_nothing_and_a_ridge_beside_the_texture_moves_the_point():
    g = (1000.0, 2000.0, 300.0)
    plane = _heights(lambda e, n: 300.0 + 0.35 * (e - 1000.0) - 0.2 * (n - 2000.0))
    tpl = _template()
    assert abs(relief_bias_px(AXES, K, g, tpl, D, False, plane)[0]) < 1e-9
    quad = _heights(lambda e, n: 300.0 + 0.002 * (e - 1000.0) ** 2 + 0.001 * (e - 1000.0) * (n - 2000.0))
    assert abs(relief_bias_px(AXES, K, g, tpl, D, True, quad)[0]) < 1e-9      # the bend follows it
    # a ridge 8 m high along the edge's column, 35 m east of the point (14 px): the texture
    # lies on it, the point does not
    ridge = _heights(lambda e, n: 300.0 + 8.0 * np.exp(-0.5 * ((e - 1035.0) / 12.0) ** 2))
    bias, _ = relief_bias_px(AXES, K, g, tpl, D, False, ridge)
    assert 0.5 * K * 8.0 < bias <= K * 8.0


def _noise_ratios(tpl, height_of_at, n=200, seed=5, sigma_dem=4.0):
    """``(bias / noise, share with |bias| ≤ 2 noise)`` of :func:`relief_bias_px` at ``n``
    random points on flat ground seen through ``height_of_at(rng)``: a noisy reference."""
    rng = np.random.default_rng(seed)
    ratios, covered = [], 0
    for _ in range(n):
        height_of, (x0, y0) = height_of_at(rng)
        bias, sd = relief_bias_px(AXES, K, (x0, y0, 0.0), tpl, D, False, height_of, sigma_dem)
        covered += abs(bias) <= 2.0 * sd + 1e-12
        if sd > 0:
            ratios.append(bias / sd)
    return np.asarray(ratios), covered / n


def test_the_noise_term_is_what_the_references_noise_makes_of_it():
    # flat ground, a reference of 90 m cells with 4 m of white noise, bilinear between its
    # posts (as an SRTM-like DEM on the scene's grid); the point and its template anywhere on it
    def height_of_at(rng):
        noise = rng.normal(0.0, 4.0, (12, 12))

        def height_of(en):
            en = np.asarray(en, float)
            return ndimage.map_coordinates(noise, [en[:, 1] / 90.0 - 0.5, en[:, 0] / 90.0 - 0.5], order=1)
        height_of.grid = type("G", (), {"source_cell_m": (90.0, 90.0)})()
        return height_of, rng.uniform(300.0, 700.0, 2)
    ratios, covered = _noise_ratios(_template(half=32), height_of_at)
    # the noise's figure is the noise's σ (measured: RMS ratio 1.00; 1.01 over 1,000 points), not
    # an upper bound (cells taken whole, as before: 0.43), which hid real relief behind it
    assert covered >= 0.92 and 0.8 < np.sqrt(np.mean(ratios ** 2)) < 1.2, (covered, ratios)


def test_a_geographic_references_own_noise_and_posts_give_the_noise_term(tmp_path):
    # a 3″ reference in longitude and latitude, flat, with 4 m of white noise rounded to whole
    # metres, read onto a 30 m UTM grid as a scene's: its noise comes from the file itself (the
    # transfer's σ of the DEM, measured at GCPs, holds the error of its cells on slopes as
    # well) and its posts where the file has them (not a lattice in map metres)
    rng = np.random.default_rng(11)
    z = np.round(300.0 + rng.normal(0.0, 4.0, (200, 200)))
    cell = 3.0 / 3600.0
    geo = tmp_path / "srtm_like.tif"
    write_dem(geo, z.astype(np.float32), "EPSG:4326", from_origin(5.0, 44.6, cell, cell))
    e0, n0 = Transformer.from_crs("EPSG:4326", "EPSG:32631", always_xy=True).transform(5.0, 44.6)
    grid = read_dem(geo, "EPSG:32631", from_origin(e0 + 1000.0, n0 - 1000.0, 30.0, 30.0), (130, 130))
    assert grid.source_noise_m == pytest.approx(np.hypot(4.0, 12 ** -0.5), rel=0.1)
    heights = DemHeights(grid)
    ratios, covered = _noise_ratios(_template(half=32), lambda rng: (
        heights, (e0 + rng.uniform(2000.0, 3000.0), n0 - rng.uniform(2000.0, 3000.0))), sigma_dem=40.0)
    # measured: RMS ratio 0.86 (read through the 30 m grid, bilinear twice, the noise a little
    # smoother than the figure says); the cells taken whole at the GCPs' σ gave 0.03
    assert covered >= 0.92 and 0.7 < np.sqrt(np.mean(ratios ** 2)) < 1.25, (covered, ratios)


def _ridge(height_m):
    """A ridge ``height_m`` high along the template's texture, 35 m east of the point."""
    return _heights(lambda e, n: 300.0 + height_m * np.exp(-0.5 * ((e - 1035.0) / 12.0) ** 2))


def _rough(height_m):
    """Relief everywhere: hills and hollows ``height_m`` high, 60–80 m across."""
    return _heights(lambda e, n: 300.0 + height_m * np.sin(e / 9.0) * np.cos(n / 13.0))


def _relief_match(terrain, along_half=24, sigma_dem=2.0):
    """A match of :func:`_template`'s point (σ 0.2 px along the parallax) on ``terrain``;
    ``along_half``: the uniformly weighted fit that gave its position along the parallax (0: the
    fit weighted to the point's surroundings). Returns the match, it with the relief and the
    reference's ``(figure, noise)`` and share of relief at the point."""
    g = (1000.0, 2000.0, 300.0)
    T, u, v = _template()
    m = LsmResult(30.0, 40.0, np.diag([0.01, 0.04]), np.diag([0.01, 0.04]), np.eye(2), 1.0, 0.0, 0.95, 5, "ok",
                  extra={"d": D, "half": 24, "bend": np.zeros(3), "along_half": along_half})
    xy = (24.5 + 10, 24.5 + 10)
    out = with_relief(m, np.pad(T, 10, mode="edge"), xy, AXES, g, K * D, terrain, sigma_dem, 0.5)
    return (m, out, relief_bias_px(AXES, K, g, (T, u, v), D, False, terrain, sigma_dem),
            relief_signal_share(AXES, g, 24, terrain, sigma_dem))


def test_the_relief_the_reference_shows_moves_the_match_back():
    """Where the reference shows relief about the point well beyond its noise, its figure of
    the relief under the template's texture (``k·Δh`` px along the parallax) moves the match
    back, shrunk by that share; its σ along the parallax gains the noise left in the move, the
    relief finer than the reference's posts (:data:`UNSEEN_SHARE` of the move) and, as a σ
    term, the figure's unmoved rest. Before, the figure was a σ term only and the match stayed
    where the relief had put it (here 0.9 px off)."""
    m, out, (bias, noise), share = _relief_match(_rough(8.0))
    assert abs(bias) > 0.5 and share > 0.9 and out.ok
    shift = share * bias
    assert (out.x, out.y) == pytest.approx((30.0, 40.0 - shift))
    var = share * noise ** 2 + (UNSEEN_SHARE * shift) ** 2 + (1 - share) ** 2 * (bias ** 2 - noise ** 2)
    assert out.extra["relief_shift"] == pytest.approx(shift) and out.extra["relief_px"] == pytest.approx(np.sqrt(var))
    assert out.cov == pytest.approx(m.cov + np.diag([0.0, var]))
    # a reference too noisy to tell that relief from its noise moves nothing
    m, noisy, (bias, noise), share = _relief_match(_rough(8.0), sigma_dem=40.0)
    assert share == 0.0 and (noisy.x, noisy.y) == (m.x, m.y)
    assert noisy.extra["relief_px"] == pytest.approx(np.sqrt(max(bias ** 2 - noise ** 2, 0.0)))


def test_the_share_of_relief_is_nil_on_a_noisy_flat_reference_and_near_one_on_relief():
    rng = np.random.default_rng(5)
    flat, hilly = [], []
    for _ in range(100):
        noise = rng.normal(0.0, 4.0, (20, 20))

        def height_of(en, noise=noise):
            en = np.asarray(en, float)
            return ndimage.map_coordinates(noise, [en[:, 1] / 90.0 - 0.5, en[:, 0] / 90.0 - 0.5], order=1)

        def relief(en, height_of=height_of):
            en = np.asarray(en, float)
            return height_of(en) + 15.0 * np.sin(en[:, 0] / 40.0) * np.cos(en[:, 1] / 55.0)
        height_of.grid = relief.grid = type("G", (), {"source_cell_m": (90.0, 90.0)})()
        g = (*rng.uniform(700.0, 1100.0, 2), 0.0)
        flat.append(relief_signal_share(AXES, g, 32, height_of, 4.0))
        hilly.append(relief_signal_share(AXES, g, 32, relief, 4.0))
    # measured: flat median 0, 90 % under 0.33; hills 250–350 m across, 15 m high: median 0.92
    assert np.median(flat) == 0.0 and np.quantile(flat, 0.9) < 0.4
    assert np.median(hilly) > 0.85 and np.min(hilly) > np.quantile(flat, 0.9)


def test_the_share_of_relief_beside_voids_comes_from_the_templates_with_heights():
    relief = _rough(8.0)
    g = (1000.0, 2000.0, 300.0)
    full = relief_signal_share(AXES, g, 24, relief, 2.0)

    def west_void(en):                  # no heights 100 m west of the point and beyond
        h = relief(en)
        return np.where(np.asarray(en, float)[:, 0] < 900.0, np.nan, h)
    beside = relief_signal_share(AXES, g, 24, west_void, 2.0)
    assert full > 0.9 and beside > 0.9
    # the point itself in a void: nothing to tell
    assert relief_signal_share(AXES, g, 24, _heights(lambda e, n: np.full(len(e), np.nan)), 2.0) == 0.0


def test_a_match_the_relief_may_move_past_its_limit_is_refused_with_the_reason():
    _, out, (bias, _), share = _relief_match(_rough(20.0))    # what the reference cannot see: > 0.5 px
    assert out.status == RELIEF and f"moved the point by {share * bias:+.2f} px" in out.reason
    # the fit weighted to the point's surroundings gave the position: the whole template's
    # figure is a σ term only, the match not moved
    m, near, (bias, noise), _ = _relief_match(_ridge(8.0), along_half=0)
    assert near.status == RELIEF and (near.x, near.y) == (m.x, m.y)
    assert near.extra["relief_px"] == pytest.approx(np.sqrt(bias ** 2 - noise ** 2))
    m, kept, _, _ = _relief_match(_heights(lambda e, n: np.full(len(e), 300.0)))
    assert kept.ok and np.allclose(kept.cov, m.cov) and kept.extra["relief_px"] == 0.0


def test_a_smaller_template_the_scaled_relief_already_refuses_is_not_fitted(monkeypatch):
    """A 65 px template refused for 0.9 px of relief: at 49 and 37 px the term scaled by the
    sizes' ratio (0.68, 0.51 px) alone exceeds 0.5 px, so only 25 px is fitted."""
    import prismstation.ops.transfer_relief as mod
    tried = []

    def refine(reference, x, y, win, t0, shape, *, half, **kw):
        tried.append(half)
        return replace(m, status="texture")

    monkeypatch.setattr(mod, "refine", refine)
    m = LsmResult(30.0, 40.0, np.diag([0.01, 0.9 ** 2]), np.diag([0.01, 0.04]), np.eye(2), 1.0, 0.0, 0.95, 5,
                  RELIEF, extra={"d": D, "half": 32, "bend": np.zeros(3), "relief_px": 0.9})
    win = (np.zeros((80, 80)), 0, 0)
    out = mod.smaller_on_relief(m, np.zeros((80, 80)), (40.0, 40.0), win, (12, 18, 24, 32), np.eye(2),
                                (AXES, (0.0, 0.0, 0.0), K * D, None, 2.0), 0.5, 0.1)
    assert tried == [12] and out is m


def _found(view, relief_px, noise_px=0.05, half=32, d=(0.0, 1.0)):
    """A match along the parallax ``d`` stating ``noise_px`` of noise and ``relief_px`` of
    relief along it, 0.1 px across."""
    d = np.asarray(d, float)
    e = np.array([-d[1], d[0]])
    cov = (noise_px ** 2 + relief_px ** 2) * np.outer(d, d) + 0.01 * np.outer(e, e)
    m = LsmResult(10.0, 20.0, cov, cov, np.eye(2), 1.0, 0.0, 0.9, 5, "ok",
                  extra={"d": d, "half": half, "bend": np.zeros(3), "noise_along": noise_px})
    return Transfer(view, 10.0, 20.0, (10.0, 20.0), m)


def _relief_m(t, k):
    d = np.asarray(t.match.extra["d"], float)
    return np.sqrt(d @ t.match.cov @ d - t.match.extra["noise_along"] ** 2) / k


def test_the_relief_one_view_shows_raises_the_others_sigma_to_their_mean():
    """F's blocks saw 0.40 px of relief, B's (a little steeper, k 0.20) nothing: one height
    moves both, so B states their mean in metres; F keeps its own, nothing changes across."""
    kf, kb = 0.18, 0.20
    found = {"F": _found("F", 0.40), "B": _found("B", 0.0, d=(0.6, 0.8))}
    out = shared_relief(found, {"F": kf * np.array([0.0, 1.0]), "B": kb * np.array([0.6, 0.8])}, 0.5)
    assert out["F"].match is found["F"].match
    mean_m = np.sqrt((0.40 / kf) ** 2 / 2)
    assert out["B"].ok and _relief_m(out["B"], kb) == pytest.approx(mean_m)
    e = np.array([-0.8, 0.6])
    assert e @ out["B"].match.cov @ e == pytest.approx(0.01)
    # a larger template's relief is scaled down by the sizes' ratio for a smaller one
    found = {"F": _found("F", 0.40, half=32), "B": _found("B", 0.0, half=12)}
    out = shared_relief(found, {"F": kf * np.array([0.0, 1.0]), "B": kf * np.array([0.0, 1.0])}, 0.5)
    assert _relief_m(out["B"], kf) == pytest.approx(np.sqrt(((0.40 / kf) * 25 / 65) ** 2 / 2))


def test_a_match_the_other_views_relief_takes_past_its_limit_is_refused_naming_it():
    found = {"F": _found("F", 0.49, noise_px=0.1), "B": _found("B", 0.30, noise_px=0.3)}
    out = shared_relief(found, {v: 0.18 * np.array([0.0, 1.0]) for v in "FB"}, 0.5)
    assert out["F"].ok
    assert out["B"].match.status == RELIEF and "the match in F" in out["B"].match.reason
    # alone, or beside a failure, a match keeps its σ
    found["B"] = Transfer("B", 0, 0, (0, 0), replace(found["B"].match, status="texture"))
    out = shared_relief({"F": _found("F", 0.0), "B": found["B"]}, {v: 0.18 * np.array([0.0, 1.0]) for v in "FB"}, 0.5)
    assert out["F"].match.cov[1, 1] == pytest.approx(0.05 ** 2)
