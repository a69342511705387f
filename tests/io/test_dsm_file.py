"""The DSM GeoTIFF written in strips of rows reads back as the grid it was given."""
import numpy as np
import rasterio

from prismstation.io import dsm as dsm_io
from prismstation.ops.dsm import Dsm


def _surface(rows, cols, seed=0):
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:rows, 0:cols]
    h = (500 + 0.3 * x + 0.2 * y + 5 * np.sin(y / 17.0)).astype(np.float32)
    h[rng.random(h.shape) < 0.2] = np.nan
    return h


def test_write_dsm_in_strips_reads_back(monkeypatch, tmp_path):
    h = _surface(rows=50, cols=30)
    seen = np.ones(h.shape, bool)
    seen[:, :3] = False
    mask = np.where(np.isfinite(h), 1, 0).astype(np.uint8)
    quality = np.where(np.isfinite(h), 3, 0).astype(np.uint8)
    d = Dsm(h, (5.0, 0.0, 500000.0, 0.0, -5.0, 4000000.0), "EPSG:32631", "ellipsoidal", 0.8,
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
