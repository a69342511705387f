"""Arrays only (numpy, scipy, OpenCV), by subject: the sensor models (:mod:`.models`), matching
(:mod:`.matching`), least squares and statistics (:mod:`.adjustment`), orientation from a
reference DEM (:mod:`.orientation`), heights on grids (:mod:`.surfaces`). No file, no CRS
(rasterio and pyproj live in :mod:`prismstation.io`).

Conventions every module here follows: image ``(x, y)`` = (column, row) with the pixel centre
at ``+0.5``, map ``(E, N)`` metres, heights ellipsoidal unless named (docs/model.md §1); a
result that can fail is falsy with a ``reason`` (:mod:`prismstation.core.adjustment.estimate`,
"Failure as a value").
"""
