"""Weighted least squares with the covariance of eq (50)."""

import numpy as np
import pytest

from identification.least_squares import solve_weighted


def _system(rng, r=400, noise=0.5):
    W = np.column_stack([np.ones(r), rng.uniform(-1, 1, r), 1e-3 * rng.uniform(0, 5, r)])
    v = np.array([2.0, -3.0, 5000.0])
    return W, v, W @ v + noise * rng.standard_normal(r)


def test_sigma_matches_the_spread_over_repeated_experiments(rng):
    W, v, _ = _system(rng)
    runs = []
    for _ in range(300):
        Y = W @ v + 0.5 * rng.standard_normal(W.shape[0])
        runs.append(solve_weighted(W, Y).value)
    res = solve_weighted(W, W @ v + 0.5 * rng.standard_normal(W.shape[0]), names=("a", "b", "k"))
    spread = np.std(runs, axis=0)
    np.testing.assert_allclose(res.sigma, spread, rtol=0.15)
    assert np.all(np.abs(np.mean(runs, axis=0) - v) < 4 * spread / np.sqrt(300))     # unbiased
    assert res.sigma_rho == pytest.approx(0.5, rel=0.1)
    np.testing.assert_allclose(res.rel_sigma, 100 * res.sigma / np.abs(res.value))
    assert res["k"] == res.value[2]


def test_condition_numbers():
    W = np.array([[1.0, 0.0], [0.0, 0.01], [1.0, 0.0], [0.0, 0.01]])
    res = solve_weighted(W, np.array([1.0, 0.02, 1.0, 0.02]))
    assert res.cond == pytest.approx(100.0)
    assert res.cond_scaled == pytest.approx(1.0)          # orthogonal columns, units do not matter
    np.testing.assert_allclose(res.value, [1.0, 2.0])


def test_row_weights_scale_the_equations(rng):
    W, v, Y = _system(rng)
    w = np.where(np.arange(W.shape[0]) % 2 == 0, 100.0, 1.0)
    a = solve_weighted(W, Y, row_weights=w)
    b = solve_weighted(W * w[:, None], Y * w)
    np.testing.assert_allclose(a.value, b.value, rtol=1e-10)
    np.testing.assert_allclose(a.sigma, b.sigma, rtol=1e-10)
    assert not np.allclose(a.value, solve_weighted(W, Y).value, rtol=1e-6)


def test_bad_systems_are_named(rng):
    W, v, Y = _system(rng, r=50)
    with pytest.raises(ValueError, match="need more samples"):
        solve_weighted(W[:3], Y[:3])
    with pytest.raises(ValueError, match="NaN"):
        solve_weighted(np.where(W == W[5, 1], np.nan, W), Y)
    with pytest.raises(ValueError, match=r"c_a\(2\) are not excited"):
        solve_weighted(np.column_stack([W, np.zeros(50)]), Y, names=("a", "b", "k", "c_a(2)"))
    collinear = np.column_stack([W, 2 * W[:, 1]])
    with pytest.raises(ValueError, match="rank-deficient.*b"):
        solve_weighted(collinear, Y, names=("a", "b", "k", "b2"))
    with pytest.raises(ValueError, match="expected W"):
        solve_weighted(W, Y[:-1])
