"""Dense parallax from a synthetic F/B pair made from real texture with a known parallax field."""
import numpy as np
import pytest
import rasterio
from scipy import ndimage

from prismstation.core.dense import heights_from_parallax, parallax_map


def py_true(x, y):
    """Known smooth parallax field (N-image pixels) at N coordinates."""
    return (4 * np.exp(-((x - 200) ** 2 + (y - 210) ** 2) / (2 * 70 ** 2))
            - 3 * np.exp(-((x - 100) ** 2 + (y - 300) ** 2) / (2 * 50 ** 2)) + 0.004 * x)


@pytest.fixture(scope="module")
def texture(shared_data):
    with rasterio.open(shared_data / "pleiades_triplet" / "img_03.tif") as ds:
        t = ds.read(1, window=((0, 800), (0, 800))).astype(float)
    return ndimage.spline_filter(ndimage.gaussian_filter(t, 1.0)[::2, ::2], 3)


def render(coeffs, sign, d, offset):
    """View image whose pixel at view coords q shows the ground point at N position pN, with
    q + offset = pN + sign·py(pN)/2·d (so F − B = py along d, midpoint at N)."""
    rows, cols = coeffs.shape
    jj, ii = np.mgrid[0:rows, 0:cols].astype(float)
    qx, qy = ii + 0.5 + offset[0], jj + 0.5 + offset[1]
    px, py = qx.copy(), qy.copy()
    for _ in range(12):
        p = py_true(px, py)
        px, py = qx - sign * p / 2 * d[0], qy - sign * p / 2 * d[1]
    return ndimage.map_coordinates(coeffs, [py - 0.5, px - 0.5], order=3, prefilter=False,
                                   mode="reflect").astype(np.float32)


@pytest.mark.parametrize("angle", [0.0, 20.0])
def test_parallax_field_is_recovered(texture, angle):
    d = np.array([np.cos(np.radians(angle)), np.sin(np.radians(angle))])
    f = render(texture, +1, d, (0.0, 0.0))
    b = render(texture, -1, d, (3.0, -2.0))          # B array coords + (3, -2) = N coords
    calls = []
    r = parallax_map(f, b, [[1, 0, 0], [0, 1, 0]], [[1, 0, 3.0], [0, 1, -2.0]],
                     (50, 40, 300, 320), d, search_range=8, block_rows=100,
                     progress=lambda x: calls.append(x) or True)
    assert r.parallax.shape == (320, 300) and not r.cancelled
    jj, ii = np.mgrid[0:320, 0:300]
    err = r.parallax - py_true(ii + 50.5, jj + 40.5)
    assert r.valid_fraction > 0.9
    assert np.sqrt(np.nanmean(err ** 2)) < 0.2           # measured ~0.06 px
    assert abs(np.nanmean(err)) < 0.05
    assert calls[-1] == pytest.approx(1.0) and len(calls) >= 3


def test_prior_shifts_the_search_and_cancel_stops(texture):
    d = np.array([1.0, 0.0])
    f = render(texture, +1, d, (0.0, 0.0))
    b = render(texture, -1, d, (0.0, 0.0))
    # a true parallax beyond the search range is missed without a prior, found with it
    b_far = np.roll(b, -10, axis=1)                     # B content 10 px further left: py + 10
    win = (60, 60, 200, 200)
    miss = parallax_map(f, b_far, np.eye(2, 3), np.eye(2, 3), win, d, search_range=7)
    hit = parallax_map(f, b_far, np.eye(2, 3), np.eye(2, 3), win, d, search_range=7, prior=10.0)
    jj, ii = np.mgrid[0:200, 0:200]
    # a point's midpoint pF − py/2 moved by −10/2 px along x with the extra 10 px of parallax
    truth = py_true(ii + 60.5 + 5, jj + 60.5) + 10
    assert miss.valid_fraction < 0.3
    assert hit.valid_fraction > 0.8
    assert np.nanmedian(np.abs(hit.parallax - truth)) < 0.3
    stop = parallax_map(f, b, np.eye(2, 3), np.eye(2, 3), win, d, block_rows=50,
                        progress=lambda x: False)
    assert stop.cancelled and stop.valid_fraction < 0.5


def test_flat_images_give_nan_and_heights_follow_the_line():
    flat = np.full((120, 120), 7.0, np.float32)
    r = parallax_map(flat, flat, np.eye(2, 3), np.eye(2, 3), (20, 20, 60, 60), (0, 1))
    assert r.valid_fraction == 0.0
    h = heights_from_parallax(np.array([0.0, 10.0, np.nan]), 100.0, 2.496)
    assert h[0] == 100.0 and h[1] == pytest.approx(124.96) and np.isnan(h[2])
