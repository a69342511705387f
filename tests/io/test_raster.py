"""RasterSource: windows, decimated reads, tiles, cache, statistics, overviews, errors (no Qt)."""
from __future__ import annotations

import threading

import numpy as np
import pytest
import rasterio
from rasterio.windows import Window

from prismstation.errors import RasterReadError
from prismstation.io.raster import TILE_SIZE, RasterSource

from tests.io.conftest import H, W, pattern


def test_metadata(pattern_tif, pattern_tif16):
    src = RasterSource(pattern_tif)
    assert (src.width, src.height) == (W, H)
    assert src.dtype == np.uint8
    assert src.levels == (1, 2, 4, 8)
    assert RasterSource(pattern_tif16).dtype == np.uint16


def test_full_resolution_window_matches_pattern(pattern_tif16):
    src = RasterSource(pattern_tif16)
    arr = src.read((1234, 567, 40, 30))
    yy, xx = np.mgrid[567:597, 1234:1274]
    np.testing.assert_array_equal(arr, pattern(xx, yy, np.uint16))


def test_decimated_read_uses_the_overview(pattern_tif):
    src = RasterSource(pattern_tif)
    arr = src.read((0, 0, 1024, 1024), (256, 256))
    with rasterio.open(pattern_tif, overview_level=1) as ov:  # factor 4
        ref = ov.read(1, window=Window(0, 0, 256, 256))
    np.testing.assert_array_equal(arr, ref)


def test_tiles_are_cached_and_bounded(pattern_tif):
    src = RasterSource(pattern_tif, cache_mb=0.6)
    t = src.read_tile(1, 2, 1)
    x, y, w, h = src.tile_rect(1, 2, 1)
    assert (x, y, w, h) == (2 * TILE_SIZE, TILE_SIZE, TILE_SIZE, TILE_SIZE)
    yy, xx = np.mgrid[y:y + h, x:x + w]
    np.testing.assert_array_equal(t, pattern(xx, yy))
    assert src.cached_tile(1, 2, 1) is t
    # edge tile is clipped to the image
    last = src.read_tile(2, 2, 1)
    assert last.shape == (np.ceil((H - 1024) / 2), np.ceil((W - 2048) / 2))
    for c in range(4):
        src.read_tile(1, c, 0)
    assert src.cache.nbytes <= 0.6 * 1024 * 1024
    assert src.cached_tile(1, 2, 1) is None  # least recently used went first


def test_read_pixels_outside_is_filled(pattern_tif):
    src = RasterSource(pattern_tif)
    arr = src.read_pixels(-3, -2, 8, 6, fill=0)
    yy, xx = np.mgrid[0:4, 0:5]
    np.testing.assert_array_equal(arr[2:, 3:], pattern(xx, yy))
    assert not arr[:2].any() and not arr[:, :3].any()


def test_threads_get_their_own_handles(pattern_tif):
    src = RasterSource(pattern_tif, cache_mb=0)
    errors = []

    def work(i):
        try:
            for k in range(5):
                a = src.read((i * 100 + k, 50, 64, 64))
                yy, xx = np.mgrid[50:114, i * 100 + k:i * 100 + k + 64]
                assert np.array_equal(a, pattern(xx, yy))
        except Exception as exc:  # noqa: BLE001
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    [t.start() for t in threads]
    [t.join() for t in threads]
    assert not errors
    assert len({id(d) for d in src._handles}) == len(src._handles) >= 4


def test_statistics_from_coarse_read(pattern_tif):
    src = RasterSource(pattern_tif)
    st = src.statistics((0.5, 50, 99.5))
    arr, f = src.coarse()
    assert f == 4 and arr.shape == (500, 750)
    # the pattern is close to uniform on 0..250
    assert st.minimum == 0 and st.maximum == 250
    assert abs(st.percentiles[50.0] - 125) < 5
    assert st.histogram.sum() == arr.size


def test_missing_and_unreadable_files(tmp_path):
    with pytest.raises(RasterReadError, match="nope.tif"):
        RasterSource(tmp_path / "nope.tif")
    bad = tmp_path / "bad.tif"
    bad.write_bytes(b"not a tiff at all")
    with pytest.raises(RasterReadError, match="bad.tif"):
        RasterSource(bad)


def test_build_overviews_external_with_progress_and_cancel(plain_tif):
    src = RasterSource(plain_tif)
    assert src.levels == (1,)
    seen = []
    assert src.build_overviews(lambda f: seen.append(f) or len(seen) < 2) is False
    assert not (plain_tif.parent / "plain.tif.ovr").exists()
    seen.clear()
    assert src.build_overviews(lambda f: seen.append(f) or True) is True
    assert seen[0] == 0 and seen[-1] == 1.0 and seen == sorted(seen)
    assert (plain_tif.parent / "plain.tif.ovr").exists()
    assert src.levels == (1, 2, 4, 8)
    assert RasterSource(plain_tif).levels == (1, 2, 4, 8)


def test_reading_a_raster_changes_no_gdal_setting(pattern_tif, monkeypatch):
    """Readers set nothing process-wide (they did: GDAL_CACHEMAX, on creating one)."""
    from types import SimpleNamespace

    from rasterio.env import get_gdal_config

    from prismstation.io.windows import ImageWindows

    monkeypatch.delenv("GDAL_CACHEMAX", raising=False)
    before = get_gdal_config("GDAL_CACHEMAX")
    RasterSource(pattern_tif).read((0, 0, 8, 8))
    with ImageWindows(SimpleNamespace(views={"N": SimpleNamespace(image=str(pattern_tif))})) as w:
        assert w.read("N", 0, 0, 8, 8)[0].shape == (8, 8)
    assert get_gdal_config("GDAL_CACHEMAX") == before


@pytest.mark.parametrize("user", [None, "64"])
def test_the_command_line_bounds_gdal_cache_while_it_runs(monkeypatch, user):
    """The entry point scopes GDAL's configuration (a rasterio Env): GDAL's default cache (5 %
    of RAM) would fill with blocks a windowed reader reads once; GDAL_CACHEMAX set by the
    user is left as it is."""
    from rasterio.env import get_gdal_config

    import prismstation.cli.bh as bh
    from prismstation.cli import main
    from prismstation.io import raster

    if user is None:
        monkeypatch.delenv("GDAL_CACHEMAX", raising=False)
    else:
        monkeypatch.setenv("GDAL_CACHEMAX", user)
    before = get_gdal_config("GDAL_CACHEMAX")
    seen = []
    monkeypatch.setattr(bh, "run", lambda args: seen.append(int(get_gdal_config("GDAL_CACHEMAX"))) or 0)
    assert main(["bh", "--left", "0", "0", "0", "--right", "1", "1", "1"]) == 0
    if user is None:
        assert seen == [raster.GDAL_CACHE_MB * 1024 * 1024]
    else:
        assert seen == [int(before)]
    assert get_gdal_config("GDAL_CACHEMAX") == before


def test_each_dsm_tile_reads_under_the_bounded_cache(monkeypatch):
    """A Dask worker may be another process, outside any entry point."""
    from rasterio.env import get_gdal_config

    from prismstation.io import raster
    from prismstation.ops import dsm_tiles

    monkeypatch.delenv("GDAL_CACHEMAX", raising=False)
    seen = []

    def read(*a, **k):
        seen.append(int(get_gdal_config("GDAL_CACHEMAX")))
        raise RuntimeError("enough")
    monkeypatch.setattr(dsm_tiles, "_read_views", read)
    monkeypatch.setattr(dsm_tiles, "frame_over", lambda *a, **k: None)
    monkeypatch.setattr(dsm_tiles, "_prior_on_frame", lambda *a, **k: np.zeros((2, 2), np.float32))
    from types import SimpleNamespace
    sol = SimpleNamespace(scene=SimpleNamespace(views={"N": SimpleNamespace(pixel_size_m=2.5)}))
    spec = dsm_tiles.TileSpec(sol, (0, 0, 2, 2), (5.0, 0, 0, 0, -5.0, 0), 5.0, 10.0, None, None)
    with pytest.raises(RuntimeError, match="enough"):
        dsm_tiles.run_tile(spec)
    assert seen == [raster.GDAL_CACHE_MB * 1024 * 1024]


@pytest.mark.parametrize("factor, window", [(1, (3, 5, 40, 30)), (3, (0, 0, 10000, 10000)),
                                            (4, (-7.5, 13.2, 301, 257)), (5, (1, 1, 4, 4))])
def test_reduced_window_reads_are_block_means_read_in_strips(pattern_tif16, factor, window, monkeypatch):
    """The DSM's coarse levels read whole images reduced: strips of rows give the block
    means of the whole window, cropped to whole blocks, at the same origin."""
    from types import SimpleNamespace

    from prismstation.io import windows
    from prismstation.io.windows import ImageWindows

    monkeypatch.setattr(windows, "READ_STRIP_ROWS", 50)     # several strips, a short last one
    with ImageWindows(SimpleNamespace(views={"N": SimpleNamespace(image=str(pattern_tif16))})) as w:
        full, c0, r0 = w.read("N", *window)
        red, c1, r1 = w.read_reduced("N", *window, factor)
    assert (c1, r1) == (c0, r0)
    if factor * 1 > min(full.shape):
        assert red is None
        return
    rows, cols = full.shape[0] // factor, full.shape[1] // factor
    blocks = full[:rows * factor, :cols * factor].reshape(rows, factor, cols, factor).mean(axis=(1, 3))
    np.testing.assert_allclose(red, blocks, rtol=1e-5)


@pytest.mark.parametrize("dtype, top", [(np.uint8, 256), (np.uint16, 4000), (np.uint16, 65536)])
def test_integer_statistics_match_numpy(dtype, top):
    from prismstation.io.raster import _integer_statistics

    rng = np.random.default_rng(int(top))
    for n in (1, 2, 7, 12345):
        v = rng.integers(0, top, n).astype(dtype)
        p = (0, 0.5, 2, 37.3, 50, 98, 99.5, 100)
        pct, lo, hi, hist, edges = _integer_statistics(v, p, 256)
        np.testing.assert_allclose(pct, np.percentile(v, p))
        ref_hist, ref_edges = np.histogram(v, bins=256, range=(lo, hi if hi > lo else lo + 1))
        np.testing.assert_allclose(edges, ref_edges)
        np.testing.assert_array_equal(hist, ref_hist)
        assert (lo, hi) == (v.min(), v.max())


def test_window_outside_the_image_is_a_clear_error(pattern_tif):
    src = RasterSource(pattern_tif)
    with pytest.raises(RasterReadError, match="pattern_u8.tif.*outside"):
        src.read((W + 10, 0, 100, 100))


def test_build_overviews_internal(plain_tif):
    src = RasterSource(plain_tif)
    assert src.build_overviews(factors=[2, 4], external=False) is True
    assert not (plain_tif.parent / "plain.tif.ovr").exists()
    assert src.levels == (1, 2, 4)
    with rasterio.open(plain_tif, overview_level=0) as ov:
        assert (ov.width, ov.height) == (W // 2, H // 2)


def test_build_overviews_refuses_a_read_only_folder(plain_tif):
    folder = plain_tif.parent
    folder.chmod(0o555)
    try:
        with pytest.raises(RasterReadError, match="plain.tif.*read-only"):
            RasterSource(plain_tif).build_overviews()
        assert not (folder / "plain.tif.ovr").exists()
    finally:
        folder.chmod(0o755)
