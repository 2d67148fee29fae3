"""The closed-loop runner: recording, metrics, failures, N = 5, and the paper's control test."""

from typing import NamedTuple

import numpy as np
import pytest

from controllers.closed_loop import run_closed_loop
from controllers.computed_torque import ComputedTorqueController
from controllers.trajectories import control_test_trajectory, cycloidal_path
from neck_sim.analytic import (cable_kinematics, estimate_alpha_pinv, motor_angles_rigid, motor_friction,
                               rigid_acceleration)
from neck_sim.params import default_params


class _Truth(NamedTuple):
    alpha: np.ndarray
    alpha_dot: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    tension: np.ndarray
    elongation: np.ndarray
    loop_gap: float


class RigidAnalyticPlant:
    """A cheap stand-in with the Plant interface: inextensible cables, eq (32) with friction,
    semi-implicit Euler at half the control period; quantised encoders, 30 Hz noisy camera.
    Tension from eq (31) (negative = the cable would have to push: slack)."""

    xml = None

    def __init__(self, params, seed=0):
        self.params = params
        self.seed = seed
        self.reset()

    def reset(self, alpha0=None):
        n = self.params.n_joints
        self.alpha = np.zeros(n) if alpha0 is None else np.array(alpha0, dtype=float)
        self.alpha_dot = np.zeros(n)
        self.time = 0.0
        self._rng = np.random.default_rng(self.seed)
        self._frame, self._next_frame = None, 0
        self._tension = np.zeros(n + 1)

    def step(self, forces):
        p = self.params
        f = np.clip(np.asarray(forces, dtype=float), 0, p.actuation.f_max)
        period = 1 / p.control.rate_hz
        for _ in range(2):
            acc = rigid_acceleration(self.alpha, self.alpha_dot, f, p)
            self.alpha_dot = self.alpha_dot + period / 2 * acc
            self.alpha = self.alpha + period / 2 * self.alpha_dot
        ck = cable_kinematics(self.alpha, self.alpha_dot, p)
        ratio = p.actuation.R / p.actuation.r_d
        theta_dot = ratio * ck.Z.T @ self.alpha_dot
        theta_ddot = ratio * (ck.Z.T @ acc + ck.Zdot.T @ self.alpha_dot)
        self._tension = f - motor_friction(theta_dot, p) - p.actuation.I_a * ratio * theta_ddot
        self._frame = None
        if self._next_frame / p.sensors.camera_rate_hz <= self.time + period + 1e-12:
            noise = self._rng.normal(0, p.sensors.camera_noise, p.n_joints)
            self._frame = (self._next_frame / p.sensors.camera_rate_hz, self.alpha + noise)
            self._next_frame += 1
        self.time += period

    def encoders(self):
        res = self.params.sensors.encoder_resolution
        return np.round(motor_angles_rigid(self.alpha, self.params) / res) * res

    def camera_frame(self):
        return self._frame

    def truth(self):
        p = self.params
        z = cable_kinematics(self.alpha, self.alpha_dot, p).Z
        return _Truth(self.alpha.copy(), self.alpha_dot.copy(), motor_angles_rigid(self.alpha, p),
                      (p.actuation.R / p.actuation.r_d) * z.T @ self.alpha_dot, self._tension.copy(),
                      np.zeros(p.n_cables), 0.0)


def test_runner_records_what_the_controller_saw(params):
    traj = control_test_trajectory(params, move_time=0.6, hold_time=0.2)
    res = run_closed_loop(RigidAnalyticPlant(params), ComputedTorqueController(params, 2), traj, progress=False)
    T = int(round(traj.duration * 500)) + 1
    assert res.t.shape == (T,) and res.alpha_hat.shape == (T, 3) and res.force.shape == (T, 4)
    np.testing.assert_allclose(np.diff(res.t), 1 / 500)
    np.testing.assert_allclose(res.alpha_d, traj.sample(res.t).alpha)
    # the online estimate is eq (35) applied to the recorded encoders (inextensible model)
    offline = estimate_alpha_pinv(res.theta, params, alpha0=res.alpha_d[0])
    np.testing.assert_allclose(res.alpha_hat, offline, atol=1e-12)
    assert abs(res.metrics.camera_frames - (30 * traj.duration + 1)) <= 1    # frames at 0, 1/30, ...
    assert np.all(np.diff(res.camera_t) > 0)
    m = res.metrics
    assert m.tracking_error < 0.5 and m.slack_samples == 0 and m.saturated_samples == 0
    assert m.force_min >= params.actuation.f_min - 1e-9 and m.force_max <= params.actuation.f_max
    # camera error is dominated by the camera's own 1 deg noise: E|N(0, 1 deg)| = 0.80 deg
    assert 0.6 < m.estimation_error_camera < 1.0
    assert m.estimation_error_true < 0.05


def test_law_1_needs_more_force_than_law_2(params):
    traj = control_test_trajectory(params, move_time=0.8, hold_time=0.2)
    m1 = run_closed_loop(RigidAnalyticPlant(params), ComputedTorqueController(params, 1), traj, progress=False).metrics
    m2 = run_closed_loop(RigidAnalyticPlant(params), ComputedTorqueController(params, 2), traj, progress=False).metrics
    # friction compensation: smaller tracking error (§7), lower forces, f_min reached while
    # unwinding (Fig. 14)
    assert m2.tracking_error < m1.tracking_error
    assert m2.force_mean < m1.force_mean
    assert m2.force_min == pytest.approx(params.actuation.f_min)


def test_five_joints(rng):
    p5 = default_params(5)
    traj = control_test_trajectory(p5, move_time=0.8, hold_time=0.2)
    res = run_closed_loop(RigidAnalyticPlant(p5), ComputedTorqueController(p5, 2), traj, progress=False)
    assert res.alpha_hat.shape[1] == 5 and res.force.shape[1] == 6
    assert res.metrics.tracking_error < 1.0
    assert res.metrics.slack_samples == 0


class _RunawayEncoder(RigidAnalyticPlant):
    """Motor 1's encoder counts up on its own (a broken encoder)."""

    def encoders(self):
        th = super().encoders()
        th[0] += 2.0 * self.time / 0.002
        return th


def test_controller_failure_stops_the_run(params, tmp_path):
    narrow = params.replace(**{"geometry.alpha_max": np.radians(80.0)})
    traj = cycloidal_path([np.zeros(3), np.radians([85.0, 0.0, 0.0])], move_time=1.0)
    with pytest.raises(ValueError, match="outside the workspace"):
        run_closed_loop(RigidAnalyticPlant(params), ComputedTorqueController(narrow, 2), traj, progress=False)
    hold = cycloidal_path(np.zeros((2, 3)), move_time=1.0)
    with pytest.raises(RuntimeError, match=r"closed loop stopped at t = 0\.\d+ s: alpha_hat: joint 1"):
        run_closed_loop(_RunawayEncoder(params), ComputedTorqueController(params, 2), hold, progress=False,
                        log_path=tmp_path / "broken.mcap" if _logs_available() else None)
    assert not list(tmp_path.iterdir())           # no log, not even a temporary file, is left


def _logs_available():
    try:
        import neck_sim.logs  # noqa: F401
    except ImportError:
        return False
    return hasattr(neck_sim.logs, "LogWriter")


def test_plant_and_controller_rates_must_agree(params):
    slow = params.replace(**{"control.rate_hz": 250.0})
    traj = cycloidal_path(np.zeros((2, 3)), move_time=0.1)
    with pytest.raises(ValueError, match="control rate"):
        run_closed_loop(RigidAnalyticPlant(slow), ComputedTorqueController(params, 2), traj, progress=False)
