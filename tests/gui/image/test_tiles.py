"""Which display tiles a view rectangle needs, centre first."""
from __future__ import annotations

from prismstation.gui.tiles import tiles_for_rect
from prismstation.io.raster import RasterSource


def test_tiles_for_rect_clips_and_orders_from_the_centre(pattern_tif):
    src = RasterSource(pattern_tif)  # 3000 x 2000: 6 x 4 tiles at level 1, 3 x 2 at level 2
    keys = tiles_for_rect(src, 1, (-100, -100, 5000, 5000))
    assert sorted(keys) == sorted((1, c, r) for c in range(6) for r in range(4))
    keys = tiles_for_rect(src, 2, (1100, 300, 100, 100))
    assert keys == [(2, 1, 0)]
    keys = tiles_for_rect(src, 1, (900, 900, 700, 100))  # cols 1..3, row 1; centre in col 2
    assert keys[0] == (1, 2, 1) and sorted(keys) == [(1, 1, 1), (1, 2, 1), (1, 3, 1)]
    assert tiles_for_rect(src, 1, (4000, 0, 100, 100)) == []
