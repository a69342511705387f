"""The one NMAD: σ of normal data, unmoved by outliers, NaN-blind, dtype kept."""
import numpy as np

from prismstation.core.adjustment.stats import nmad


def test_nmad_is_sigma_of_normal_data_and_ignores_outliers_and_nan():
    rng = np.random.default_rng(0)
    v = rng.normal(5.0, 2.0, 200_000)
    assert abs(nmad(v) - 2.0) < 0.02
    v[:10_000] = 1e6                      # 5 % blunders
    v[10_000:10_100] = np.nan
    assert abs(nmad(v) - 2.0) < 0.15
    assert np.isnan(nmad([])) and np.isnan(nmad([np.nan]))
    f32 = np.array([1, 2, 3, 10], np.float32)
    assert nmad(f32) == float(1.4826 * np.median(np.abs(f32 - np.median(f32))))
