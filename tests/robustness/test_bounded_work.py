"""Work bounded by what the inputs really cover: a DEM is read over the window the project
needs (never whole when it declares 100,000 × 100,000 cells), the DSM grid covers only the
ground the three images share, the PDF report lists a bounded number of points."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

from prismstation.errors import InputError
from prismstation.io.dem import read_dem
from prismstation.io.report_html import listed_points, report_html


def _huge_dem(path):
    """A tiled GeoTIFF declaring 100,000 × 100,000 cells of 30 m with one block written (a
    sparse file: the tile index only)."""
    with rasterio.open(path, "w", driver="GTiff", width=100_000, height=100_000, count=1, dtype="int16",
                       crs="EPSG:32629", transform=from_origin(400_000, 4_500_000, 30, 30), tiled=True,
                       blockxsize=256, blockysize=256, compress="deflate", sparse_ok=True, nodata=-32768) as ds:
        ds.write(np.full((1, 256, 256), 120, np.int16), window=rasterio.windows.Window(0, 0, 256, 256))


def test_a_huge_dem_is_read_only_where_it_is_needed(tmp_path):
    dem = tmp_path / "huge.tif"
    _huge_dem(dem)
    assert dem.stat().st_size < 4 << 20  # the tile index only
    grid = read_dem(dem, "EPSG:32629", (30.0, 0.0, 400_300.0, 0.0, -30.0, 4_499_700.0), (100, 100))
    assert grid.heights.shape == (100, 100) and np.nanmax(grid.heights) == 120
    with pytest.raises(InputError, match="too large to read"):
        read_dem(dem)  # whole: refused, not a 80 GB allocation


def test_the_dsm_grid_covers_only_the_ground_the_images_share(sim):
    """N declaring an image a hundred times larger than it is: the DSM's footprint stays that
    of F and B (before, the grid followed N's declared size)."""
    from prismstation.io.project import load_project
    from prismstation.ops.dsm import plan_dsm
    from prismstation.ops.fit import solve_project
    project = load_project(sim / "p.prismproj")
    sol = solve_project(project)
    true = plan_dsm(sol, None, 10.0, False, None)
    sc = sol.scene
    big = dataclasses.replace(sc.views["N"], shape=tuple(100 * s for s in sc.views["N"].shape))
    sol_big = dataclasses.replace(sol, scene=dataclasses.replace(sc, views={**sc.views, "N": big}))
    plan = plan_dsm(sol_big, None, 10.0, False, None)
    area = lambda foot: float(np.prod(np.ptp(foot, axis=0)))  # noqa: E731
    assert area(plan.foot) <= 1.5 * area(true.foot)


def test_the_document_lists_a_bounded_number_of_points():
    pts = [{"id": f"T{i}", "kind": "TIE"} for i in range(5000)]
    pts[4000] = {"id": "G1", "kind": "GCP", "E_known": 1.0, "N_known": 2.0}
    pts[4500] = {"id": "B1", "kind": "TIE", "blunder": True}
    listed, note = listed_points(pts, 100)
    assert len(listed) == 100 and {"G1", "B1"} <= {p["id"] for p in listed}
    assert "100 of the 5,000 points" in note
    assert listed_points(pts[:50], 100) == (pts[:50], None)
    html = report_html({"points": pts}, max_points=100)
    assert html.count("<td>T") <= 2 * 100 and "100 of the 5,000 points" in html
