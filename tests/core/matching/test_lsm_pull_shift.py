"""The low-passed fit's shift of a point-sampled template carries its own σ (core.matching.lsm,
lsm_sampled.PULL_SHARE): it takes most of the two pixel grids' pull out, not all of it.

The fixture is one match of a ``prismstation simulate`` tuning scene (the SRTM tile at 5.35° E
44.62° N, 38 % slopes, mottled parcels as another renderer draws them, no point spread, 2 DN
of noise; point 36 in B with a 65 px template, projected reference): the N template, the B
search window, the start and shape the transfer gave, the point's exact position. The low-passed
fit moves it 0.42 px across the parallax, and it ends 0.80 px off across; before, it stated
0.08 px there (z 9.5). Captured while the bend was held to 1 px at every template's edge (the
limit is now a curvature, :func:`~prismstation.core.matching.lsm_fit.max_bend`): refined as
then, and as now."""
from __future__ import annotations

import numpy as np

from prismstation.core.matching import lsm_fit
from prismstation.core.matching.lsm_sampled import PULL_SHARE
from tests.core.matching.captured import refine_captured


def test_the_low_passed_fits_shift_keeps_a_share_of_itself_in_the_sigma(monkeypatch):
    monkeypatch.setattr(lsm_fit, "MAX_BEND", (lsm_fit.BEND_HALF / 32) ** 2)     # 1 px at 32 px
    f, r = refine_captured("pull_shift.npz")
    assert r.ok, r.reason
    shift = np.asarray(r.extra["smoothed"], float)
    d = np.asarray(r.extra["d"], float)
    e2 = np.array([-d[1], d[0]])
    assert abs(shift @ e2) > 0.3                           # a large shift across the parallax
    u = shift / np.hypot(*shift)
    assert u @ r.cov @ u >= (PULL_SHARE * np.hypot(*shift)) ** 2
    err = np.array([r.x, r.y]) - f["truth"]
    assert abs(err @ e2) / np.sqrt(e2 @ r.cov @ e2) < 4.0  # 9.5 before


def test_with_the_curvature_it_bends_by_the_capture_ends_near_the_truth():
    """Bent by 2.6–3.7 px at the 65 px template's edge (under the curvature's limit, 7.1 px),
    the same capture needs no large low-passed shift and ends 0.15 px off across the parallax
    (0.80 px before)."""
    f, r = refine_captured("pull_shift.npz")
    assert r.ok, r.reason
    d = np.asarray(r.extra["d"], float)
    e2 = np.array([-d[1], d[0]])
    err = np.array([r.x, r.y]) - f["truth"]
    assert np.abs(r.extra["bend"]).max() * r.extra["half"] > 1.0
    assert abs(err @ e2) < 0.25 and abs(err @ d) < 0.25, err
