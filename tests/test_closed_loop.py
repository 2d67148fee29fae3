"""The closed-loop runner: recording, metrics, failures, N = 5, and the paper's control test."""

import json

import numpy as np
import pytest

from controllers.closed_loop import compute_metrics, run_closed_loop
from controllers.computed_torque import ComputedTorqueController
from controllers.experiments import TABLE3_CASES, format_table3
from controllers.trajectories import control_test_trajectory, cycloidal_path
from neck_sim.analytic import estimate_alpha_pinv
from neck_sim.logs import MJCF_ATTACHMENT, read_log
from neck_sim.params import default_params
from neck_sim.plant import Plant


def test_runner_records_what_the_controller_saw(params):
    traj = control_test_trajectory(params, move_time=0.6, hold_time=0.2)
    plant = Plant(params, rigid_cables=True)        # rigid cables: the rigid estimator is exact
    res = run_closed_loop(plant, ComputedTorqueController(params, 2), traj, progress=False)
    T = int(round(traj.duration * 500)) + 1
    assert res.t.shape == (T,) and res.alpha_hat.shape == (T, 3) and res.force.shape == (T, 4)
    np.testing.assert_allclose(np.diff(res.t), 1 / 500)
    np.testing.assert_allclose(res.alpha_d, traj.sample(res.t).alpha)
    # the online estimate is eq (35) applied to the recorded encoders (inextensible model)
    offline = estimate_alpha_pinv(res.theta, params, alpha0=res.alpha_d[0])
    np.testing.assert_allclose(res.alpha_hat, offline, atol=1e-12)
    assert abs(res.metrics.camera_frames - 30 * traj.duration) < 1.5         # a 30 Hz camera
    assert np.all(np.diff(res.camera_t) > 0)
    m = res.metrics
    assert m.tracking_error < 0.5 and m.slack_samples == 0 and m.saturated_samples == 0
    assert m.force_min >= params.actuation.f_min - 1e-9 and m.force_max <= params.actuation.f_max
    # camera error is dominated by the camera's own 1 deg noise: E|N(0, 1 deg)| = 0.80 deg
    assert 0.6 < m.estimation_error_camera < 1.0
    assert m.estimation_error_true < 0.05


def test_law_1_needs_more_force_than_law_2(params):
    traj = control_test_trajectory(params, move_time=0.8, hold_time=0.2)
    m1 = run_closed_loop(Plant(params), ComputedTorqueController(params, 1), traj, progress=False).metrics
    m2 = run_closed_loop(Plant(params), ComputedTorqueController(params, 2), traj, progress=False).metrics
    # friction compensation: smaller tracking error (§7), lower forces, f_min reached while
    # unwinding (Fig. 14)
    assert m2.tracking_error < m1.tracking_error
    assert m2.force_mean < m1.force_mean
    assert m2.force_min == pytest.approx(params.actuation.f_min)


class _RunawayEncoder(Plant):
    """Motor 1's encoder counts up on its own (a broken encoder)."""

    def encoders(self):
        th = super().encoders()
        th[0] += 2.0 * self.time / 0.002
        return th


def test_controller_failure_stops_the_run(params, tmp_path):
    narrow = params.replace(**{"geometry.alpha_max": np.radians(80.0)})
    traj = cycloidal_path([np.zeros(3), np.radians([85.0, 0.0, 0.0])], move_time=1.0)
    with pytest.raises(ValueError, match="outside the workspace"):
        run_closed_loop(Plant(params), ComputedTorqueController(narrow, 2), traj, progress=False)
    hold = cycloidal_path(np.zeros((2, 3)), move_time=1.0)
    with pytest.raises(RuntimeError, match=r"closed loop stopped at t = 0\.\d+ s: alpha_hat: joint 1"):
        run_closed_loop(_RunawayEncoder(params), ComputedTorqueController(params, 2), hold, progress=False,
                        log_path=tmp_path / "broken.mcap")
    assert not list(tmp_path.iterdir())           # no log, not even a temporary file, is left


def test_plant_and_controller_rates_must_agree(params):
    slow = params.replace(**{"control.rate_hz": 250.0})
    traj = cycloidal_path(np.zeros((2, 3)), move_time=0.1)
    with pytest.raises(ValueError, match="control rate"):
        run_closed_loop(Plant(slow), ComputedTorqueController(params, 2), traj, progress=False)

def test_control_test_on_the_default_plant(params):
    """Acceptance: the whole §7 trajectory (15 s at 500 Hz) on the default
    MuJoCo plant, law 2: mean tracking error under 1 deg and no slack cable."""
    traj = control_test_trajectory(params)
    res = run_closed_loop(Plant(params), ComputedTorqueController(params, 2), traj, progress=False)
    m = res.metrics
    assert m.samples == 7501 and m.duration == pytest.approx(15.0)
    assert m.tracking_error < 1.0
    assert m.slack_samples == 0 and m.take_up < 0.05
    assert m.saturated_samples == 0
    # the estimate is worse than the tracking: elastic cables read as motion by a rigid estimator
    assert 0.3 < m.estimation_error_true < 3.0
    assert res.loop_gap.max() < 1e-4


def test_elastic_estimator_improves_the_estimate(params):
    """§7: law 3 estimates alpha better than law 2 (the elastic model), law 1 leaves cable 1
    slack at t_min = 8.5 N unless t_min is raised (design notes)."""
    traj = control_test_trajectory(params, move_time=1.0, hold_time=0.4)
    m2 = run_closed_loop(Plant(params), ComputedTorqueController(params, 2), traj, progress=False).metrics
    m3 = run_closed_loop(Plant(params), ComputedTorqueController(params, 3), traj, progress=False).metrics
    assert m3.estimation_error_true < 0.6 * m2.estimation_error_true
    assert m3.tracking_error < 1.0 and m3.slack_samples == 0
    # law 1 ignores the friction that holds cable 1 back while it winds up (joint 1 coming back
    # from 50 deg): it goes slack
    there_and_back = cycloidal_path(np.radians([[0, 0, 0], [50, 50, 50], [0, 0, 0]]), 1.0, 0.4)
    m1 = run_closed_loop(Plant(params), ComputedTorqueController(params, 1), there_and_back, progress=False).metrics
    assert m1.slack_samples > 10 and m1.slack_per_cable[1:] == (0, 0, 0)
    m1_safe = run_closed_loop(Plant(params), ComputedTorqueController(params, 1, t_min=15.0), there_and_back,
                              progress=False).metrics
    assert m1_safe.slack_samples == 0


def test_five_joints_on_the_plant():
    p5 = default_params(5)
    traj = control_test_trajectory(p5, move_time=1.0, hold_time=0.4)
    res = run_closed_loop(Plant(p5), ComputedTorqueController(p5, 2), traj, progress=False)
    assert res.force.shape[1] == 6
    assert res.metrics.tracking_error < 1.0 and res.metrics.slack_samples == 0


def test_log_holds_the_run(params, tmp_path):
    traj = control_test_trajectory(params, move_time=0.5, hold_time=0.2)
    path = tmp_path / "run.mcap"
    res = run_closed_loop(Plant(params, seed=3), ComputedTorqueController(params, 3), traj, progress=False,
                          log_path=path)
    log = read_log(path, require=("motors", "camera", "reference", "estimate", "truth"))
    np.testing.assert_allclose(log.motors.t, res.t, atol=1e-9)
    np.testing.assert_allclose(log.motors.theta, res.theta, rtol=1e-12)
    np.testing.assert_allclose(log.motors.force, res.force, rtol=1e-12)
    np.testing.assert_allclose(log.estimate.alpha_hat, res.alpha_hat, rtol=1e-12)
    np.testing.assert_allclose(log.reference.alpha_d, res.alpha_d, rtol=1e-12)
    np.testing.assert_allclose(log.truth.tension, res.tension, rtol=1e-12)
    np.testing.assert_allclose(log.camera.alpha, res.camera_alpha, rtol=1e-12)
    assert MJCF_ATTACHMENT in log.attachments
    assert log.params.n_joints == 3


def test_simulate_command(tmp_path, capsys):
    from neck_sim.cli import main

    out_json = tmp_path / "m.json"
    rc = main(["simulate", "--law", "2", "3", "--duration-scale", "0.2", "-o", str(tmp_path / "run.mcap"),
               "--json", str(out_json), "--plots", str(tmp_path / "fig"), "--no-progress"])
    assert rc == 0
    text = capsys.readouterr().out
    assert "law 2" in text and "law 3" in text
    assert "(paper)" not in text              # a shortened trajectory is not the paper's experiment
    summary = json.loads(out_json.read_text())
    assert set(summary) == {"law 2", "law 3"}
    for label, tag in (("law 2", "law2"), ("law 3", "law3")):
        log = read_log(tmp_path / f"run-{tag}.mcap", require=("motors", "estimate", "truth"))
        hat = log.estimate.alpha_hat
        d = read_log(tmp_path / f"run-{tag}.mcap", topics=["reference"]).reference.alpha_d
        # the JSON's tracking error is the log's, recomputed here from the recorded topics
        assert summary[label]["metrics"]["tracking_error"] == pytest.approx(np.degrees(np.abs(hat - d).mean()))
        assert summary[label]["info"]["law"] == int(tag[-1])
    pngs = sorted(p.name for p in (tmp_path / "fig").iterdir())
    assert pngs == ["angles_law_2.png", "angles_law_3.png", "estimation_error.png", "forces.png",
                    "tracking_error.png"]
    assert all((tmp_path / "fig" / p).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in pngs)


@pytest.mark.parametrize("argv, message", [
    (["--duration-scale", "0"], "argument --duration-scale: must be"),
    (["-o", "run.txt"], "end in .mcap"),
    (["--table3", "--law", "1", "2"], "one law"),
    (["--table3", "--no-pulleys"], "--table3 chooses"),
])
def test_simulate_command_refuses_bad_options(argv, message, capsys, tmp_path, monkeypatch):
    from neck_sim.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "--no-progress", *argv]) == 2
    assert message in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_metrics_on_known_arrays():
    t = np.arange(6) * 0.002
    alpha_d = np.zeros((6, 2))
    alpha_hat = np.radians(np.tile([[1.0, -3.0]], (6, 1)))
    alpha = np.radians(np.tile([[0.5, -3.0]], (6, 1)))
    tension = np.array([[0, 0], [0, 1], [1, 1], [2, 0], [2, 2], [3, 3]], dtype=float)
    force = np.array([[2, 9]] * 6, dtype=float)
    saturated = np.zeros((6, 2), dtype=bool)
    saturated[4, 1] = True
    cam_t = np.array([0.001, 0.003])
    cam_a = np.radians([[2.0, -3.0], [1.0, -1.0]])
    m = compute_metrics(t, alpha_d, alpha_hat, alpha, tension, force, saturated, cam_t, cam_a)
    assert m.tracking_error == pytest.approx(2.0)                # (1 + 3) / 2 deg
    assert m.estimation_error_true == pytest.approx(0.25)        # (0.5 + 0) / 2
    assert m.estimation_error_camera == pytest.approx((1 + 0 + 0 + 2) / 4)
    assert m.take_up == pytest.approx(0.004)                     # all taut first at sample 2
    assert m.slack_samples == 1 and m.slack_per_cable == (0, 1)  # the take-up is not slack
    assert m.saturated_samples == 1
    assert (m.force_min, m.force_max) == (2.0, 9.0)


def test_table3_layout():
    from types import SimpleNamespace

    fake = {case: SimpleNamespace(metrics=SimpleNamespace(estimation_error_true=1.0 + i, tracking_error=0.1 * i))
            for i, case in enumerate(TABLE3_CASES)}
    text = format_table3(fake)
    rows = text.splitlines()
    assert rows[2].startswith("with pulleys") and rows[3].startswith("without pulleys")
    assert "e_a 1.00 (0.35), e 0.00 (0.08)" in rows[2] and "e_a 2.00 (1.68), e 0.10 (0.11)" in rows[2]
    assert "e_a 3.00 (2.00), e 0.20 (0.21)" in rows[3] and "e_a 4.00 (2.88), e 0.30 (0.26)" in rows[3]


def test_closed_loop_log_replays_exactly_with_hidden_effects(params, tmp_path):
    """The runner records the plant (seed, effects, parameters), so replay rebuilds it exactly."""
    from neck_sim.effects import Effects, Payload
    from neck_sim.replay import replay

    traj = control_test_trajectory(params, move_time=0.4, hold_time=0.1)
    plant = Plant(params.replace(**{"friction.c_s": 0.7}), effects=Effects(payload=Payload(mass=0.03)), seed=11)
    path = tmp_path / "run.mcap"
    run_closed_loop(plant, ComputedTorqueController(params, 2), traj, progress=False, log_path=path)
    res = replay(path)
    np.testing.assert_array_equal(res.theta, res.theta_log)
    np.testing.assert_allclose(res.alpha, res.alpha_log, atol=1e-12)
    assert not res.notes
