"""Tension distribution (eqs 63-65): bounds met, torque exact when unsaturated, minimal, any N."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.optimize import linprog

from controllers.tension import (TensionInfeasibleError, distribute_tensions, tension_lower_bounds)
from neck_sim.analytic import transmission_matrix
from neck_sim.params import default_params

P3 = default_params(3)
P5 = default_params(5)
AMAX = P3.geometry.alpha_max * 0.999


def _case(n):
    return st.tuples(arrays(float, n, elements=st.floats(-AMAX, AMAX)),
                     arrays(float, n, elements=st.floats(-4.0, 4.0)),
                     arrays(float, n + 1, elements=st.floats(0.0, 40.0)))


@settings(max_examples=300, deadline=None)
@given(case=st.one_of(_case(3).map(lambda c: (P3, c)), _case(5).map(lambda c: (P5, c))))
def test_bounds_met_and_torque_exact(case):
    params, (alpha, gamma, lower) = case
    Z = transmission_matrix(alpha, params)
    f_max = 1e6                                     # no saturation: the torque must be exact
    res = distribute_tensions(Z, gamma, lower, f_max)
    assert not res.any_saturated
    assert np.all(res.forces >= lower - 1e-9 * (1 + np.abs(lower)))
    np.testing.assert_allclose(Z @ res.forces, gamma, atol=1e-9)
    # the binding cable sits exactly on its bound (minimal solution)
    assert res.forces[res.binding] == pytest.approx(lower[res.binding], abs=1e-9)


@settings(max_examples=60, deadline=None)
@given(case=_case(3))
def test_matches_an_independent_linear_program(case):
    """min sum(f) s.t. Z f = Gamma, f >= lb (scipy HiGHS) gives the same forces: along the
    one-parameter family every force grows with the long cable's, so both minima coincide."""
    alpha, gamma, lower = case
    Z = transmission_matrix(alpha, P3)
    res = distribute_tensions(Z, gamma, lower, 1e6)
    lp = linprog(np.ones(4), A_eq=Z, b_eq=gamma, bounds=list(zip(lower, [None] * 4)), method="highs")
    assert lp.status == 0
    np.testing.assert_allclose(res.forces, lp.x, atol=1e-6)


def test_saturation_is_reported(rng):
    alpha = rng.uniform(-1, 1, (200, 3))
    Z = transmission_matrix(alpha, P3)
    gamma = rng.uniform(-4, 4, (200, 3))
    lower = np.full(4, 8.5)
    free = distribute_tensions(Z, gamma, lower, 1e6)
    f_max = 40.0
    res = distribute_tensions(Z, gamma, lower, f_max)
    assert np.all(res.forces <= f_max)
    over = free.forces > f_max
    assert over.any() and (~over).any()
    np.testing.assert_array_equal(res.saturated, over)
    ok = ~res.any_saturated
    np.testing.assert_allclose(np.einsum("bij,bj->bi", Z[ok], res.forces[ok]), gamma[ok], atol=1e-9)
    sat = res.any_saturated
    assert np.all(np.abs(np.einsum("bij,bj->bi", Z[sat], res.forces[sat]) - gamma[sat]).max(axis=1) > 1e-6)


def test_lower_bounds_eq65():
    p = P3
    act = p.actuation
    td = np.array([10.0, -10.0, 0.0, 100.0])
    tdd = np.array([0.0, 0.0, 50.0, -2000.0])
    fs = np.array(p.friction.f_s)
    lb = tension_lower_bounds(td, tdd, p, f_s=fs)
    fric = np.array([fs[0] * 2 / np.pi * np.arctan(5.0), -fs[1] * 2 / np.pi * np.arctan(5.0), 0.0,
                     fs[3] * 2 / np.pi * np.arctan(50.0)])
    inertia = 1250.0 * 1e-5 * tdd                  # (R / r_d) I_a theta_ddot with R = 25, r_d = 0.02 m
    want = np.maximum(8.5 + fric + inertia, 2.0)
    assert act.R / act.r_d * act.I_a == pytest.approx(1250.0 * 1e-5)
    np.testing.assert_allclose(lb, want)
    assert lb[1] == 2.0                             # unwinding cable: friction helps, f_min binds
    no_fric = tension_lower_bounds(td, tdd, p)
    np.testing.assert_allclose(no_fric, np.maximum(8.5 + inertia, 2.0))


def test_infeasible_pose_is_an_error():
    Z = transmission_matrix(np.zeros(3), P3)
    Z_bad = Z.copy()
    Z_bad[:, 3] *= -1                               # left cable pulling the wrong way
    with pytest.raises(TensionInfeasibleError, match="c[1-3]"):
        distribute_tensions(Z_bad, np.zeros(3), np.full(4, 2.0), 100.0)
    Z_sing = Z.copy()
    Z_sing[:, 0] = 0.0
    with pytest.raises(TensionInfeasibleError, match="singular"):
        distribute_tensions(Z_sing, np.zeros(3), np.full(4, 2.0), 100.0)


def test_bad_input_is_named():
    Z = transmission_matrix(np.zeros(3), P3)
    with pytest.raises(ValueError, match="gamma"):
        distribute_tensions(Z, np.zeros(4), np.zeros(4), 100.0)
    with pytest.raises(ValueError, match="lower"):
        distribute_tensions(Z, np.zeros(3), np.zeros(3), 100.0)
    with pytest.raises(ValueError, match="gamma.*NaN"):
        distribute_tensions(Z, np.array([0, np.nan, 0]), np.zeros(4), 100.0)
    with pytest.raises(ValueError, match="Z"):
        distribute_tensions(Z[:, :3], np.zeros(3), np.zeros(4), 100.0)
