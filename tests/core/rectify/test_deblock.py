"""JPEG block-noise reduction on real JPEG compression (cv2.imencode)."""
import cv2
import numpy as np
import pytest

from prismstation.core.matching.deblock import blockiness, deblock
from prismstation.errors import ModelError


def _jpeg(img, quality):
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, quality])
    assert ok
    return cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)


def _rmse(a, b):
    return float(np.sqrt(np.mean((a.astype(float) - b.astype(float)) ** 2)))


def _smooth_scene(shape=(512, 512), seed=0):
    """Paddy fields / water: smooth low-contrast texture where JPEG blocks show most."""
    rng = np.random.default_rng(seed)
    noise = rng.normal(0, 1, shape).astype(np.float32)
    img = cv2.GaussianBlur(noise, (0, 0), 6)
    img = 128 + 40 * img / img.std()
    return np.clip(img, 0, 255).astype(np.uint8)


def _real_crop(shared_data):
    import rasterio

    with rasterio.open(shared_data / "pleiades_triplet" / "img_01.tif") as ds:
        a = ds.read(1).astype(float)
    lo, hi = np.percentile(a, [1, 99])
    return np.clip((a - lo) / (hi - lo) * 255, 0, 255).astype(np.uint8)


def test_blockiness_metric():
    img = _smooth_scene()
    assert blockiness(img) == pytest.approx(1.0, abs=0.1)       # no block structure
    blocky = img.astype(float)
    blocky += np.kron(np.random.default_rng(1).normal(0, 6, (64, 64)), np.ones((8, 8)))
    assert blockiness(blocky) > 1.5


@pytest.mark.parametrize("quality", [10, 20, 40])
def test_deblock_smooth_scene(quality):
    img = _smooth_scene()
    jpg = _jpeg(img, quality)
    out = deblock(jpg)
    assert out.dtype == np.uint8 and out.shape == jpg.shape
    assert blockiness(jpg) > 1.3
    assert blockiness(out) < 0.75 * blockiness(jpg)
    assert _rmse(out, img) <= _rmse(jpg, img)


@pytest.mark.parametrize("quality", [20, 40])
def test_deblock_real_imagery(shared_data, quality):
    img = _real_crop(shared_data)
    jpg = _jpeg(img, quality)
    out = deblock(jpg)
    assert blockiness(out) < 0.92 * blockiness(jpg)
    assert _rmse(out, img) <= _rmse(jpg, img) + 1e-9


def test_real_edges_are_left_alone():
    img = np.full((64, 64), 60, np.uint8)
    img[:, 32:] = 200          # a real edge on a block boundary
    img[40:, :] += 0           # flat elsewhere
    assert np.array_equal(deblock(img), img)
    small = np.full((64, 64), 100, np.uint8)
    small[:, 24:] = 106        # a small step in flat surroundings: an artefact, ramped
    out = deblock(small).astype(int)
    assert np.all(np.diff(out[0]) >= 0) and np.abs(np.diff(out[0])).max() <= 3
    assert out[0, 0] == 100 and out[0, -1] == 106


def test_16x8_blocks_and_other_dtypes():
    img = _smooth_scene((256, 512))
    jpg = _jpeg(img, 15)
    out = deblock(jpg, block=(8, 16))
    # vertical boundaries only every 16 columns: those at 8 mod 16 are left
    assert blockiness(out, block=(8, 16)) < blockiness(jpg, block=(8, 16))
    f = deblock(jpg.astype(np.float32) * 4.0)    # float, another range: thresholds scale
    assert f.dtype == np.float32
    assert blockiness(f) < blockiness(jpg)
    with pytest.raises(ModelError):
        deblock(np.zeros((4, 4, 3)))
