"""The DSM of images with RPCs written tile by tile, whatever its size: what ``prismstation
dsm`` and the window's Export DSM write for a project of images with RPCs
(:func:`prismstation.ops.rpc_project.export_dsm` gives them the project's files and models).

The steps are :func:`prismstation.ops.rpc_dsm.rpc_dsm`'s (the plan, the tiles, each tile's
pairs matched and fused as a Dask task by :func:`prismstation.ops.dsm_tiles.run_tiles`); each
tile's heights go into the DSM's scratch GeoTIFF as they arrive
(:func:`prismstation.io.dsm.write_dsm_tiles`), made orthometric there when asked; ``fill``
then fills the voids block by block, reading the scratch copy back
(:func:`prismstation.core.surfaces.dsm_grid.fill_voids_in_blocks`). Nothing grid-sized is held:
the memory is that of a few tiles in flight (their images' windows and pair grids), the
reference DEM read onto the grid at a coarser step (:func:`~prismstation.ops.rpc_dsm.reference_prior`,
at most 16 MB), the agreement sample (at most 1.6 MB per two pairs) and the tiles' specs. A
cancel (``progress`` returning False) or a failure leaves no file and an existing one as it was.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from prismstation.core.surfaces.dsm_grid import FILL_BLOCK, fill_voids_in_blocks
from prismstation.io.dsm import dsm_tags, write_dsm_tiles
from prismstation.io.geoid import undulation_on_grid
from prismstation.ops.dsm import MASK_FILLED, MASK_MATCHED, Dsm
from prismstation.ops.progress import checkpoint, scaled
from prismstation.ops.rpc_dsm import (TILE_CELLS, dsm_info, match_tiles, plan_rpc_dsm, reference_prior,
                                      tile_specs)

#: share of the progress range the matching takes (the rest: filling, when asked, and writing)
MATCH_SHARE, FILL_SHARE = 0.85, 0.1


def write_rpc_dsm(output, paths, models, *, posting: float, grid=None, window=None, fill: bool = False,
                  orthometric_geoid=None, height_range=None, points=None, reference=None, geoid=None,
                  tile_cells: int = TILE_CELLS, scheduler=None, workers=None, progress=None,
                  before_keep=None) -> Dsm:
    """Compute the DSM of ``paths`` and ``models`` and write it to ``output`` tile by tile (the
    module docstring). The arguments are :func:`~prismstation.ops.rpc_dsm.rpc_dsm`'s;
    ``orthometric_geoid``: heights written above that geoid (else ellipsoidal); ``before_keep``
    as :func:`prismstation.io.cog.write_cog`'s. Returns the :class:`~prismstation.ops.dsm.Dsm`
    without its grids (``counts``: the shape and the cells seen, matched and filled; ``info``
    as :func:`~prismstation.ops.rpc_dsm.rpc_dsm`'s, the agreement from a sample)."""
    plan = plan_rpc_dsm(paths, models, posting=posting, height_range=height_range, grid=grid,
                        tile_cells=tile_cells, keep_pairs=False, window=window)
    grid = plan.grid
    specs = tile_specs(plan, reference_prior(plan, reference, geoid), points)
    kind = "ellipsoidal" if orthometric_geoid is None else "orthometric"
    geoid_name = None if orthometric_geoid is None else getattr(orthometric_geoid, "describe", lambda: "geoid")()
    record = {}

    def put_tiles(tiles):
        a, _, c, _, e, f = grid.transform

        def put(win, h, q, seen):
            r0, c0, rows, cols = win
            if orthometric_geoid is not None:
                cell = SimpleNamespace(shape=(rows, cols), crs=grid.crs,
                                       transform=(a, 0.0, c + a * c0, 0.0, e, f + e * r0))
                h = h - undulation_on_grid(orthometric_geoid, cell, max_samples=32).astype(np.float32)
            tiles.write(r0, c0, h, (np.isfinite(h) & seen).astype(np.uint8) * MASK_MATCHED, q, seen)

        share = MATCH_SHARE if fill else MATCH_SHARE + FILL_SHARE
        sums = match_tiles(plan, specs, put, scheduler=scheduler, workers=workers,
                           progress=scaled(progress, 0.0, share))
        filled = fill_tiles(tiles, grid.shape, scaled(progress, MATCH_SHARE, MATCH_SHARE + FILL_SHARE)) if fill else 0
        checkpoint(progress, MATCH_SHARE + FILL_SHARE, "writing")
        record.update(sums=sums, filled=filled)
        return dsm_tags(sums.matched, sums.seen, grid.posting, kind)

    write_dsm_tiles(output, crs=grid.crs, transform=grid.transform, shape=grid.shape, height_kind=kind,
                    geoid=geoid_name, fill=put_tiles, before_keep=before_keep)
    sums = record["sums"]
    counts = {"shape": tuple(grid.shape), "seen": sums.seen, "matched": sums.matched, "filled": record["filled"]}
    valid = (sums.matched + record["filled"]) / sums.seen if sums.seen else 0.0
    return Dsm(None, grid.transform, grid.crs, kind, valid, posting_m=grid.posting, geoid=geoid_name,
               info=dsm_info(plan, sums, len(specs)), counts=counts)


def fill_tiles(tiles, shape, progress=None) -> int:
    """The voids of the seen cells of the DSM being written (:class:`~prismstation.io.dsm.DsmTiles`)
    filled block by block, their mask :data:`~prismstation.ops.dsm.MASK_FILLED`; returns the
    cells filled. ``progress(fraction, message)`` after each block (False cancels)."""
    rows, cols = shape
    blocks = max(1, -(-rows // FILL_BLOCK) * -(-cols // FILL_BLOCK))
    done = 0

    def read(r0, c0, nr, nc):
        h, m, _, seen = tiles.read(r0, c0, nr, nc)
        return h, m == MASK_MATCHED, seen

    def write(r0, c0, h, new):
        _, m, q, seen = tiles.read(r0, c0, *h.shape)
        m[new] = MASK_FILLED
        tiles.write(r0, c0, h, m, q, seen)

    def step():
        nonlocal done
        done += 1
        checkpoint(progress, done / blocks, f"filling voids: block {done} of {blocks}")

    return fill_voids_in_blocks(shape, read, write, after=step)
