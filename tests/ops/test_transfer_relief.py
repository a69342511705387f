"""The relief within a transfer's template that its patch cannot follow, as the reference DEM
shows it (ops.transfer_relief): what a plane or a quadratic leaves (nothing), what a ridge
beside the template's edges leaves (its height times the parallax per metre), and what the
reference's own noise makes of it (covered by the noise term)."""
from __future__ import annotations

import numpy as np
from scipy import ndimage

from prismstation.core.matching.lsm import LsmResult
from prismstation.ops.transfer_relief import RELIEF, relief_bias_px, with_relief

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


def test_the_noise_term_covers_what_the_references_noise_makes_of_it():
    # flat ground, a reference of 90 m cells with 4 m of white noise, bilinear between them (as
    # an SRTM-like DEM on the scene's grid); the point and its template placed anywhere on it
    rng = np.random.default_rng(5)
    tpl = _template(half=32)
    ratios, covered = [], 0
    for _ in range(200):
        noise = rng.normal(0.0, 4.0, (12, 12))
        x0, y0 = rng.uniform(300.0, 700.0, 2)

        def height_of(en, noise=noise):
            en = np.asarray(en, float)
            return ndimage.map_coordinates(noise, [en[:, 1] / 90.0 - 0.5, en[:, 0] / 90.0 - 0.5], order=1)
        height_of.grid = type("G", (), {"source_cell_m": (90.0, 90.0)})()
        bias, sd = relief_bias_px(AXES, K, (x0, y0, 0.0), tpl, D, False, height_of, 4.0)
        covered += abs(bias) <= 2.0 * sd + 1e-12
        if sd > 0:
            ratios.append(bias / sd)
    # the term is an upper bound (cells taken whole where the DEM interpolates between its
    # posts): the noise's figure within 2 of it at least 95 % of the time, and not a vast
    # overstatement (measured: all 200 within, RMS ratio 0.43)
    assert covered >= 0.95 * 200 and 0.25 < np.sqrt(np.mean(np.square(ratios))) < 1.0, (covered, ratios)


def test_a_match_the_relief_may_move_past_its_limit_is_refused_with_the_reason():
    g = (1000.0, 2000.0, 300.0)
    ridge = _heights(lambda e, n: 300.0 + 8.0 * np.exp(-0.5 * ((e - 1035.0) / 12.0) ** 2))
    T, u, v = _template()
    ref = np.pad(T, 10, mode="edge")
    m = LsmResult(30.0, 40.0, np.diag([0.01, 0.04]), np.diag([0.01, 0.04]), np.eye(2), 1.0, 0.0, 0.95, 5, "ok",
                  extra={"d": D, "half": 24, "bend": np.zeros(3)})
    xy = (24.5 + 10, 24.5 + 10)
    out = with_relief(m, ref, xy, AXES, g, K * D, ridge, 2.0, 0.5)
    assert out.status == RELIEF and "relief" in out.reason and out.extra["relief_px"] > 0.7
    flat = _heights(lambda e, n: np.full(len(e), 300.0))
    kept = with_relief(m, ref, xy, AXES, g, K * D, flat, 2.0, 0.5)
    assert kept.ok and np.allclose(kept.cov, m.cov) and kept.extra["relief_px"] == 0.0
