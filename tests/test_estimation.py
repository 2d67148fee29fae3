import numpy as np
import pytest

import neck_sim.analytic as an
from neck_sim.params import default_params


@pytest.mark.parametrize("n", [1, 3, 10])
def test_triangular_round_trip_within_encoder_resolution(n, rng):
    p = default_params(n)
    alpha = rng.uniform(-1.2, 1.2, (500, n))
    res = p.sensors.encoder_resolution
    theta = an.motor_angles_rigid(alpha, p)
    theta_q = np.round(theta / res) * res
    exact = an.estimate_alpha_triangular(theta, p)
    np.testing.assert_allclose(exact, alpha, atol=1e-12)
    # half a count on each right cable, mapped through |d alpha / d l| <= 1 / min|Z_jj| and the chain
    quant = an.estimate_alpha_triangular(theta_q, p)
    bound = n * 0.5 * res * (p.actuation.r_d / p.actuation.R) / 0.0175
    assert np.abs(quant - alpha).max() < bound


def test_triangular_with_elongation(params, rng):
    alpha = rng.uniform(-1, 1, (50, 3))
    x = rng.uniform(0, 3e-3, (50, 4))
    theta = an.motor_angles_rigid(alpha, params, x)
    np.testing.assert_allclose(an.elongation(theta, alpha, params), x, atol=1e-15)
    np.testing.assert_allclose(an.estimate_alpha_triangular(theta, params, x), alpha, atol=1e-12)
    # ignoring the elongation gives a wrong answer: the elongation is really used
    assert np.abs(an.estimate_alpha_triangular(theta, params) - alpha).max() > 1e-2


def test_pinv_follows_a_trajectory(params):
    t = np.linspace(0, 1, 2001)[:, None]
    path = np.array([0.8, -0.6, 0.9]) * np.sin(np.pi * t)
    x = 1e-3 * np.sin(2 * np.pi * t) * np.array([1, 2, 3, 4]) / 4 + 2e-3
    theta = an.motor_angles_rigid(path, params, x)
    est = an.estimate_alpha_pinv(theta, params, x, alpha0=path[0])
    assert np.abs(est - path).max() < 5e-4            # first-order increments, 2000 steps
    bad = an.estimate_alpha_pinv(theta, params, None, alpha0=path[0])
    assert np.abs(bad - path).max() > 5e-3


def test_unreachable_is_reported(params):
    theta = an.motor_angles_rigid(np.zeros(3), params)
    theta[1] += 1e4
    with pytest.raises(an.UnreachableError, match="c2"):
        an.estimate_alpha_triangular(theta, params)


def test_estimators_reject_bad_shapes(params):
    with pytest.raises(ValueError, match="theta"):
        an.estimate_alpha_triangular(np.zeros(3), params)
    with pytest.raises(ValueError, match="time series"):
        an.estimate_alpha_pinv(np.zeros(4), params)
