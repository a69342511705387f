"""The engine's pixel readers the window's tools call (point transfer, automatic tie points, the
coarse view offsets) on a truncated or bit-flipped tiled GeoTIFF: the project's
:class:`RasterReadError` naming the file and the place, never a match, an offset or a
"not found" made of a read that failed."""
from __future__ import annotations

import pytest

from prismstation.errors import RasterReadError
from tests.robustness import faults as ft

pytestmark = pytest.mark.filterwarnings("ignore")


def _solution(sim):
    from prismstation.io.project import load_project
    from prismstation.ops.fit import solve_project
    return solve_project(load_project(sim / "p.prismproj"))


def _transfer(sol, images):
    from prismstation.ops.transfer import transfer
    return transfer(sol, images, "N", (500.0, 500.0))


def _auto_ties(sol, images):
    from prismstation.ops.tie_points import auto_tie_points
    return auto_tie_points(sol, images, grid=2)


@pytest.mark.parametrize("how", list(ft.BREAKS))
@pytest.mark.parametrize("broken", ["N.tif", "F.tif"])
@pytest.mark.parametrize("call", [_transfer, _auto_ties], ids=["transfer", "auto-ties"])
def test_point_transfer_on_a_broken_image(sim, call, broken, how):
    from prismstation.io.windows import ImageWindows
    sol = _solution(sim)
    ft.BREAKS[how](sim / broken)
    images = ImageWindows(sol.scene)
    try:
        with pytest.raises(RasterReadError) as err:
            call(sol, images)
    finally:
        images.close()
    msg = str(err.value)
    view = broken[0]
    assert broken in msg and f"view {view}" in msg and "window" in msg, msg


@pytest.mark.parametrize("how", list(ft.BREAKS))
@pytest.mark.parametrize("broken", ["N.tif", "srtm_tiled.tif"])
def test_coarse_offsets_on_a_broken_raster(sim, broken, how):
    from prismstation.io.scene import read_scene
    from prismstation.ops.coarse_offsets import coarse_view_offsets
    ft.BREAKS[how](sim / broken)
    scene = read_scene(sim / "scene.json")
    with pytest.raises(RasterReadError) as err:
        coarse_view_offsets(scene, sim / "srtm_tiled.tif", 55.0, sigma_apriori_m=60.0, grid=2)
    assert broken in str(err.value), err.value


def test_a_tile_failure_crosses_a_process_boundary():
    """A DSM tile's read error, chained to GDAL's exception where it was caught, reaches the
    caller of a process pool as the project's error: once tblib's pickling is installed
    after rasterio's exceptions exist (as Dask's process pool does), a chained GDAL exception
    fails to unpickle — the tile runner sends the error without its chain."""
    import pickle

    import tblib.pickling_support
    from rasterio._err import CPLE_AppDefinedError

    from prismstation.errors import RasterReadError
    from prismstation.ops.dsm_tiles import _portable
    tblib.pickling_support.install()

    def tile(spec):
        try:
            raise CPLE_AppDefinedError(3, 1, "TIFFFillTile:Read error")
        except Exception:
            raise RasterReadError(f"F.tif: cannot read view F, for the DSM tile {spec}") from None

    with pytest.raises(RasterReadError) as err:
        _portable(tile, 7)
    back = pickle.loads(pickle.dumps(err.value))
    assert isinstance(back, RasterReadError) and "F.tif" in str(back) and "tile 7" in str(back)
