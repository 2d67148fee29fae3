"""The sign conventions written in neck_sim.analytic.cables, held here once."""

import numpy as np

import neck_sim.analytic as an


def test_positive_alpha_bends_left_and_lengthens_the_right_side(params):
    sd = an.side_lengths(0.3, params)
    assert sd.l_r > sd.l_l
    assert an.forward_kinematics(np.array([0.3, 0.3, 0.3]), params).head_position[0] < 0


def test_winding_a_right_motor_bends_right(params):
    """theta > 0 winds the cable up; for rigid cables winding c1 gives alpha_1 < 0."""
    theta = an.motor_angles_rigid(np.array([-0.1, 0.0, 0.0]), params)
    assert theta[0] > 0 and theta[3] < 0


def test_tension_torques(params):
    """tau = Z t: right cables turn their joint negative, the left cable turns every joint positive."""
    Z = an.transmission_matrix(np.zeros(3), params)
    assert np.all(np.diag(Z[:, :3]) < 0)
    assert np.all(Z[:, 3] > 0)


def test_elongation_sign(params):
    """x_c = l_c - l_c0 + (r_d/R) theta: winding up at a fixed pose stretches the cable."""
    alpha = np.array([0.2, -0.1, 0.3])
    th = an.motor_angles_rigid(alpha, params)
    np.testing.assert_allclose(an.elongation(th, alpha, params), 0, atol=1e-16)
    assert np.all(an.elongation(th + 0.1, alpha, params) > 0)


def test_velocity_relation(params, rng):
    """Z^T alpha_dot = (r_d/R) theta_dot - x_dot, checked by finite differences in time."""
    alpha = rng.uniform(-1, 1, 3)
    ad = rng.normal(size=3)
    theta = rng.normal(size=4)
    td = rng.normal(size=4)
    h = 1e-6
    x = lambda s: an.elongation(theta + s * td, alpha + s * ad, params)
    x_dot = (x(h) - x(-h)) / (2 * h)
    a = params.actuation
    np.testing.assert_allclose(an.transmission_matrix(alpha, params).T @ ad, a.r_d / a.R * td - x_dot, atol=1e-9)
