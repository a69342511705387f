"""A template whose 4 × 4 px blocks read no relief along the parallax still states, along it,
the noise of that reading (its standard error under noise alone), as across (core.matching.lsm,
the σ along where the whole template places the point).

The fixture is one match of a ``prismstation simulate`` scene (the SRTM tile at 5.75° E
44.56° N, 34 % slopes, mottled parcels as another renderer draws them, no point spread, 2 DN
of noise; point 34 in F of the transfer benchmark's ``judged_fresh2`` set, 3″ reference): the
N template, the F search window, the start and shape the transfer gave, the point's exact
position. Its blocks read nil relief; the match is 0.57 px off along the parallax, and F and B
alike (the three rays meet). Before, it stated 0.047 px there: the noise's share alone."""
from __future__ import annotations

import numpy as np

from tests.core.matching.captured import refine_captured


def test_a_nil_relief_reading_keeps_its_own_noise_in_the_sigma_along():
    _, r = refine_captured("nil_relief_reading.npz")
    assert r.ok, r.reason
    d = r.extra["d"]
    along = float(np.sqrt(d @ r.cov @ d))
    assert r.extra["sigma_relief"] == 0.0                 # the blocks read nil
    assert along > 1.5 * r.extra["noise_along"]            # and the σ says more than the noise's share
    # across, where relief moves nothing, the same match is as before
    e2 = np.array([-d[1], d[0]])
    assert float(np.sqrt(e2 @ r.cov @ e2)) < along
