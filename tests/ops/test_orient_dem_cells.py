"""The matched patches' cells enter the adjustment under their own patch, failed patches or not."""
import numpy as np

from prismstation.ops.dem_patches import PatchCells
from prismstation.ops.orient_dem import join_cells


def _patch(k, n):
    cells = {} if n == 0 else {key: np.full(n, float(k)) for key in ("x", "y", "e", "n", "h")}
    if n:
        cells.update(row=np.arange(n), col=np.zeros(n, int))
    return PatchCells((0, 0, 1, 1), 0.0, 0.0, 0.5, cells, "" if n else "failed")


def test_failed_patches_do_not_shift_the_others():
    pcs = [_patch(0, 12), _patch(1, 0), _patch(2, 0), _patch(3, 20), _patch(4, 15)]
    cells, index = join_cells(pcs)
    assert index == [0, 3, 4]
    assert sorted(set(cells.patch.tolist())) == [0, 1, 2]          # 0 … n − 1, as the adjustment counts
    for j, k in enumerate(index):                                  # adjustment patch j holds pcs[k]'s cells
        sel = cells.patch == j
        assert sel.sum() == pcs[k].count and np.all(cells.h[sel] == k)
