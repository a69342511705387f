"""With no reference DEM the transfer starts from the level plane's shape; on a steep slope
that start can end in the level shape's own minimum, found and wrong, while the slope's true
shape, never started from, fits clearly better (ops.transfer_slope.from_slopes).

The fixture is one point of a ``prismstation simulate`` scene on 50 % Alpine relief (the SRTM
tile at 5.78° E 44.68° N, mottled parcels, no point spread, 2 DN; point 44 of the transfer
benchmark's debugging place, view F): the source template, the search window cropped about the
point's true position, the level plane's prediction and shape, the four slope starts and the parallax."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from prismstation.core.matching.lsm_search import AMBIGUOUS, match
from prismstation.ops.transfer import RETRY_STATUSES as RETRY
from prismstation.ops.transfer_slope import from_slopes

DATA = Path(__file__).parent / "data" / "steep_level_minimum.npz"


def _case():
    f = np.load(DATA)
    ref, search = f["reference"].astype(np.float64), f["search"].astype(np.float64)
    x, y = f["point"]
    d, half, truth = f["d"], int(f["half"]), f["truth"]
    band = (ref, float(x), float(y), search, f["pred"])     # the level plane's prediction, 44 px off
    return band, f["A0"], list(f["starts"]), d, half, truth


def test_a_level_start_found_in_its_own_minimum_gives_way_to_the_slope_that_fits_better():
    band, A0, starts, d, half, truth = _case()
    along, across = 60.0, 8.0
    level = match(*band, A0, d, along=along, across=across, half=half, max_sigma=0.5, max_shape_change=0.6,
                  coarse=1.5, rival=6.0, parallax=d)
    off = np.hypot(level.x - truth[0], level.y - truth[1])
    assert level.ok and off > 2.0          # the cause: found, and wrong by more than 2 px
    m = from_slopes(level, starts, band, d, along, across, half, RETRY, 0.6 * half, max_sigma=0.5,
                    max_shape_change=0.25, rival=6.0, parallax=d)
    assert m.ok and np.hypot(m.x - truth[0], m.y - truth[1]) < 0.5 and m.rho > level.rho + 0.02


def test_a_found_match_no_slope_beats_is_kept_and_a_failed_one_takes_the_first_slope_found():
    band, A0, starts, d, half, truth = _case()
    right = match(*band, starts[int(np.argmax([abs(A[1, 1] - 1) for A in starts]))], d, along=60.0, across=8.0,
                  half=half, max_sigma=0.5, max_shape_change=0.25, rival=6.0, parallax=d)
    assert right.ok and np.hypot(right.x - truth[0], right.y - truth[1]) < 0.5
    kept = from_slopes(right, starts, band, d, 60.0, 8.0, half, RETRY, 0.6 * half, max_sigma=0.5,
                       max_shape_change=0.25, rival=6.0, parallax=d)
    assert kept.ok and kept.status != AMBIGUOUS and np.hypot(kept.x - right.x, kept.y - right.y) < 0.5
    failed = replace(right, status="not_converged")
    again = from_slopes(failed, starts, band, d, 60.0, 8.0, half, RETRY, 0.6 * half, max_sigma=0.5,
                        max_shape_change=0.25, rival=6.0, parallax=d)
    assert again.ok and np.hypot(again.x - truth[0], again.y - truth[1]) < 0.5
