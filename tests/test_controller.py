"""Computed-torque controller (eqs 59, 66) and its online estimators (eqs 35, 58)."""

import numpy as np
import pytest

from controllers.computed_torque import ComputedTorqueController, ControlLaw, OutsideWorkspaceError
from controllers.estimators import CableModel, ElongationEstimator, JointAngleEstimator
from controllers.trajectories import TrajectorySample, cycloidal_path
from neck_sim.analytic import (cable_tension, gravity_spring_torque, mass_matrix, motor_angles_rigid, motor_friction,
                               transmission_matrix, transmission_matrix_dot)


def _static_reference(alpha, alpha_dot=None, alpha_ddot=None):
    n = len(alpha)
    z = np.zeros(n)
    return TrajectorySample(np.asarray(alpha, float), z if alpha_dot is None else np.asarray(alpha_dot, float),
                            z if alpha_ddot is None else np.asarray(alpha_ddot, float))


def test_elongation_estimator_settles_on_eq54(params):
    """A constant force at rest: eq (58) converges to the x whose eq (54) tension is that force."""
    for model in (CableModel.CONSTANT, CableModel.VARIABLE):
        est = ElongationEstimator.for_model(model, params)
        force = np.array([10.0, 20.0, 40.0, 30.0])
        for _ in range(20000):                  # 40 s, several c_a / k time constants
            x = est.step(force, np.zeros(4))
        k = params.cables.k_linear if model is CableModel.CONSTANT else params.cables.k
        lam = np.zeros(4) if model is CableModel.CONSTANT else params.cables.lam
        np.testing.assert_allclose(cable_tension(x, np.zeros(4), params, k=k, lam=lam), force, rtol=1e-6)
    assert ElongationEstimator.for_model("inextensible", params) is None


def test_elongation_estimator_friction_and_slack(params):
    est = ElongationEstimator.for_model(CableModel.VARIABLE, params)
    fs = np.asarray(params.friction.f_s)
    winding = est.tension(np.full(4, 30.0), np.full(4, 1e3))     # winding up: friction eats force
    np.testing.assert_allclose(winding, 30.0 - fs * 2 / np.pi * np.arctan(0.5e3))
    unwinding = est.tension(np.full(4, 30.0), np.full(4, -1e3))
    np.testing.assert_allclose(unwinding, 30.0 + fs * 2 / np.pi * np.arctan(0.5e3))
    assert np.all(est.tension(np.full(4, 2.0), np.full(4, 1e3)) == 0)   # a cable cannot push


def test_joint_estimator_uses_the_elongation(params):
    """With the estimator's own elongation fed to the plant's motors, alpha_hat stays exact;
    ignoring it (inextensible model) reads the stretch as motion."""
    alpha = np.radians([20.0, -10.0, 30.0])
    elong = ElongationEstimator.for_model(CableModel.VARIABLE, params)
    probe = ElongationEstimator.for_model(CableModel.VARIABLE, params)
    est = JointAngleEstimator(params, elong)
    rigid = JointAngleEstimator(params, None)
    theta0 = motor_angles_rigid(alpha, params)
    est.reset(alpha, theta0)
    rigid.reset(alpha, theta0)
    force = np.array([20.0, 25.0, 30.0, 35.0])
    for _ in range(500):
        x = probe.step(force, np.zeros(4))
        theta = motor_angles_rigid(alpha, params, x)      # the neck holds still, cables stretch
        a_hat = est.update(theta, force, np.zeros(4))
        a_rigid = rigid.update(theta)
    np.testing.assert_allclose(a_hat, alpha, atol=1e-9)
    assert np.abs(a_rigid - alpha).max() > np.radians(0.5)


def test_gamma_is_eq66_and_forces_produce_it(params):
    alpha = np.radians([15.0, -25.0, 35.0])
    ad = np.array([0.3, -0.2, 0.5])
    add = np.array([1.0, 0.5, -2.0])
    ctrl = ComputedTorqueController(params, law=2)
    ref = ctrl.motor_reference(_static_reference(alpha, ad, add))
    ctrl.reset(alpha, motor_angles_rigid(alpha, params))
    out = ctrl.step(motor_angles_rigid(alpha, params), ref)
    # the estimate is exact (inextensible model, encoders exact) and the first step has no error
    np.testing.assert_allclose(out.alpha_hat, alpha, atol=1e-12)
    k_v = 3 * params.control.omega
    w = add + k_v * ad                                  # e = 0, e' = alpha_d' - 0 at the first step
    np.testing.assert_allclose(out.w, w)
    Z = transmission_matrix(alpha, params)
    theta_dot_d = 1250.0 * Z.T @ ad                     # (R / r_d) Z^T alpha_d', eq (21)
    gamma = mass_matrix(alpha, params) @ w + gravity_spring_torque(alpha, params) + Z @ motor_friction(theta_dot_d, params)
    np.testing.assert_allclose(out.gamma, gamma, rtol=1e-10)
    assert not out.saturated.any()
    np.testing.assert_allclose(Z @ out.forces, gamma, atol=1e-10)
    # eq (65) bounds with desired motor acceleration (R / r_d)(Z^T alpha_d'' + Zdot^T alpha_d')
    theta_ddot_d = 1250.0 * (Z.T @ add + transmission_matrix_dot(alpha, ad, params).T @ ad)
    lb = np.maximum(8.5 + motor_friction(theta_dot_d, params) + 1250.0 * 1e-5 * theta_ddot_d, 2.0)
    assert np.all(out.forces >= lb - 1e-9) and np.any(np.isclose(out.forces, lb))


def test_pid_terms_of_eq59(params):
    """Two periods with a known estimate error: w = alpha_d'' + k_v e' + k_p e + k_i int e."""
    c = ComputedTorqueController(params, 1)
    dt = 1 / params.control.rate_hz
    k_p, k_v, k_i = 3 * 11.0 ** 2, 3 * 11.0, 11.0 ** 3
    ref = c.motor_reference(_static_reference(np.radians([10.0, 10.0, 10.0]), alpha_ddot=[0.5, 0.0, -0.5]))
    c.reset()
    out0 = c.step(np.zeros(4), ref)                          # alpha_hat = 0
    e0 = np.radians([10.0, 10.0, 10.0])
    np.testing.assert_allclose(out0.w, [0.5, 0, -0.5] + k_p * e0 + k_i * e0 * dt)
    pose = np.radians([1.0, 2.0, 3.0])
    out1 = c.step(motor_angles_rigid(pose, params), ref)
    e1 = e0 - out1.alpha_hat
    np.testing.assert_allclose(out1.w, [0.5, 0, -0.5] + k_v * (-out1.alpha_hat / dt) + k_p * e1
                               + k_i * (e0 + e1) * dt)


def test_law_1_has_no_friction_and_beliefs_are_separate(params):
    alpha = np.radians([10.0, 10.0, 10.0])
    ad = np.array([0.4, 0.4, 0.4])
    sample = _static_reference(alpha, ad)
    theta = motor_angles_rigid(alpha, params)
    outs = {}
    for name, kw in (("law1", dict(law=1)), ("law2", dict(law=2)), ("law2_fs", dict(law=2, f_s=np.zeros(4)))):
        c = ComputedTorqueController(params, **kw)
        c.reset(alpha, theta)
        outs[name] = c.step(theta, c.motor_reference(sample))
    Z = transmission_matrix(alpha, params)
    fr = motor_friction(1250.0 * Z.T @ ad, params)
    np.testing.assert_allclose(outs["law2"].gamma - outs["law1"].gamma, Z @ fr, rtol=1e-9)
    np.testing.assert_allclose(outs["law2_fs"].gamma, outs["law1"].gamma, rtol=1e-12)
    # a plant with other friction does not change what the controller believes
    other = params.replace(**{"friction.f_s": (1.0, 1.0, 1.0, 1.0)})
    c = ComputedTorqueController(other, law=2)
    np.testing.assert_allclose(c.f_s, [14.42, 17.65, 18.77, 16.18])
    assert ControlLaw(3).default_cable_model is CableModel.VARIABLE
    assert ComputedTorqueController(params, 3).elongation is not None
    assert ComputedTorqueController(params, 2).elongation is None


def test_controller_without_pulleys(params):
    """r = 0 in the controller only: Z1 is diagonal, the law still distributes tensions."""
    bare = params.replace(**{"geometry.r": 0.0})
    alpha = np.radians([30.0, 20.0, -40.0])
    c = ComputedTorqueController(bare, 2)
    theta = motor_angles_rigid(alpha, params)            # the real neck has pulleys
    c.reset(alpha, theta)
    out = c.step(theta, c.motor_reference(_static_reference(alpha)))
    Z0 = transmission_matrix(alpha, bare)
    assert np.allclose(np.triu(Z0[:, :3], 1), 0)
    np.testing.assert_allclose(Z0 @ out.forces, out.gamma, atol=1e-10)


def test_estimate_outside_the_workspace_is_an_error(params):
    c = ComputedTorqueController(params, 2)
    c.reset()
    ref = c.motor_reference(_static_reference(np.zeros(3)))
    c.step(np.zeros(4), ref)
    far = motor_angles_rigid(np.radians([95.0, 0.0, 0.0]), params, allow_outside_range=True)   # probes past the edge
    with pytest.raises(OutsideWorkspaceError, match="joint 1") as err:
        c.step(far, ref)
    # the message gives the estimate that left the range (one eq-35 step from straight: near 95 deg)
    shown = float(str(err.value).split("estimated at ")[1].split(" deg")[0])
    assert 90.0 < shown < 110.0, str(err.value)


def test_bad_arguments_are_named(params):
    with pytest.raises(ValueError, match="law"):
        ComputedTorqueController(params, 4)
    with pytest.raises(ValueError, match="f_s"):
        ComputedTorqueController(params, 2, f_s=[1.0, 2.0])
    with pytest.raises(ValueError, match="cable"):
        ComputedTorqueController(params, 2, cable_model="rubber")
    c = ComputedTorqueController(params, 2)
    c.reset()
    ref = c.motor_reference(_static_reference(np.zeros(3)))
    with pytest.raises(ValueError, match="theta"):
        c.step(np.zeros(3), ref)
    with pytest.raises(ValueError, match="theta.*NaN"):
        c.step(np.array([0.0, np.nan, 0.0, 0.0]), ref)


def test_reference_is_batched(params):
    traj = cycloidal_path(np.radians([[0, 0, 0], [40, 30, 20]]), 1.0, 0.5)
    c = ComputedTorqueController(params, 2)
    t = np.linspace(0, traj.duration, 50)
    batch = c.motor_reference(traj.sample(t))
    one = c.motor_reference(traj.sample(t[17]))
    for a, b in zip(batch.at(17), one):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)
