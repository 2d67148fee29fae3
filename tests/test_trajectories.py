"""Cycloidal segments and the paper's two trajectories."""

import numpy as np
import pytest

from controllers.trajectories import (Trajectory, control_test_trajectory, cycloidal_path,
                                      identification_trajectory, make_trajectory)
from neck_sim.params import default_params


def test_derivatives_agree_with_finite_differences():
    traj = cycloidal_path([[0.0, 0.1], [0.5, -0.3], [-0.2, 0.0]], move_time=1.3, hold_time=0.4)
    t = np.linspace(0, traj.duration, 20001)
    s = traj.sample(t)
    dt = t[1] - t[0]
    np.testing.assert_allclose(np.gradient(s.alpha, dt, axis=0)[1:-1], s.alpha_dot[1:-1], atol=2e-5)
    # the jerk jumps at the knots (cycloids are C2, not C3): a central difference there is off by
    # about jerk * dt / 4 ~ 1e-3 rad/s^2, against accelerations of up to 3 rad/s^2
    np.testing.assert_allclose(np.gradient(s.alpha_dot, dt, axis=0)[1:-1], s.alpha_ddot[1:-1], atol=2e-3)


def test_knots_reached_at_rest():
    poses = np.radians([[0, 0, 0], [50, 50, 50], [0, 0, 0]])
    traj = cycloidal_path(poses, move_time=2.0, hold_time=1.0)
    np.testing.assert_allclose(traj.times, [0, 1, 3, 4, 6, 7])
    s = traj.sample(traj.times)
    np.testing.assert_allclose(s.alpha, poses[[0, 0, 1, 1, 2, 2]], atol=1e-15)
    np.testing.assert_allclose(s.alpha_dot, 0, atol=1e-15)
    np.testing.assert_allclose(s.alpha_ddot, 0, atol=1e-12)
    mid = traj.sample(2.0)                          # half-way through the move: half-way, peak speed 2/T
    np.testing.assert_allclose(mid.alpha, poses[1] / 2)
    np.testing.assert_allclose(mid.alpha_dot, poses[1] / 2.0 * 2)
    outside = traj.sample(np.array([-1.0, 100.0]))
    np.testing.assert_allclose(outside.alpha, poses[[0, 2]])
    assert np.all(outside.alpha_dot == 0) and np.all(outside.alpha_ddot == 0)


def test_sample_is_vectorised_over_any_shape():
    traj = control_test_trajectory(default_params(3))
    t = np.linspace(0, 15, 24).reshape(2, 3, 4)
    s = traj.sample(t)
    assert s.alpha.shape == (2, 3, 4, 3)
    np.testing.assert_allclose(s.alpha[1, 2, 3], traj.sample(t[1, 2, 3]).alpha)


def test_control_test_trajectory_of_section_7():
    p = default_params(3)
    traj = control_test_trajectory(p)
    assert traj.duration == pytest.approx(1 + 4 * 3.5)
    np.testing.assert_allclose(np.degrees(traj.sample(3.5).alpha), [50, 50, 50])
    np.testing.assert_allclose(np.degrees(traj.sample(10.5).alpha), [-30, -40, -50])
    np.testing.assert_allclose(traj.sample([7.0, 15.0]).alpha, 0, atol=1e-15)
    five = control_test_trajectory(default_params(5), move_time=1.0, hold_time=0.5)
    np.testing.assert_allclose(np.degrees(five.poses.min(axis=0)), [-30, -35, -40, -45, -50])
    assert five.duration == pytest.approx(0.5 + 4 * 1.5)


def test_identification_trajectory_of_section_5_2_2():
    p = default_params(3)
    traj = identification_trajectory(p)
    moves = traj.poses[1:][np.any(np.diff(traj.poses, axis=0) != 0, axis=1)]
    assert len(moves) == 24
    deg = np.round(np.degrees(moves)).astype(int)
    a = np.array([40, 30, 20])
    for seq, flip in enumerate([None, 0, 1, 2]):
        amp = a.copy()
        if flip is not None:
            amp[flip] *= -1
        want = [amp, -amp, 0 * amp, -amp, amp, 0 * amp]
        np.testing.assert_array_equal(deg[6 * seq: 6 * seq + 6], want)


def test_duration_scale_and_names():
    p = default_params(3)
    slow = make_trajectory("control-test", p, duration_scale=2.0)
    assert slow.duration == pytest.approx(30.0)
    with pytest.raises(ValueError, match="unknown name 'circle'"):
        make_trajectory("circle", p)
    with pytest.raises(ValueError, match="duration_scale"):
        make_trajectory("control-test", p, duration_scale=0)


def test_bad_trajectories_are_refused():
    with pytest.raises(ValueError, match="strictly increasing"):
        Trajectory(np.array([0.0, 1.0, 1.0]), np.zeros((3, 2)))
    with pytest.raises(ValueError, match="poses"):
        Trajectory(np.array([0.0, 1.0]), np.zeros((3, 2)))
    with pytest.raises(ValueError, match="move_time"):
        cycloidal_path(np.zeros((2, 3)), move_time=0.0)
    with pytest.raises(ValueError, match="NaN"):
        control_test_trajectory(default_params(3)).sample(np.nan)
    narrow = default_params(3).replace(**{"geometry.alpha_max": np.radians(45)})
    with pytest.raises(ValueError, match="outside the workspace"):
        control_test_trajectory(narrow)
