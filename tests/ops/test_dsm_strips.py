"""The DSM's grid-sized steps done in strips of rows (memory on 14,000 px scenes) give what
the whole-grid steps give."""
import numpy as np
import pytest
import rasterio

from prismstation.io import dsm as dsm_io
from prismstation.ops import dsm as ops_dsm


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
    whole = ops_dsm.bridge(h)
    monkeypatch.setattr(ops_dsm, "BRIDGE_STRIP", 40)
    monkeypatch.setattr(ops_dsm, "BRIDGE_HALO", 30)
    strips = ops_dsm.bridge(h)
    assert np.isfinite(strips).all()
    np.testing.assert_array_equal(strips, whole)


@pytest.mark.parametrize("strip", [10 ** 6, 40])
def test_bridge_from_a_subset_of_the_cells_needs_no_masked_copy(monkeypatch, strip):
    """``valid`` bridges from those cells only: what a NaN'd copy of the grid would give."""
    h = _surface(seed=3)
    valid = np.isfinite(h) & (np.random.default_rng(4).random(h.shape) < 0.5)
    monkeypatch.setattr(ops_dsm, "BRIDGE_STRIP", strip)
    monkeypatch.setattr(ops_dsm, "BRIDGE_HALO", 30)
    np.testing.assert_array_equal(ops_dsm.bridge(h, valid=valid),
                                  ops_dsm.bridge(np.where(valid, h, np.float32(np.nan))))


def test_a_strip_with_nothing_near_takes_the_median(monkeypatch):
    h = _surface()
    h[150:260] = np.nan
    monkeypatch.setattr(ops_dsm, "BRIDGE_STRIP", 20)
    monkeypatch.setattr(ops_dsm, "BRIDGE_HALO", 10)
    out = ops_dsm.bridge(h)
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
        monkeypatch.setattr(ops_dsm, "BRIDGE_STRIP", strip)
        hh, qq = h.copy(), q.copy()
        ops_dsm._drop_unconfirmed(hh, qq, 6.0)
        results.append((hh, qq))
    (h1, q1), (h2, q2) = results
    np.testing.assert_array_equal(h1, h2)
    np.testing.assert_array_equal(q1, q2)
    blunder = (q == 1) & np.isfinite(h)
    assert np.isnan(h1[blunder]).all() and (q1[blunder] == 0).all()
    assert np.isfinite(h1[3::7, ::5]).sum() == np.isfinite(h[3::7, ::5]).sum()


def test_write_dsm_in_strips_reads_back(monkeypatch, tmp_path):
    h = _surface(rows=50, cols=30)
    seen = np.ones(h.shape, bool)
    seen[:, :3] = False
    mask = np.where(np.isfinite(h), 1, 0).astype(np.uint8)
    quality = np.where(np.isfinite(h), 3, 0).astype(np.uint8)
    d = ops_dsm.Dsm(h, (5.0, 0.0, 500000.0, 0.0, -5.0, 4000000.0), "EPSG:32631", "ellipsoidal", 0.8,
                    mask, seen, quality, 5.0)
    monkeypatch.setattr(dsm_io, "STRIP_ROWS", 7)
    dsm_io.write_dsm(tmp_path / "d.tif", d)
    with rasterio.open(tmp_path / "d.tif") as ds:
        a, m, q = ds.read(1), ds.read(2), ds.read(3)
    ok = np.isfinite(h)
    np.testing.assert_array_equal(a[ok], h[ok])
    assert np.isnan(dsm_io.NODATA) and np.isnan(a[~ok]).all()
    assert np.isnan(m[~seen]).all() and (m[seen] == mask[seen]).all()
    assert (q[seen] == quality[seen]).all()
