"""Point transfer on real texture warped by known affine transforms (truth = the warp)."""
import numpy as np
import pytest
import rasterio
from scipy import ndimage

from prismstation.core.matching.matching import match_point


@pytest.fixture(scope="module")
def texture(shared_data):
    with rasterio.open(shared_data / "pleiades_triplet" / "img_02.tif") as ds:
        img = ds.read(1)
    assert img.dtype == np.uint16
    return img


def warp_case(img, p, A, t, noise, rng, half=60):
    """Search crop made from ``img`` by q = A (p' - p) + p + t (continuous coords, docs/model.md §1).

    Returns the reference crop, the point in it, the search crop and the true position in it.
    """
    p = np.asarray(p, float)
    r0 = (np.floor(p) - half).astype(int)
    ref = img[r0[1]:r0[1] + 2 * half, r0[0]:r0[0] + 2 * half].astype(float)
    s0 = np.floor(p + t) - half
    oy, ox = np.mgrid[0:2 * half, 0:2 * half]
    q = np.stack([ox + 0.5 + s0[0], oy + 0.5 + s0[1]], -1)
    src = (q - p - t) @ np.linalg.inv(A).T + p
    srch = ndimage.map_coordinates(img.astype(float), [src[..., 1] - 0.5, src[..., 0] - 0.5],
                                   order=3, mode="reflect")
    ref = ref + rng.normal(0, noise, ref.shape)
    srch = srch + rng.normal(0, noise, srch.shape)
    u16 = lambda a: np.clip(np.rint(a), 0, 65535).astype(np.uint16)  # noqa: E731
    return u16(ref), p - r0, u16(srch), p + t - s0


def rot(deg, scale=1.0):
    a = np.radians(deg)
    return scale * np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


def test_subpixel_affine_cases_are_recovered(texture):
    rng = np.random.default_rng(7)
    errs = []
    for _ in range(12):
        p = rng.uniform(100, 900, 2)
        A = rot(rng.uniform(-2, 2), 1 + rng.uniform(-0.02, 0.02))
        t = rng.uniform(-0.5, 0.5, 2)
        ref, pt, srch, truth = warp_case(texture, p, A, t, noise=5.0, rng=rng)
        d = np.array([np.cos(0.3), np.sin(0.3)])
        pred = truth + 2.5 * d
        r = match_point(ref, *pt, srch, *pred, direction=d, search_range=6)
        assert r.ok, r.reason
        assert 0.5 < r.score <= 1.0
        assert 0 < r.formal_sigma_x < 0.1 and 0 < r.formal_sigma_y < 0.1
        assert r.sigma_x > r.formal_sigma_x and r.sigma_y > r.formal_sigma_y  # calibrated
        errs.append(np.hypot(r.x - truth[0], r.y - truth[1]))
    rms = np.sqrt(np.mean(np.square(errs)))
    assert rms < 0.03, rms         # measured ~0.01 px; NCC alone gives ~0.25 px on these
    assert max(errs) < 0.1


def test_pure_shift_along_a_direction_and_point_off_pixel_centre(texture):
    # search = reference moved by exactly (+3, -2) px: no interpolation in the truth
    ref = texture[200:400, 300:500]
    srch = texture[202:402, 297:497]
    x, y = 100.3, 90.8                       # not a pixel centre
    r = match_point(ref, x, y, srch, x + 1.0, y - 1.0, direction=(3, -2), search_range=8)
    assert r.ok, r.reason
    assert r.x == pytest.approx(x + 3, abs=0.01)
    assert r.y == pytest.approx(y - 2, abs=0.01)
    assert r.score > 0.99


def test_match_outside_the_search_range_is_reported_at_border(texture):
    ref = texture[200:400, 300:500]
    srch = texture[200:400, 290:490]         # true shift +10 px in x
    r = match_point(ref, 100.5, 100.5, srch, 100.5, 100.5, direction=(1, 0), search_range=4)
    assert not r.ok
    assert r.status in ("border", "low_score")


def test_flat_and_unrelated_images_fail_with_a_reason(texture):
    flat = np.full((200, 200), 1000, np.uint16)
    r = match_point(flat, 100, 100, texture[:200, :200], 100, 100)
    assert r.status == "flat" and r.reason
    rng = np.random.default_rng(0)
    noise = rng.integers(0, 4000, (200, 200)).astype(np.uint16)
    r = match_point(texture[300:500, 300:500], 100, 100, noise, 100, 100, search_range=3)
    assert not r.ok and r.status in ("low_score", "flat", "border")


def test_point_too_close_to_the_edge_is_outside(texture):
    r = match_point(texture, 3.0, 3.0, texture, 3.0, 3.0)
    assert r.status == "outside"


def test_texture_varying_in_one_direction_only_is_ambiguous():
    # stripes constant along y: y is undetermined whatever the search direction
    rng = np.random.default_rng(0)
    stripes = 1000 + 300 * np.sin(np.arange(200) / 3.0) + 200 * np.sin(np.arange(200) / 7.3)
    a = (stripes[None, :] + rng.normal(0, 5, (200, 200))).astype(np.uint16)
    b = (stripes[None, :] + rng.normal(0, 5, (200, 200))).astype(np.uint16)
    for d in [(0, 1), None]:
        r = match_point(a, 100.5, 100.5, b, 100.5, 101.5, direction=d, search_range=5)
        assert r.status == "flat", (d, r)


def test_transfer_a_grid_and_reject_a_planted_blunder(texture):
    from prismstation.core.matching.matching import blunder_mask, transfer_points
    ref = texture[100:600, 100:600]
    srch = texture[104:604, 99:599]                 # content moved by (+1, -4) px
    gx, gy = np.meshgrid(np.arange(80.5, 430, 70), np.arange(80.5, 430, 70))
    pts = np.column_stack([gx.ravel(), gy.ravel()])
    d = (0.0, 1.0)                                  # parallax along y, offset across = +1 px
    pred = pts + [0.0, -2.0]
    pred[7] += [6.0, 0.0]                           # a wrong prediction 6 px across
    res = transfer_points(ref, srch, pts, pred, d, search_range=5, across_range=8.0)
    xy = np.array([[r.x, r.y] for r in res])
    ok = np.array([r.ok for r in res])
    assert ok.mean() > 0.9
    assert np.allclose(xy[ok], (pts + [1.0, -4.0])[ok], atol=0.02)
    # the blunder: pretend point 7 matched a wrong place 5 px across
    from dataclasses import replace
    res[7] = replace(res[7], x=res[7].x + 5.0)
    bad = blunder_mask(res, pred, d)
    assert bad[7] and bad.sum() == (~ok).sum() + (1 if ok[7] else 0)
