"""M, c, g and the simulators against independent computations."""

import numpy as np
import pytest

import neck_sim.analytic as an
from neck_sim.params import default_params


@pytest.mark.parametrize("n", [1, 3, 10])
def test_mass_matrix_symmetric_positive_definite(n, rng):
    p = default_params(n)
    alpha = rng.uniform(-1.2, 1.2, (100, n))
    for motors in (False, True):
        M = an.mass_matrix(alpha, p, motors=motors)
        np.testing.assert_allclose(M, np.swapaxes(M, -1, -2), atol=1e-18)
        assert np.linalg.eigvalsh(M).min() > 0


def test_linkage_inertia_magnitude(params, rng):
    # design notes: the bare manipulator is 1e-5 .. 4e-3 kg m^2 in alpha-space
    ev = np.linalg.eigvalsh(an.mass_matrix(rng.uniform(-1, 1, (500, 3)), params, motors=False))
    assert 5e-6 < ev.min() and ev.max() < 6e-3


def test_mass_matrix_from_kinetic_energy_of_points(params, rng):
    """M_m from finite-difference velocities of the bar end points (independent of the Jacobians)."""
    alpha = rng.uniform(-1, 1, 3)
    h = 1e-6
    kin = lambda a: an.forward_kinematics(a, params).corners  # (3, 4, 2)
    # a uniform rod's kinetic energy from its two end velocities: m/6 (v1^2 + v1.v2 + v2^2)
    def energy(ad):
        v = (kin(alpha + h * ad) - kin(alpha - h * ad)) / (2 * h)
        A, B, C, D = (v[:, k] for k in range(4))
        rod = lambda m, u, w: m / 6 * ((u * u).sum(-1) + (u * w).sum(-1) + (w * w).sum(-1))
        i = params.inertia
        return (rod(i.diagonal_mass, A, D) + rod(i.diagonal_mass, B, C) + rod(i.bar_mass, C, D)).sum()
    M = an.mass_matrix(alpha, params, motors=False)
    E = np.eye(3)
    M_fd = np.array([[(energy(E[i] + E[j]) - energy(E[i]) - energy(E[j])) for j in range(3)] for i in range(3)])
    np.testing.assert_allclose(M, M_fd, rtol=1e-6, atol=1e-12)


@pytest.mark.parametrize("payload", [0.0, 0.05])
def test_g_is_gradient_of_potential(payload, rng):
    p = default_params(3).replace(**{"inertia.payload_mass": payload})
    alpha = rng.uniform(-1.2, 1.2, (50, 3))
    h = 1e-6
    grad = np.stack([(an.potential_energy(alpha + h * e, p) - an.potential_energy(alpha - h * e, p)) / (2 * h)
                     for e in np.eye(3)], -1)
    np.testing.assert_allclose(an.gravity_spring_torque(alpha, p), grad, atol=1e-8)


def test_bias_forces_match_lagrangian(params, rng):
    """c = Mdot alpha_dot - 1/2 d(alpha_dot^T M alpha_dot)/d alpha, motors included (erratum 5)."""
    alpha = rng.uniform(-1, 1, (30, 3))
    ad = rng.normal(size=(30, 3))
    h = 1e-6
    Md = (an.mass_matrix(alpha + h * ad, params) - an.mass_matrix(alpha - h * ad, params)) / (2 * h)
    dT = np.stack([(an.kinetic_energy(alpha + h * e, ad, params) - an.kinetic_energy(alpha - h * e, ad, params))
                   / (2 * h) for e in np.eye(3)], -1)
    ref = np.einsum("bij,bj->bi", Md, ad) - dT
    np.testing.assert_allclose(an.bias_forces(alpha, ad, params), ref, atol=1e-9)


def test_free_motion_conserves_energy(params):
    """No friction, no forces: kinetic (bars + motors) + potential energy stays constant."""
    a0 = np.array([0.4, -0.3, 0.5])
    ad0 = np.array([0.5, 1.0, -0.8])
    t, alpha, alpha_dot = an.simulate_rigid(a0, lambda t: np.zeros(4), 1.0, params, friction=False,
                                            alpha_dot0=ad0, sample_dt=0.01)
    E = an.kinetic_energy(alpha, alpha_dot, params) + an.potential_energy(alpha, params)
    assert np.ptp(alpha) > 0.05                       # it did move
    assert np.abs(E - E[0]).max() < 1e-7 * max(abs(E[0]), 1e-3)


def test_rigid_and_stiff_elastic_models_agree(params):
    """Eqs (29)-(30) with very stiff cables approach eq (32) with rigid cables."""
    stiff = params.replace(**{"cables.k": (5e6,) * 4, "cables.lam": (0.0,) * 4, "cables.c_a": (3e3,) * 4})
    forces = lambda t: np.array([30.0, 25.0, 20.0, 40.0])
    a0 = np.zeros(3)
    t, alpha, _ = an.simulate_rigid(a0, forces, 0.3, stiff, sample_dt=0.01)
    # start the elastic model on its static pre-stretch so both start at rest
    x0 = forces(0) / 5e6
    te, st = an.simulate_elastic(a0, an.motor_angles_rigid(a0, stiff, x0), forces, 0.3, stiff, sample_dt=0.01)
    assert np.abs(alpha[-1]).max() > 0.01
    np.testing.assert_allclose(st.alpha, alpha, atol=2e-3)


def test_cable_tension_law(params):
    k, lam = np.asarray(params.cables.k), np.asarray(params.cables.lam)
    x = np.array([0.001, 0.002, 0.003, 0.004])
    t = an.cable_tension(x, np.zeros(4), params)
    np.testing.assert_allclose(t, (k + lam * t) * x, rtol=1e-12)      # eq (54), implicit form
    assert np.all(an.cable_tension(-x, np.zeros(4), params) == 0)     # slack
    assert np.all(an.cable_tension(x, -np.ones(4) * 1e3, params) == 0)  # never pushes
    big = an.cable_tension(np.full(4, 0.05), np.zeros(4), params)      # beyond 1/lambda
    assert np.all(np.isfinite(big)) and np.all(big > params.cables.t_cap)
    xs = np.linspace(0, 0.05, 2001)[:, None] * np.ones(4)
    assert np.all(np.diff(an.cable_tension(xs, 0 * xs, params), axis=0) >= 0)


def test_motor_friction_eq37(params):
    fs = np.asarray(params.friction.f_s)
    np.testing.assert_allclose(an.motor_friction(np.full(4, 1e9), params), fs, rtol=1e-6)
    np.testing.assert_allclose(an.motor_friction(np.full(4, 2.0), params), fs / 2, rtol=1e-12)
    assert np.all(an.motor_friction(-np.ones(4), params) < 0)
