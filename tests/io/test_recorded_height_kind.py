"""Which heights a raster says it holds: a DSM written here says it (tag and vertical CRS);
another raster through its CRS; a 2-D CRS says nothing."""
from __future__ import annotations

import numpy as np
import pyproj
import rasterio
from rasterio.crs import CRS
from rasterio.transform import from_origin

from prismstation.io.dsm import recorded_height_kind, vertical_crs


def _raster(path, crs, tags=None):
    with rasterio.open(path, "w", driver="GTiff", width=4, height=4, count=1, dtype="float32", crs=crs,
                       transform=from_origin(500000, 4500000, 10, 10), GEOTIFF_VERSION="1.1") as ds:
        ds.write(np.zeros((1, 4, 4), np.float32))
        if tags:
            ds.update_tags(**tags)
    return path


def test_recorded_height_kinds(tmp_path):
    utm = "EPSG:32629"
    assert recorded_height_kind(_raster(tmp_path / "a.tif", vertical_crs(utm, "ellipsoidal"))) == "ellipsoidal"
    assert recorded_height_kind(_raster(tmp_path / "b.tif", vertical_crs(utm, "orthometric", "constant 55 m"))) \
        == "orthometric"
    egm96 = CRS.from_wkt(pyproj.CRS("EPSG:32629+5773").to_wkt())
    assert recorded_height_kind(_raster(tmp_path / "c.tif", egm96)) == "orthometric"
    assert recorded_height_kind(_raster(tmp_path / "d.tif", "EPSG:4979")) == "ellipsoidal"  # 3-D geographic
    assert recorded_height_kind(_raster(tmp_path / "e.tif", utm, {"HEIGHTS": "orthometric"})) == "orthometric"
    assert recorded_height_kind(_raster(tmp_path / "f.tif", utm)) is None               # says nothing
    assert recorded_height_kind(tmp_path / "missing.tif") is None
    (tmp_path / "g.tif").write_text("not a raster")
    assert recorded_height_kind(tmp_path / "g.tif") is None


def test_a_fifo_or_a_folder_says_nothing_and_does_not_hang(tmp_path):
    import os
    fifo = tmp_path / "dsm.tif"
    os.mkfifo(fifo)
    assert recorded_height_kind(fifo) is None      # (opening it for reading would block)
    assert recorded_height_kind(tmp_path) is None
