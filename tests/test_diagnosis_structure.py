"""The structure tests behind the ``unexplained`` verdict, as pure functions on synthetic series."""

import numpy as np
import pytest
from scipy import stats

from identification.diagnosis.structure import bonferroni_z, correlations, lag_one


def test_correlations_match_numpy_and_skip_slack_samples(rng):
    res = rng.normal(size=(500, 3))
    feats = np.column_stack([res[:, 0] + rng.normal(size=500), rng.normal(size=500), np.ones(500)])
    res[::7, 1] = np.nan                                  # a slack cable's samples
    rho = correlations(res, feats)
    ok = np.isfinite(res[:, 1])
    assert rho[0, 0] == pytest.approx(np.corrcoef(res[:, 0], feats[:, 0])[0, 1], rel=1e-12)
    assert rho[1, 1] == pytest.approx(np.corrcoef(res[ok, 1], feats[ok, 1])[0, 1], rel=1e-12)
    assert np.all(rho[:, 2] == 0.0)                       # a constant feature explains nothing


def test_lag_one_sees_an_autoregressive_series_and_not_white_noise(rng):
    white = rng.normal(size=(4000, 1))
    ar = np.zeros((4000, 1))
    e = rng.normal(size=4000)
    for k in range(1, 4000):
        ar[k] = 0.7 * ar[k - 1] + e[k]
    assert abs(lag_one(white, 1)[0]) < 4 / np.sqrt(4000)
    assert lag_one(ar, 1)[0] == pytest.approx(0.7, abs=0.04)
    assert lag_one(ar, 2)[0] == pytest.approx(0.49, abs=0.05)      # sampled every other step


def test_bonferroni_bound_is_the_normal_quantile():
    assert bonferroni_z(0.05, 1) == pytest.approx(stats.norm.ppf(0.975))
    assert bonferroni_z(0.01, 100) == pytest.approx(stats.norm.ppf(1 - 0.01 / 200))
    assert bonferroni_z(0.01, 100) > bonferroni_z(0.01, 10)
