"""The shift-field consistency test: rejects one 50 m blunder patch, accepts
a consistent field, rescales σ by what the data show, and its false-alarm rate on consistent
fields is its stated α (Monte Carlo)."""
import json

import numpy as np
import pytest

from prismstation.core.orientation.consistency import (ALPHA, EXIT_NOT_TRUSTED, INCONSISTENT, OK, TOO_FEW,
                                           shift_field_verdict, snoop)


def _field(rng, n=16, sigma=(2.0, 2.0, 1.5), scale=1.0):
    """Patches on a 4×4 lattice of a 14,000 px image, an affine field of tens of metres, and
    Gaussian noise of ``scale``·σ."""
    g = (np.arange(4) + 0.5) * 3500
    x, y = np.meshgrid(g, g)
    x, y = x.ravel()[:n], y.ravel()[:n]
    truth = np.column_stack([40 + 1e-3 * x - 5e-4 * y, -55 + 2e-4 * x + 1e-3 * y, 3 + 0 * x])
    sig = np.tile(sigma, (n, 1))
    return x, y, truth + rng.normal(0, 1, truth.shape) * sig * scale, sig


def test_accepts_a_consistent_field():
    x, y, s, sig = _field(np.random.default_rng(0))
    v = shift_field_verdict(x, y, s, sig)
    assert v.status == OK and v.exit_status == 0 and v.scale == 1.0
    assert v.dof == 3 * 13 and 0.4 < v.variance_factor < 1.8
    doc = json.loads(json.dumps(v.to_dict(), allow_nan=False))
    assert doc["status"] == "ok" and "consistent" in doc["message"]


def test_rejects_one_50_m_blunder_and_names_it():
    x, y, s, sig = _field(np.random.default_rng(1))
    s[6, 1] += 50.0
    v = shift_field_verdict(x, y, s, sig)
    assert v.status == INCONSISTENT and v.exit_status == EXIT_NOT_TRUSTED
    assert v.worst == 6 and v.worst_w > v.w_critical and v.scale > 3
    assert "inconsistent" in v.message and "blunder" in v.message
    # data snooping takes it out and the rest is consistent again
    sv = snoop(x, y, s, sig)
    assert sv.status == OK and sv.rejected == (6,) and sv.n == 15
    assert np.isnan(sv.w[6]) and "rejected" in sv.message


def test_sigma_too_optimistic_is_inconsistent_and_rescaled():
    x, y, s, sig = _field(np.random.default_rng(2), n=16, scale=3.0)   # σ claimed 3× too small
    v = snoop(x, y, s, sig)
    assert v.status == INCONSISTENT and 2.0 < v.scale < 4.5
    assert len(v.rejected) <= 4


def test_too_few_patches():
    x, y, s, sig = _field(np.random.default_rng(3), n=5)
    v = shift_field_verdict(x, y, s, sig)
    assert v.status == TOO_FEW and v.exit_status == EXIT_NOT_TRUSTED and "patches" in v.message
    json.dumps(v.to_dict(), allow_nan=False)
    line = shift_field_verdict([0, 1, 2, 3, 4, 5], [0, 1, 2, 3, 4, 5], np.zeros((6, 1)), np.ones((6, 1)))
    assert line.status == TOO_FEW and "line" in line.message


@pytest.mark.parametrize("n", [6, 16])
def test_false_alarm_rate_is_alpha(n):
    rng = np.random.default_rng(10 + n)
    trials = 2000
    alarms = sum(shift_field_verdict(*_field(rng, n=n)).status != OK for _ in range(trials))
    rate = alarms / trials
    se = np.sqrt(ALPHA * (1 - ALPHA) / trials)
    assert abs(rate - ALPHA) < 3 * se, rate
    # snooping adds no false alarms: it can only turn an alarm into ok
    rng = np.random.default_rng(99)
    snooped = sum(snoop(*_field(rng, n=n)).status != OK for _ in range(400))
    assert snooped / 400 <= ALPHA + 3 * np.sqrt(ALPHA * (1 - ALPHA) / 400)
