"""The matcher's σ is a claim: checked against empirical scatter on real independent imagery
(Pléiades triplet closure) and on a simulated PRISM triplet with relief (known truth).
Calibration numbers: :mod:`prismstation.core.matching.matching` module doc."""
from __future__ import annotations

import numpy as np
import pytest

from prismstation.core.matching.matching import (SIGMA_FLOOR_ACROSS, SIGMA_FLOOR_ALONG, SIGMA_SCALE,
                                        calibrated_sigma)
from benchmarks.sigma_experiments import closure_rows, summary, truth_rows


def test_calibrated_sigma_formula():
    assert calibrated_sigma(0.02, 0.02, (0, 1)) == pytest.approx(
        (np.hypot(SIGMA_SCALE * 0.02, SIGMA_FLOOR_ACROSS), np.hypot(SIGMA_SCALE * 0.02, SIGMA_FLOOR_ALONG)))
    sx, sy = calibrated_sigma(0.0, 0.0, (1, 1))
    assert sx == pytest.approx(sy) == pytest.approx(np.sqrt((SIGMA_FLOOR_ALONG ** 2 + SIGMA_FLOOR_ACROSS ** 2) / 2))
    assert calibrated_sigma(0.0, 0.0, None) == pytest.approx((SIGMA_FLOOR_ALONG, SIGMA_FLOOR_ALONG))


def _check(s, lo, hi):
    """RMS z per axis within (lo, hi); the claimed 95 % ellipse holds 90–99.5 % of errors."""
    assert np.all((s["rms_z_claimed"] > lo) & (s["rms_z_claimed"] < hi)), s
    assert 0.9 <= s["in95_claimed"] <= 0.995, s
    assert s["in95_formal"] < s["in95_claimed"], s


def test_sigma_against_closure_on_the_real_pleiades_triplet(shared_data):
    s = summary(closure_rows(shared_data / "pleiades_triplet", n=120))
    assert s["n"] >= 80
    _check(s, 0.25, 1.8)            # heavy tails along the parallax: RMS z is tail-driven
    assert s["rms_z_formal"][1] > 1.5 * s["rms_z_claimed"][1]     # formal σ alone: too small


def test_sigma_against_truth_on_a_simulated_triplet_with_relief(tmp_path):
    from prismstation.sim import simulate
    simulate(tmp_path, size=500, seed=11)
    s = summary(truth_rows(tmp_path, reps=3))
    assert s["n"] >= 100
    _check(s, 0.3, 1.4)             # across the parallax the floor is on the safe side
    assert s["rms_err"][1] > 0.1                      # the scatter along the parallax is real…
    assert s["rms_z_formal"][1] > 4                   # …and the formal σ does not see it
