"""One blunder threshold for every fit: standardised residuals on the normal scale."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from prismstation.core.models.solution import PointObs, Settings, critical_value, normal_equivalent, solve
from prismstation.sim.model_triplet import make_points, make_scene


@pytest.mark.parametrize("dof", [2, 3, 5, 7, 12, 40, 1000])
def test_beyond_the_threshold_exactly_when_beyond_the_fits_critical_value(dof):
    w = np.linspace(0.0, 60.0, 6001)
    for thr in (2.0, 2.58, 3.29, 4.0):
        crit = critical_value(thr, dof)
        z = normal_equivalent(w, dof)
        away = np.abs(w - crit) > 1e-9 * crit       # (equality is rounding's business)
        assert np.array_equal((z > thr)[away], (w > crit)[away]), (dof, thr)
    # the same tail probability: Student's t with dof − 1 against the normal law
    p = 2 * stats.t.sf(3.0, dof - 1) if dof > 1 else None
    assert normal_equivalent([3.0], dof)[0] == pytest.approx(stats.norm.isf(p / 2), rel=1e-9)
    assert np.all(np.diff(z) >= 0) and np.isnan(normal_equivalent([np.nan], dof)[0])


def test_far_beyond_double_precision_stays_beyond():
    assert normal_equivalent([1e6], 500)[0] > 100


def _shifted(pts, k, dx):
    bad = pts[k]
    img = dict(bad.image)
    img["N"] = (img["N"][0] + dx, img["N"][1])
    return pts[:k] + [PointObs(bad.id, bad.kind, bad.ground, img)] + pts[k + 1:]


def test_every_gcp_beyond_the_threshold_is_flagged_and_only_those():
    sc = make_scene()
    clean = make_points(sc, n_gcp=9, noise_px=0.3, seed=5)
    for pts in (clean, _shifted(clean, 4, 4.0), _shifted(_shifted(clean, 1, 4.0), 4, 4.0)):
        for thr in (1.5, 2.0, 3.29, 5.0):
            sol = solve(sc, pts, Settings(blunder_threshold=thr))
            gcps = [r for r in sol.points if r.std_residual is not None]
            assert len(gcps) == 9
            for r in gcps:
                assert r.blunder == (r.std_residual > thr), (thr, r.id, r.std_residual)
    sol = solve(sc, _shifted(clean, 4, 4.0))       # 4 px off in N, 9 GCPs: it alone stands out
    assert [r.id for r in sol.points if r.blunder] == [clean[4].id]
    assert not any(r.blunder for r in solve(sc, clean).points)
