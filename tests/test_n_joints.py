"""The control test on necks of N joints: a trajectory fitted to each neck's force limits, run closed
loop with the real controller and plant (shortened: 0.75 s moves, 0.3 s holds)."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.closed_loop import run_closed_loop
from controllers.computed_torque import ComputedTorqueController
from controllers.elastic_lqr import ElasticLQRController, closed_loop_rates, linearise
from controllers.trajectories import FORCE_MARGIN, feedforward_forces, make_trajectory, workspace_amplitude
from neck_sim.params import default_params
from neck_sim.plant import Plant
from neck_sim.trajectory import TrajectorySample

SHORT = 0.3      # duration scale: 0.75 s moves, 0.3 s holds


def test_paper_neck_keeps_the_paper_trajectory():
    p = default_params(3)
    assert workspace_amplitude("control-test", p) == 1.0
    traj = make_trajectory("control-test", p)
    assert traj.name == "control-test"
    np.testing.assert_allclose(np.degrees(traj.poses).max(), 50.0)


@pytest.mark.parametrize("n", [9, 10])
def test_long_neck_amplitude_is_the_largest_within_the_force_margin(n):
    p = default_params(n)
    s = workspace_amplitude("control-test", p, SHORT)
    limit = FORCE_MARGIN * p.actuation.f_max
    assert 0.05 < s < 1.0
    peak = feedforward_forces(make_trajectory("control-test", p, SHORT, amplitude=s), p).max()
    above = feedforward_forces(make_trajectory("control-test", p, SHORT, amplitude=s + 0.02), p).max()
    assert peak <= limit < above, (peak, limit, above)
    traj = make_trajectory("control-test", p, SHORT)
    assert traj.name == f"control-test x{s:.2f}"
    np.testing.assert_allclose(np.degrees(np.abs(traj.poses).max()), 50.0 * s)


def _check_run(res, traj, p):
    m = res.metrics
    assert res.t[-1] == pytest.approx(traj.duration, abs=2e-3)          # ran to the end
    assert not res.saturated.any() and m.slack_samples == 0
    assert m.force_max <= p.actuation.f_max
    assert np.abs(res.alpha).max() < np.abs(traj.poses).max() + np.radians(2.0)
    return m


@pytest.mark.parametrize("n", [1, 5])
def test_law_2_runs_the_control_test_for_n_joints(n):
    """Law 2 follows the fitted control test on elastic cables up to N = 5 without leaving the
    workspace, saturating or letting a cable go slack (from N = 6 it saturates: README)."""
    p = default_params(n)
    traj = make_trajectory("control-test", p, SHORT)
    m = _check_run(run_closed_loop(Plant(p), ComputedTorqueController(p, 2), traj, progress=False), traj, p)
    # e of §7 (alpha_hat vs alpha_d) 0.2 deg and the truth 1.3 to 2.1 deg: the inextensible
    # estimator's error on stretched cables (as for N = 3, README)
    assert m.tracking_error < 0.3, m.tracking_error
    assert m.tracking_error_true < 2.5, m.tracking_error_true


@pytest.mark.parametrize("n", [1, 5, 10])
def test_elastic_lqr_runs_the_control_test_for_n_joints(n):
    """The elastic LQR follows the fitted control test on the default elastic neck, N = 10
    included, where law 2 diverges: the true angles track to about 0.1-0.2 deg and the neck
    observer, checked against MuJoCo's truth, is within a few hundredths of a degree."""
    p = default_params(n)
    traj = make_trajectory("control-test", p, SHORT)
    m = _check_run(run_closed_loop(Plant(p), ElasticLQRController(p), traj, progress=False), traj, p)
    # measured: N = 1, 5, 10: truth 0.12, 0.18, 0.18 deg; observer vs truth 0.002, 0.022, 0.019 deg
    # (at most 0.02, 0.27, 0.10)
    assert m.tracking_error_true < 0.25, m.tracking_error_true
    assert m.estimation_error_true < 0.04, m.estimation_error_true
    assert m.max_estimation_error_true < 0.4, m.max_estimation_error_true


def test_elastic_lqr_is_stable_for_the_friction_it_does_not_count_on():
    """The gain, designed with 0.3 of eq (37)'s friction slope at rest, keeps the linearised
    10-joint neck stable from almost no friction to the whole slope (the plant's friction
    slope depends on the motor speed), every mode decaying."""
    p = default_params(10)
    ctrl = ElasticLQRController(p)
    for scale in (0.01, 0.3, 1.0):
        rates = closed_loop_rates(linearise(p, t_min=ctrl.t_min, friction_scale=scale), ctrl.K, ctrl.dt)
        assert rates[0].real < -0.05, (scale, rates[0])


def test_the_command_line_runs_the_ten_joint_neck_with_the_elastic_lqr(tmp_path, capsys):
    """`neck-sim simulate --n-joints 10` runs the elastic LQR by default; law 2 stops and names it."""
    import json

    from neck_sim.cli import main

    base = ["simulate", "--n-joints", "10", "--duration-scale", str(SHORT), "--no-log", "--no-progress"]
    assert main(base + ["--law", "2"]) == 2
    err = capsys.readouterr().err
    assert "outside the workspace" in err and "try --controller elastic-lqr" in err
    assert main(base + ["--controller", "elastic-lqr", "--law", "2"]) == 2
    assert "drop --law" in capsys.readouterr().err
    js = tmp_path / "m.json"
    assert main(base + ["--json", str(js)]) == 0
    assert "elastic LQR" in capsys.readouterr().out
    run = json.loads(js.read_text())["elastic lqr"]["metrics"]
    assert run["slack_samples"] == 0 and run["saturated_samples"] == 0 and run["tracking_error_true"] < 0.25


def test_elastic_lqr_feedforward_computed_once_equals_the_per_period_one():
    """The feed-forward that motor_reference computes for the whole reference gives the same
    forces, bit for bit, as law 2's reference alone, computed period by period in step."""
    from controllers.elastic_lqr import ElasticReference
    from controllers.computed_torque import MotorReference

    p = default_params(10)
    traj = make_trajectory("control-test", p, SHORT)
    once, per_period = ElasticLQRController(p), ElasticLQRController(p)
    ref = once.motor_reference(traj.sample(np.arange(0, 600, 7) / p.control.rate_hz))
    assert isinstance(ref, ElasticReference)
    plain = MotorReference(*ref[:len(MotorReference._fields)])
    rng = np.random.default_rng(3)
    theta = np.zeros(p.n_cables)
    for k in range(len(ref.alpha)):
        a, b = once.step(theta, ref.at(k)), per_period.step(theta, plain.at(k))
        for name in ("forces", "gamma", "elongation", "alpha_hat"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=f"{name} at {k}")
        theta = theta + rng.normal(0.0, 0.02, p.n_cables)


def test_elastic_lqr_reference_with_an_infeasible_sample_stops_at_that_sample(monkeypatch):
    """Where the whole reference's feed-forward fails (a sample with no positive forces), the
    controller keeps law 2's reference and computes the feed-forward period by period, so the run
    still stops at the failing sample and not before its first period."""
    import controllers.elastic_lqr as elastic
    from controllers.computed_torque import MotorReference
    from controllers.tension import TensionInfeasibleError

    feedforward = elastic.reference_feedforward

    def failing_at_sample_2(ref, params):
        if np.asarray(ref.alpha).ndim == 1 and not np.array_equal(ref.alpha, bad):
            return feedforward(ref, params)
        raise TensionInfeasibleError("no positive forces at sample (2,)")

    p = default_params(3)
    ctrl = ElasticLQRController(p)
    alpha = np.zeros((3, 3))
    alpha[1:] = 0.1
    alpha[2, 0] = 0.2
    bad = alpha[2]
    monkeypatch.setattr(elastic, "reference_feedforward", failing_at_sample_2)
    ref = ctrl.motor_reference(TrajectorySample(alpha, np.zeros((3, 3)), np.zeros((3, 3))))
    assert type(ref) is MotorReference
    theta = np.zeros(p.n_cables)
    for k in (0, 1):
        assert np.all(ctrl.step(theta, ref.at(k)).forces > 0)
    with pytest.raises(TensionInfeasibleError):
        ctrl.step(theta, ref.at(2))
