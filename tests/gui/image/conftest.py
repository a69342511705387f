"""Fixtures: the pattern GeoTIFFs of tests/io/conftest.py, and an ImageView on one."""
from __future__ import annotations

import pytest

from tests.io.conftest import H, W, pattern, pattern_tif, pattern_tif16, plain_tif, write_pattern  # noqa: F401


@pytest.fixture()
def view(qtbot, pattern_tif):  # noqa: F811 (the fixture imported above)
    """An ImageView (600 × 400, shown) on the pattern GeoTIFF, grey levels 0–255."""
    from prismstation.gui.image_view import ImageView
    from prismstation.io.raster import RasterSource
    v = ImageView()
    qtbot.addWidget(v)
    v.resize(600, 400)
    v.show()
    qtbot.waitExposed(v)
    v.set_source(RasterSource(pattern_tif))
    v.set_levels(0, 255)
    yield v
    v.close()
