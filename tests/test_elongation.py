"""Elongation from tension (eq 54 inverted, eq 58): the one definition against independent forms."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from neck_sim.analytic import cable_tension, elongation_series, elongation_step, static_elongation


def test_static_elongation_inverts_the_cable_law(params, rng):
    """cable_tension (eq 54 solved for t) of the static elongation gives the tension back."""
    t = rng.uniform(0.0, 200.0, size=(50, 4))
    x = static_elongation(t, params.cables.k, params.cables.lam)
    assert np.all(x >= 0)
    np.testing.assert_allclose(cable_tension(x, np.zeros_like(x), params), t, rtol=1e-12, atol=1e-9)
    # a cable cannot push: no elongation under a negative tension
    assert np.all(static_elongation(-t, params.cables.k, params.cables.lam) == 0)


def test_elongation_step_and_series_follow_the_ode(params, rng):
    """Eq (58) (explicit Euler) and the exact per-sample step against scipy's ODE solver of eq (54)."""
    k, lam, c_a = np.asarray(params.cables.k), np.asarray(params.cables.lam), 3000.0
    dt, T = 2e-3, 200
    tension = np.repeat(rng.uniform(5.0, 120.0, size=(4, 4)), T // 4, axis=0)     # piecewise constant
    x0 = np.zeros(4)

    def rhs(s, x):
        t = tension[min(int(s / dt) + 1, T - 1)]         # sample i's tension acts over (i - 1, i]
        return (t - (k + lam * t) * x) / c_a

    ref = solve_ivp(rhs, (0, dt * (T - 1)), x0, t_eval=dt * np.arange(T), rtol=1e-10, atol=1e-14,
                    max_step=dt / 4).y.T
    exact = elongation_series(tension, dt, k, lam, np.full(4, c_a), x0=x0)
    np.testing.assert_allclose(exact, ref, rtol=0, atol=1e-6 * np.abs(ref).max())
    euler = [x0]
    for i in range(T - 1):
        euler.append(elongation_step(euler[-1], tension[i], dt, k, lam, c_a))
    euler = np.array(euler)
    assert np.abs(euler - ref).max() < 2e-2 * np.abs(ref).max()
    # c_a = 0: the series is the static elongation
    np.testing.assert_array_equal(elongation_series(tension, dt, k, lam, np.zeros(4)),
                                  static_elongation(tension, k, lam))


@pytest.mark.parametrize("c_a", [1000.0, 3000.0])
def test_elongation_step_converges_to_the_static_elongation(params, c_a):
    k, lam = np.asarray(params.cables.k), np.asarray(params.cables.lam)
    t = np.array([10.0, 40.0, 80.0, 5.0])
    x = np.zeros(4)
    for _ in range(20000):                      # 40 s, 25 time constants of the softest cable
        x = elongation_step(x, t, 2e-3, k, lam, c_a)
    np.testing.assert_allclose(x, t / (k + lam * t), rtol=1e-9)
