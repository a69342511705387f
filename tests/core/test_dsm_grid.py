"""The DSM grid's steps done in strips of rows (memory on 14,000 px scenes) give what the
whole-grid steps give."""
import numpy as np
import pytest

from prismstation.core.surfaces import dsm_grid


def _surface(rows=300, cols=80, seed=0):
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:rows, 0:cols]
    h = (500 + 0.3 * x + 0.2 * y + 5 * np.sin(y / 17.0)).astype(np.float32)
    voids = rng.random(h.shape) < 0.2
    h[voids] = np.nan
    h[100:130, 10:40] = np.nan          # a hole wider than one cell
    return h


def test_bridge_in_strips_equals_the_whole_grid_bridge(monkeypatch):
    h = _surface()
    whole = dsm_grid.bridge(h)
    monkeypatch.setattr(dsm_grid, "BRIDGE_STRIP", 40)
    monkeypatch.setattr(dsm_grid, "BRIDGE_HALO", 30)
    strips = dsm_grid.bridge(h)
    assert np.isfinite(strips).all()
    np.testing.assert_array_equal(strips, whole)


@pytest.mark.parametrize("strip", [10 ** 6, 40])
def test_bridge_from_a_subset_of_the_cells_needs_no_masked_copy(monkeypatch, strip):
    """``valid`` bridges from those cells only: what a NaN'd copy of the grid would give."""
    h = _surface(seed=3)
    valid = np.isfinite(h) & (np.random.default_rng(4).random(h.shape) < 0.5)
    monkeypatch.setattr(dsm_grid, "BRIDGE_STRIP", strip)
    monkeypatch.setattr(dsm_grid, "BRIDGE_HALO", 30)
    np.testing.assert_array_equal(dsm_grid.bridge(h, valid=valid),
                                  dsm_grid.bridge(np.where(valid, h, np.float32(np.nan))))


def test_a_strip_with_nothing_near_takes_the_median(monkeypatch):
    h = _surface()
    h[150:260] = np.nan
    monkeypatch.setattr(dsm_grid, "BRIDGE_STRIP", 20)
    monkeypatch.setattr(dsm_grid, "BRIDGE_HALO", 10)
    out = dsm_grid.bridge(h)
    assert out[200:220] == pytest.approx(np.full((20, 80), np.nanmedian(h)))
    assert np.isfinite(out).all()


def test_drop_unconfirmed_in_strips(monkeypatch):
    h = _surface(seed=2)
    q = np.full(h.shape, 3, np.uint8)
    q[::7, ::5] = 1
    h[::7, ::5] += 50.0           # single-pair blunders
    h[3::7, ::5] += 2.0           # confirmed cells a little off stay
    results = []
    for strip in (10 ** 6, 40):
        monkeypatch.setattr(dsm_grid, "BRIDGE_STRIP", strip)
        hh, qq = h.copy(), q.copy()
        dsm_grid.drop_unconfirmed(hh, qq, 6.0)
        results.append((hh, qq))
    (h1, q1), (h2, q2) = results
    np.testing.assert_array_equal(h1, h2)
    np.testing.assert_array_equal(q1, q2)
    blunder = (q == 1) & np.isfinite(h)
    assert np.isnan(h1[blunder]).all() and (q1[blunder] == 0).all()
    assert np.isfinite(h1[3::7, ::5]).sum() == np.isfinite(h[3::7, ::5]).sum()
