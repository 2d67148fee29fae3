"""Statics of necks with any cable count: stiffness against finite differences of an independent
potential (forward kinematics + a cable energy written here), equilibrium residuals, stability signs."""

import numpy as np
import pytest

from neck_sim.analytic import cable_lengths, forward_kinematics, potential_energy
from neck_sim.analytic.statics import (equilibrium_for_forces, equilibrium_for_motor_angles, force_stiffness,
                                       head_jacobian, motor_angles_for, motor_stiffness, with_payload)
from neck_sim.params import default_params


def _necks():
    """(name, params) of the necks the statics must hold for: the paper's routing for N = 3 and 10,
    and the routings the design command compares for the 10-X, 4-cable neck."""
    necks = [("paper3", default_params(3)), ("paper10", default_params(10))]
    import neck_sim.params
    if not hasattr(neck_sim.params, "Routing"):         # before routing-as-data is merged
        return necks
    from neck_sim.design import routing_strategies
    return necks + [(s.name, s.params) for s in routing_strategies(default_params(10), 4)]


NECKS = _necks()


def _cable_energy(x, p):
    """Energy stored in resting cables of eq (54), t = k x / (1 - lambda x) for x > 0 (below t_cap)."""
    k, lam = np.asarray(p.cables.k), np.asarray(p.cables.lam)
    e = np.where(lam > 0, -k * x / np.where(lam > 0, lam, 1) - k * np.log1p(-lam * x) / np.where(lam > 0, lam, 1) ** 2,
                 0.5 * k * x * x)
    return np.where(x > 0, e, 0.0).sum(-1)


def _fd_hessian(fun, a, h=1e-4):
    n = a.size
    E = np.eye(n) * h
    H = np.empty((n, n))
    for i in range(n):
        for j in range(i, n):
            H[i, j] = H[j, i] = (fun(a + E[i] + E[j]) - fun(a + E[i] - E[j]) - fun(a - E[i] + E[j])
                                 + fun(a - E[i] - E[j])) / (4 * h * h)
    return H


@pytest.mark.parametrize("name,p", NECKS, ids=[n for n, _ in NECKS])
def test_force_stiffness_is_hessian_of_potential(name, p):
    rng = np.random.default_rng(7)
    p = with_payload(p, 0.2)
    for _ in range(2):
        a = rng.uniform(-0.6, 0.6, p.n_joints)
        f = rng.uniform(2, 100, p.n_cables)

        def energy(x):
            return potential_energy(x, p) + f @ cable_lengths(x, p)
        H = _fd_hessian(energy, a)
        K = force_stiffness(a, f, p)
        assert np.max(np.abs(K - H)) < 2e-5 * np.max(np.abs(H)), name


@pytest.mark.parametrize("name,p", NECKS[:2] + NECKS[-1:], ids=[n for n, _ in NECKS[:2] + NECKS[-1:]])
def test_motor_stiffness_is_hessian_with_elastic_cables(name, p):
    rng = np.random.default_rng(11)
    act = p.actuation
    a = rng.uniform(-0.4, 0.4, p.n_joints)
    x = rng.uniform(1e-3, 6e-3, p.n_cables)               # taut, below t_cap
    theta = (act.R / act.r_d) * (x - cable_lengths(a, p))

    def energy(y):
        return potential_energy(y, p) + _cable_energy(cable_lengths(y, p) + (act.r_d / act.R) * theta, p)
    H = _fd_hessian(energy, a, h=2e-5)
    K = motor_stiffness(a, theta, p)
    assert np.max(np.abs(K - H)) < 1e-4 * np.max(np.abs(H)), name


@pytest.mark.parametrize("name,p", NECKS, ids=[n for n, _ in NECKS])
def test_head_jacobian_against_forward_kinematics(name, p):
    a = np.random.default_rng(3).uniform(-0.7, 0.7, p.n_joints)
    h = 1e-6
    cols = []
    for e in np.eye(p.n_joints) * h:
        k1, k0 = forward_kinematics(a + e, p), forward_kinematics(a - e, p)
        cols.append(np.r_[k1.head_position - k0.head_position, k1.head_angle - k0.head_angle] / (2 * h))
    assert np.max(np.abs(np.stack(cols, 1) - head_jacobian(a, p))) < 1e-8


def _gradient(fun, a, h=1e-6):
    return np.array([(fun(a + e) - fun(a - e)) / (2 * h) for e in np.eye(a.size) * h])


def test_force_equilibrium_zeroes_the_independent_potential_gradient():
    p = with_payload(default_params(3), 0.1)
    f = np.random.default_rng(5).uniform(5, 40, (20, 4))
    eq = equilibrium_for_forces(f, p)
    assert eq.converged.sum() >= 10
    for a, fk in zip(eq.alpha[eq.converged], f[eq.converged]):
        grad = _gradient(lambda x: potential_energy(x, p) + fk @ cable_lengths(x, p), a)
        assert np.max(np.abs(grad)) < 1e-7                # N m; the forces' torques are ~1 N m
        assert np.max(np.abs(a)) > 1e-3                   # a real, bent pose


@pytest.mark.parametrize("name,p", NECKS[1:], ids=[n for n, _ in NECKS[1:]])
def test_motor_angle_equilibrium_round_trip(name, p):
    """Tensions -> equilibrium -> the motor angles that hold it with elastic cables -> from a
    perturbed start, the same pose and tensions; the independent potential (with the cables'
    stored energy) is stationary there."""
    forces = np.random.default_rng(2).uniform(10, 40, (8, p.n_cables))
    eq_f = equilibrium_for_forces(forces, p)
    assert eq_f.converged.any(), name
    act = p.actuation
    for f, a in list(zip(forces[eq_f.converged], eq_f.alpha[eq_f.converged]))[:2]:
        theta = motor_angles_for(a, f, p)
        eq = equilibrium_for_motor_angles(theta, p, alpha0=a + 0.03)
        assert eq.converged, name
        assert np.max(np.abs(eq.alpha - a)) < 1e-9 and np.max(np.abs(eq.tension - f)) < 1e-6

        def energy(y):
            return potential_energy(y, p) + _cable_energy(cable_lengths(y, p) + (act.r_d / act.R) * theta, p)
        assert np.max(np.abs(_gradient(energy, eq.alpha))) < 1e-6


def test_the_solvers_answer_is_evaluated_at_the_pose_it_returns():
    """The solver keeps each sample's residual, stiffness and tensions (and, for held motors, the
    cable lengths and Z) from its last accepted step instead of evaluating them again: they equal
    those computed afresh at the returned poses (max_iter=0: no step), in a batch whose samples
    leave the iteration at different steps (half start at their equilibrium) or never converge."""
    from neck_sim.analytic import transmission_matrix
    from neck_sim.analytic.statics import held_pose

    p = NECKS[-1][1]
    rng = np.random.default_rng(5)
    forces = rng.uniform(20, 60, (12, p.n_cables))
    eq_f = equilibrium_for_forces(forces, p, max_iter=8)
    fresh_f = equilibrium_for_forces(forces, p, eq_f.alpha, max_iter=0)
    for got, want in ((eq_f.residual, fresh_f.residual), (eq_f.stiffness, fresh_f.stiffness)):
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    assert 0 < eq_f.converged.sum() < 12, eq_f.converged
    theta = motor_angles_for(eq_f.alpha, forces, p) + np.where(np.arange(12) < 6, 0.0, 0.05)[:, None]
    for max_iter in (2, 5, 60):
        held = held_pose(theta, p, eq_f.alpha, max_iter=max_iter)
        eq = held.equilibrium
        assert eq.converged.any(), max_iter
        fresh = equilibrium_for_motor_angles(theta, p, eq.alpha, max_iter=0)
        for got, want in ((eq.residual, fresh.residual), (eq.stiffness, fresh.stiffness),
                          (eq.tension, fresh.tension), (held.lengths, cable_lengths(eq.alpha, p)),
                          (held.Z, transmission_matrix(eq.alpha, p))):
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    assert not equilibrium_for_motor_angles(theta, p, eq_f.alpha, max_iter=2).converged.all()


def test_stability_signs_agree_with_the_potential():
    """The sign of K's smallest eigenvalue is the sign of the independent potential's curvature
    along its eigenvector; the 10-X neck is unstable under pure force control at the straight
    pose (gravity), stable with held motors (elastic cables)."""
    for n, f_level in ((3, 20.0), (10, 20.0)):
        p = default_params(n)
        a = np.zeros(n)
        f = np.full(p.n_cables, f_level)
        K = force_stiffness(a, f, p)
        lam, vec = np.linalg.eigh(K)
        h = 1e-3

        def energy(x):
            return potential_energy(x, p) + f @ cable_lengths(x, p)
        curv = (energy(a + h * vec[:, 0]) - 2 * energy(a) + energy(a - h * vec[:, 0])) / h ** 2
        assert np.sign(curv) == np.sign(lam[0]) and abs(curv - lam[0]) < 1e-3 * max(1, abs(lam[0]))
        if n == 10:
            assert lam[0] < -1.0
            theta = motor_angles_for(a, f, p)
            assert np.linalg.eigvalsh(motor_stiffness(a, theta, p))[0] > 0
        else:
            assert lam[0] > 0


def test_bad_input_names_the_problem():
    p = default_params(3)
    with pytest.raises(ValueError, match="forces"):
        equilibrium_for_forces(np.ones(3), p)
    with pytest.raises(ValueError, match="cables only pull"):
        equilibrium_for_forces([-1, 2, 3, 4], p)
    with pytest.raises(ValueError, match="theta"):
        equilibrium_for_motor_angles([0.0, np.nan, 0, 0], p)
    with pytest.raises(ValueError, match="payload_mass"):
        equilibrium_for_forces([1, 2, 3, 4], p, payload_mass=-1)


def test_force_equilibrium_is_where_mujoco_comes_to_rest():
    """The MuJoCo plant (its own geometry, gravity and springs), motor friction off and a light
    viscous motor damping to settle, held at constant forces, rests at the analytic equilibrium."""
    from neck_sim.effects import Effects, ViscousFriction
    from neck_sim.plant import Plant

    p = default_params(3).replace(**{"friction.f_s": (0.0,) * 4, "inertia.payload_mass": 0.05})
    forces = np.array([[12.0, 25.0, 8.0, 30.0], [30.0, 10.0, 22.0, 18.0]])
    eq = equilibrium_for_forces(forces, p)
    assert eq.converged.all() and eq.stable.all()
    for f, a in zip(forces, eq.alpha):
        plant = Plant(p, effects=Effects(viscous_friction=ViscousFriction(c_v=0.1)))
        plant.reset(alpha0=a + 0.02)                      # start off the equilibrium
        for _ in range(2000):
            plant.step(f)
        truth = plant.truth()
        assert np.degrees(np.max(np.abs(truth.alpha - a))) < 2e-3      # 2.4e-4 deg achieved
        assert np.max(np.abs(truth.tension - f)) < 5e-4                  # N
