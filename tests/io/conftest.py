"""Fixtures: small GeoTIFFs with a known pattern (value a function of column x and row y);
the window's image tests use them too (tests/gui/image/conftest.py)."""
from __future__ import annotations

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

W, H = 3000, 2000


def pattern(x, y, dtype=np.uint8):
    """Known pixel value at column ``x``, row ``y`` (integer arrays), neighbours all differ."""
    x = np.asarray(x, dtype=np.int64)
    y = np.asarray(y, dtype=np.int64)
    if np.dtype(dtype) == np.uint8:
        return ((x * 7 + y * 13) % 251).astype(np.uint8)
    return ((x * 37 + y * 101) % 65521).astype(np.uint16)


def write_pattern(path, dtype=np.uint8, width=W, height=H, overviews=(2, 4, 8)):
    yy, xx = np.mgrid[0:height, 0:width]
    data = pattern(xx, yy, dtype)
    with rasterio.open(path, "w", driver="GTiff", width=width, height=height, count=1,
                       dtype=np.dtype(dtype).name, tiled=True, blockxsize=256, blockysize=256,
                       compress="deflate", crs="EPSG:32629",
                       transform=from_origin(500000, 4600000, 2.5, 2.5)) as ds:
        ds.write(data, 1)
        if overviews:
            ds.build_overviews(list(overviews), rasterio.enums.Resampling.nearest)
    return path


@pytest.fixture(scope="session")
def pattern_tif(tmp_path_factory):
    return write_pattern(tmp_path_factory.mktemp("raster") / "pattern_u8.tif")


@pytest.fixture(scope="session")
def pattern_tif16(tmp_path_factory):
    return write_pattern(tmp_path_factory.mktemp("raster") / "pattern_u16.tif", np.uint16)


@pytest.fixture()
def plain_tif(tmp_path):
    """A copy of the pattern without overviews (for building them)."""
    return write_pattern(tmp_path / "plain.tif", overviews=())
