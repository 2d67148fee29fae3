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


# -- motor angles no pose reaches, poses outside the joint range -------------------

from scipy.optimize import least_squares  # noqa: E402


def _plant_encoders(n: int, seed: int, seconds: float = 0.5):
    """Encoder readings and true angles of the MuJoCo plant (elastic cables, 500 Hz) under smooth
    random forces in [12, 60] N: what a prototype's motors report while its cables stretch."""
    from neck_sim.plant import Plant

    plant = Plant(default_params(n), seed=seed)
    rng = np.random.default_rng(seed)
    alpha0 = rng.uniform(-0.3, 0.3, n)
    plant.reset(alpha0=alpha0)
    amp, freq, phase = rng.uniform(6, 12, n + 1), rng.uniform(0.8, 1.6, n + 1), rng.uniform(0, 2 * np.pi, n + 1)
    theta, alpha = [], []
    for _ in range(int(round(seconds * 500))):
        theta.append(plant.encoders())
        alpha.append(plant.truth().alpha)
        plant.step(36.0 + 2 * amp * np.sin(2 * np.pi * freq * plant.time + phase))
    return plant.params, np.array(theta), np.array(alpha), alpha0


@pytest.mark.parametrize("n, seed", [(3, 0), (3, 1), (5, 2)])
def test_pinv_refuses_motor_angles_no_pose_reaches(n, seed):
    """An encoder jump on one motor at the last sample raises exactly when scipy finds no pose whose
    cable lengths come within the cables' stretch at f_max of the ones the motors allow."""
    import re

    p, theta, alpha, alpha0 = _plant_encoders(n, seed)
    est = an.estimate_alpha_pinv(theta, p, alpha0=alpha0)      # stretch unmodelled: still reachable
    assert np.degrees(np.abs(est - alpha).max()) < 5.0          # eq (35) inextensible: 1.8 (N = 3) to 4.2 deg (N = 5)
    ratio = p.actuation.r_d / p.actuation.R
    # stretch of every cable at f_max by eq (54) (t = (k + lambda t) x), the estimator's default tolerance
    tol = 1e3 * np.linalg.norm(np.asarray(p.actuation.f_max) / (np.asarray(p.cables.k)
                                                              + np.asarray(p.cables.lam) * p.actuation.f_max))
    j = int(np.random.default_rng(seed).integers(n + 1))
    raised = []
    for jump in (50.0, -50.0, 20.0, -20.0, 5.0):               # rad on motor j; 50 is the case
        bad = theta.copy()
        bad[-1, j] += jump
        target = an.cable_lengths(alpha0, p) - ratio * (bad[-1] - bad[0])
        fits = [least_squares(lambda a: an.cable_lengths(a, p) - target, a0, bounds=(-np.pi / 2, np.pi / 2))
                for a0 in (alpha[-1], est[-1], np.zeros(n))]
        distance = 1e3 * min(np.linalg.norm(f.fun) for f in fits)
        assert abs(distance - tol) > 0.2, "jump too close to the threshold to judge"
        if distance > tol:
            with pytest.raises(an.UnreachableError, match=rf"at sample {len(theta) - 1} the") as info:
                an.estimate_alpha_pinv(bad, p, alpha0=alpha0)
            reported = float(re.search(r"are ([0-9.]+) mm from", str(info.value)).group(1))
            assert reported == pytest.approx(distance, abs=0.06)
            raised.append(jump)
        else:
            an.estimate_alpha_pinv(bad, p, alpha0=alpha0)
    assert 50.0 in raised and 5.0 not in raised, raised


def test_pinv_refuses_estimates_outside_the_joint_range(params):
    t = np.linspace(0, 1, 801)[:, None]
    path = np.array([1.9, -0.4, 0.3]) * np.sin(0.5 * np.pi * t)      # joint 1 passes 90 deg
    theta = an.motor_angles_rigid(path, params, allow_outside_range=True)
    crossing = int(np.argmax(np.abs(path[:, 0]) > params.geometry.alpha_max))
    with pytest.raises(an.UnreachableError, match="joint 1 at") as info:
        an.estimate_alpha_pinv(theta, params)
    k = int(str(info.value).split("at sample ")[1].split(" ")[0])
    assert abs(k - crossing) <= 1
    an.estimate_alpha_pinv(theta[:crossing - 2], params)       # up to the edge it is fine


@pytest.mark.parametrize("fn", [
    lambda a, p, **kw: an.cable_lengths(a, p, **kw),
    lambda a, p, **kw: an.transmission_matrix(a, p, **kw),
    lambda a, p, **kw: an.transmission_matrix_dot(a, np.ones_like(a), p, **kw),
    lambda a, p, **kw: an.cable_kinematics(a, np.ones_like(a), p, **kw).Zdot,
    lambda a, p, **kw: an.motor_angles_rigid(a, p, **kw),
    lambda a, p, **kw: an.elongation(np.zeros(a.shape[:-1] + (4,)), a, p, **kw),
    lambda a, p, **kw: an.mass_matrix(a, p, **kw),
    lambda a, p, **kw: an.bias_forces(a, np.ones_like(a), p, **kw),
    lambda a, p, **kw: an.gravity_spring_torque(a, p, **kw),
    lambda a, p, **kw: an.linkage_dynamics(a, np.ones_like(a), p, **kw).M,
    lambda a, p, **kw: an.potential_energy(a, p, **kw),
    lambda a, p, **kw: an.kinetic_energy(a, np.ones_like(a), p, **kw),
    lambda a, p, **kw: an.rigid_acceleration(a, np.zeros_like(a), np.full(a.shape[:-1] + (4,), 20.0), p, **kw),
    lambda a, p, **kw: an.forward_kinematics(a, p, **kw).corners,
    lambda a, p, **kw: an.pinv_increment(a, np.ones(a.shape[:-1] + (4,)), p, **kw),
])
def test_analytic_functions_refuse_poses_outside_the_joint_range(fn, params):
    amax = params.geometry.alpha_max
    edge = np.array([[amax, -amax, 0.3], [0.1, 0.2, -amax]])
    assert np.all(np.isfinite(fn(edge, params)))               # the range is closed
    outside = edge.copy()
    outside[1, 2] = -amax - 1e-9
    with pytest.raises(an.PoseRangeError, match=r"joint 3 at -90\.00 deg \(index \(1, 2\)\)"):
        fn(outside, params)
    allowed = fn(outside, params, allow_outside_range=True)
    np.testing.assert_allclose(allowed, fn(edge, params), atol=1e-6)   # continuous across the edge
