"""Observation matrices of eqs (44)-(47), (54)-(57) with the errata fixed, on noise-free synthetic runs."""

import dataclasses

import numpy as np
import pytest

from identification import regressors as reg
from identification.excitation import synthetic_measurements
from identification.least_squares import solve_weighted
from identification.preprocessing import prepare
from neck_sim.analytic import linkage_dynamics
from neck_sim.params import default_params
from test_preprocessing import predicted


@pytest.fixture(scope="module")
def p3():
    return default_params(3)


@pytest.fixture(scope="module")
def clean(p3):
    """A noise-free camera and exact forces at the paper's speed (2.5 s moves): the models must fit
    to within discretisation."""
    run = predicted(p3, move_time=2.5, hold_time=0.5)
    return prepare(synthetic_measurements(run, p3, np.random.default_rng(0), camera_noise=0.0), p3)


def test_friction_model_recovers_friction(clean, p3):
    res = solve_weighted(*reg.friction_model(clean, p3))
    np.testing.assert_allclose(res.value, p3.friction.f_s, rtol=0.01)
    assert res.names == ("f_s(1)", "f_s(2)", "f_s(3)", "f_s(4)")


def test_elastic_model_recovers_friction_and_a_secant_stiffness(clean, p3):
    res = solve_weighted(*reg.elastic_model(clean, p3))
    # the linear cable model misfits the stiffening plant, and the tension rows' misfit leaks into
    # f_s by a few percent on this short run (W = 100 keeps it small)
    np.testing.assert_allclose(res.group("f_s"), p3.friction.f_s, rtol=0.03)
    # a linear fit of t = (k + lambda t) x sees a secant stiffness k + lambda t within the run's tensions
    k_lin = res.group("k")
    t = reg.tension_from_forces(clean, p3, p3.friction.f_s)
    k, lam = np.asarray(p3.cables.k), np.asarray(p3.cables.lam)
    assert np.all((k_lin > k + lam * np.median(t, axis=0)) & (k_lin < k + lam * t.max(axis=0)))


def test_variable_stiffness_model_recovers_the_plant(clean, p3):
    res = solve_weighted(*reg.variable_stiffness_model(clean, p3, p3.friction.f_s))
    np.testing.assert_allclose(res.group("k"), p3.cables.k, rtol=0.01)
    np.testing.assert_allclose(res.group("lambda"), p3.cables.lam, rtol=0.02)   # lambda(3) is the least excited


def test_torque_rows_hold_the_corrected_sign_of_the_elongation_term(clean, p3):
    """Eq (44)'s torque rows equal the linkage's own balance Z t = M_m a'' + c_m + g (eqs 29-30).

    The two forms differ only in how the motor inertia is written; with the printed sign of
    I_a (R/r_d)^2 Z x_c_ddot they would differ by twice that term.
    """
    act = p3.actuation
    dyn = reg.joint_dynamics(clean, p3)
    _, y_paper = reg._torque_rows(clean, p3, dyn, elastic=True)
    lk = linkage_dynamics(clean.alpha, clean.alpha_dot, p3)
    t = clean.force - (act.R / act.r_d) * act.I_a * clean.theta_ddot
    y_link = (np.einsum("sij,sj->si", dyn.Z, t) - np.einsum("sij,sj->si", lk.M, clean.alpha_ddot) - lk.c - lk.g)
    flip = 2 * act.reflected_inertia * np.einsum("sij,sj->si", dyn.Z, clean.x_c_ddot)
    rms = lambda x: np.sqrt(np.mean(np.square(x)))  # noqa: E731
    assert rms(y_paper - y_link.ravel()) < 0.4 * rms(flip)


def test_elastic_rows_and_weight(clean, p3):
    S, C = clean.x_c.shape
    taut = np.ones((S, C), bool)
    taut[100:140, 0] = False
    r = reg.elastic_model(clean, p3, weight=100.0, taut=taut)
    assert r.W.shape == (taut.sum() + S * (C - 1), 3 * C)
    r1 = reg.elastic_model(clean, p3, weight=1.0, taut=taut)
    n_t = taut.sum()
    np.testing.assert_allclose(r.W[n_t:], 100 * r1.W[n_t:])
    np.testing.assert_allclose(r.Y[n_t:], 100 * r1.Y[n_t:])
    np.testing.assert_allclose(r.W[:n_t], r1.W[:n_t])
    with pytest.raises(ValueError, match="weight"):
        reg.elastic_model(clean, p3, weight=0.0)
    with pytest.raises(ValueError, match="taut"):
        reg.elastic_model(clean, p3, taut=taut[:, :3])


def test_taut_samples_leave_out_slack_intervals_with_a_margin(clean, p3):
    force = clean.force.copy()
    friction = reg.friction_basis(clean.theta_dot, p3) * p3.friction.f_s
    force[200:230, 1] = friction[200:230, 1] - 5.0     # cable 2 goes slack: eq (41) tension about -5 N
    prep = dataclasses.replace(clean, force=force)
    taut = reg.taut_samples(prep, p3, p3.friction.f_s, threshold=2.0, margin_s=0.1)
    pad = int(np.ceil(0.1 * prep.rate_hz))
    assert not taut[200 - pad:230 + pad, 1].any()
    assert taut[:200 - pad - 1, 1].all() and taut[230 + pad + 1:, 1].all()
    assert taut[:, [0, 2, 3]].all()


def test_models_need_the_camera(clean, p3):
    blind = dataclasses.replace(clean, alpha=None, alpha_dot=None, alpha_ddot=None, x_c=None, x_c_dot=None,
                                x_c_ddot=None, camera=None)
    for call in (lambda: reg.friction_model(blind, p3), lambda: reg.elastic_model(blind, p3),
                 lambda: reg.variable_stiffness_model(blind, p3, p3.friction.f_s)):
        with pytest.raises(ValueError, match="camera"):
            call()


def test_friction_basis_follows_the_filtered_friction_not_the_filtered_speed(p3):
    """A motor speed ringing at 8 Hz (+-12 rad/s) around a slow 1 rad/s: the friction the motor
    feels, averaged over the ringing, is far below the friction at the filtered speed.  The slow-grid
    basis must be the former (the forces on the slow grid carry that averaged friction)."""
    from identification.preprocessing import Measurements, PreprocessSettings

    rate = p3.control.rate_hz
    t = np.arange(0.0, 12.0, 1.0 / rate)
    speed = 1.0 + 12.0 * np.sin(2 * np.pi * 8.0 * t)                      # rad/s
    theta = np.cumsum(speed) / rate
    th = np.stack([theta, -theta, 0.5 * theta, theta], axis=1)
    tc = np.arange(0.0, 12.0, 1.0 / 30.0)
    meas = Measurements(t, th, np.full_like(th, 20.0), tc, np.zeros((tc.size, 3)))
    prep = prepare(meas, p3, PreprocessSettings(motor_cutoff_hz=40.0, camera_cutoff_hz=2.0))
    a = reg.slow_friction_basis(prep, p3)
    # independent: the period average of eq (37)'s (2/pi) arctan(c_s v) over one 8 Hz cycle
    phase = np.linspace(0.0, 2 * np.pi, 4001)[:-1]
    avg = np.mean(2 / np.pi * np.arctan(p3.friction.c_s * (1.0 + 12.0 * np.sin(phase))))
    mid = slice(20, -20)
    np.testing.assert_allclose(a[mid, 0], avg, atol=0.01)
    np.testing.assert_allclose(a[mid, 1], -avg, atol=0.01)
    # the arctan of the filtered speed (1 rad/s) is far from it
    at_filtered = 2 / np.pi * np.arctan(p3.friction.c_s * 1.0)
    assert abs(at_filtered - avg) > 0.1
