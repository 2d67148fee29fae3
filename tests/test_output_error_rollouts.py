"""The output-error rollout engine (identification.output_error.rollouts) against serial plants.

One short closed-loop run (about 2.2 s, two excitation moves) is logged per module; its forces
are re-simulated for a few parameter sets on MuJoCo's batch threads and compared, bit for bit,
with the same forces stepped through one :class:`neck_sim.plant.Plant` per set (the plant's own
stepping path, with no camera noise so that its frames are the true joint angles).
"""

import os

import numpy as np
import pytest

from identification.output_error.rollouts import Experiment, cable_params, rollout
from neck_sim.effects import Effects
from neck_sim.effects.camera_delay import CameraDelay
from neck_sim.params import default_params

INTEGRATOR = "implicitfast"


@pytest.fixture(scope="module")
def logged(tmp_path_factory):
    from controllers.closed_loop import run_closed_loop
    from controllers.computed_torque import ComputedTorqueController
    from identification.excitation import sequences_trajectory
    from neck_sim.logs import read_log
    from neck_sim.plant import Plant

    p = default_params(3)
    traj = sequences_trajectory(np.radians([[30.0, 20.0, -25.0]]), move_time=0.8, hold_time=0.2)
    path = tmp_path_factory.mktemp("oeroll") / "run.mcap"
    run_closed_loop(Plant(p, seed=3), ComputedTorqueController(p, law=1), traj, log_path=path, progress=False)
    return p, read_log(path, topics=("motors", "camera", "reference"))


def _sets(p):
    """Three parameter sets around the plant's: the truth, then f_s, k, lambda and c_a moved."""
    f_s, k, lam, c_a = (np.array(v, dtype=float) for v in (p.friction.f_s, p.cables.k, p.cables.lam, p.cables.c_a))
    up, down = np.array([[1.0], [1.1], [0.8]]), np.array([[1.0], [0.8], [1.1]])
    return cable_params(p, f_s=f_s * up, k=k * down, lam=lam * up, c_a=c_a * down)


def _serial(params, effects, exp, theta=None):
    """Encoders before each period and (stamp, alpha) of every camera frame, one Plant stepping
    alone; with ``theta`` also the motor angles before each period."""
    from neck_sim.plant import Plant

    plant = Plant(params.replace(**{"sensors.camera_noise": 0.0}), effects, seed=0, integrator=INTEGRATOR)
    plant.reset(alpha0=exp.alpha0)
    enc, stamps, alpha = [], [], []
    for f in exp.force:
        enc.append(plant.encoders())
        if theta is not None:
            theta.append(plant.truth().theta)
        plant.step(f)
        frame = plant.camera_frame()
        if frame is not None:
            stamps.append(frame[0])
            alpha.append(frame[1])
    return np.array(enc), np.array(stamps), np.array(alpha)


def test_batch_rollout_equals_serial_plant_runs_bit_for_bit(logged):
    p, log = logged
    exp = Experiment.from_log(log)
    assert exp.n_periods > 600            # more than one batch call (500 periods each)
    sets = _sets(p)
    out = rollout(exp, sets, integrator=INTEGRATOR, nthread=2)
    assert out.encoders.shape == (3, exp.n_periods, p.n_cables)
    assert out.camera_alpha.shape == (3, exp.camera_t.size, p.n_joints)
    assert not out.diverged.any() and out.reasons == ("", "", "")
    raw = rollout(exp, sets, integrator=INTEGRATOR, nthread=2, quantise=False)
    for i, params in enumerate(sets):
        theta = []
        enc, stamps, alpha = _serial(params, None, exp, theta)
        np.testing.assert_array_equal(out.encoders[i], enc)
        np.testing.assert_array_equal(raw.encoders[i], theta)
        np.testing.assert_array_equal(raw.camera_alpha[i], out.camera_alpha[i])
        frames = np.searchsorted(stamps, exp.camera_t)
        np.testing.assert_array_equal(stamps[frames], exp.camera_t)
        np.testing.assert_array_equal(out.camera_alpha[i], alpha[frames])
    # the truth's rollout is the logged run itself (the closed loop stepped the same plant)
    np.testing.assert_array_equal(out.encoders[0], log.motors.theta)
    # the sets differ, so the comparison above could fail
    assert np.abs(out.encoders[1] - out.encoders[0]).max() > 100 * p.sensors.encoder_resolution


def test_thread_count_and_grouping_do_not_change_the_result(logged, monkeypatch):
    import identification.output_error.rollouts as R

    p, log = logged
    exp = Experiment.from_log(log)
    sets = _sets(p)
    two = rollout(exp, sets, integrator=INTEGRATOR, nthread=2)
    monkeypatch.setattr(R, "MAX_GROUP", 2)
    one = rollout(exp, sets, integrator=INTEGRATOR, nthread=1)
    np.testing.assert_array_equal(one.encoders, two.encoders)
    np.testing.assert_array_equal(one.camera_alpha, two.camera_alpha)


def test_camera_lag_reads_the_frame_the_lagging_camera_shows(logged):
    p, log = logged
    exp = Experiment.from_log(log)
    effects = Effects.of(CameraDelay(delay=0.02))
    enc, stamps, alpha = _serial(p, effects, exp)
    keep = stamps <= exp.n_periods * exp.period
    lagged = Experiment(exp.force, exp.period, stamps[keep], exp.alpha0)
    out = rollout(lagged, [p], effects, integrator=INTEGRATOR, nthread=1)
    np.testing.assert_array_equal(out.camera_alpha[0], alpha[keep])
    np.testing.assert_array_equal(out.encoders[0], enc)


def test_a_diverging_set_is_flagged_and_the_others_run_on(logged):
    p, log = logged
    exp = Experiment.from_log(log)
    sets = _sets(p)
    # implicitfast with c_a = 1e6 N s/m on 20 g bars: MuJoCo reports a singular inertia at once
    bad = p.replace(**{"cables.c_a": (1e6,) * p.n_cables})
    out = rollout(exp, [sets[0], bad, sets[1]], integrator=INTEGRATOR, nthread=2)
    assert out.diverged.tolist() == [False, True, False]
    assert "singular inertia" in out.reasons[1] and out.reasons[0] == out.reasons[2] == ""
    assert out.diverged_at[1] < 0.05 and np.isnan(out.diverged_at[[0, 2]]).all()
    k = int(round(out.diverged_at[1] / exp.period))
    assert np.isfinite(out.encoders[1, : k + 1]).all() and np.isnan(out.encoders[1, k + 1:]).all()
    assert np.isnan(out.camera_alpha[1]).all()
    ref = rollout(exp, [sets[0], sets[1]], integrator=INTEGRATOR, nthread=2)
    np.testing.assert_array_equal(out.encoders[[0, 2]], ref.encoders)
    np.testing.assert_array_equal(out.camera_alpha[[0, 2]], ref.camera_alpha)


def _one_line_error(fn, *words):
    with pytest.raises(ValueError) as err:
        fn()
    msg = str(err.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, msg


def test_bad_input_is_refused_in_one_line(logged):
    p, log = logged
    exp = Experiment.from_log(log)
    force = exp.force.copy()
    force[7, 2] = np.nan
    _one_line_error(lambda: Experiment(force, exp.period, exp.camera_t, exp.alpha0), "force", "period 7")
    _one_line_error(lambda: Experiment(exp.force[:, :, None], exp.period, exp.camera_t, exp.alpha0), "force", "(T, m)")
    late = np.append(exp.camera_t, exp.n_periods * exp.period + 0.01)
    _one_line_error(lambda: Experiment(exp.force, exp.period, late, exp.alpha0), "camera_t", "outside")
    _one_line_error(lambda: Experiment(exp.force, 0.0, exp.camera_t, exp.alpha0), "period")
    _one_line_error(lambda: rollout(exp, [], integrator=INTEGRATOR), "params")
    five = default_params(4)
    _one_line_error(lambda: rollout(exp, [p, five], integrator=INTEGRATOR), "set 1", "joints")
    _one_line_error(lambda: rollout(exp, [five], integrator=INTEGRATOR), "cables", "joints")
    _one_line_error(lambda: rollout(exp, [p, p], [Effects()] * 3, integrator=INTEGRATOR), "effects", "(2)")
    _one_line_error(lambda: rollout(exp, [p], integrator="euler"), "integrator")
    _one_line_error(lambda: rollout(exp, [p], integrator=INTEGRATOR, nthread=0), "nthread")
    slow = Experiment(exp.force, 2 * exp.period, exp.camera_t, exp.alpha0)
    _one_line_error(lambda: rollout(slow, [p], integrator=INTEGRATOR), "control period")
    _one_line_error(lambda: cable_params(p, f_s=[1.0, 2.0], k=1.0, lam=1.0, c_a=1.0), "cable_params", "(K, 4)")


def test_default_threads_follow_the_environment(monkeypatch):
    from identification.output_error.rollouts import THREADS_ENV, default_threads

    monkeypatch.setenv(THREADS_ENV, "3")
    assert default_threads() == 3
    monkeypatch.setenv(THREADS_ENV, "none")
    _one_line_error(default_threads, THREADS_ENV, "'none'")
    monkeypatch.delenv(THREADS_ENV)
    assert default_threads() == len(os.sched_getaffinity(0))


def test_forces_outside_the_motor_range_are_clipped_as_the_plant_clips_them(logged):
    p, log = logged
    exp = Experiment.from_log(log)
    force = exp.force[:300].copy()
    force[50:80, 0] = -5.0                               # a negative command: the motor pushes nothing
    force[100:140, 1] = p.actuation.f_max + 40.0         # beyond the motor's force
    short = Experiment(force, exp.period, exp.camera_t[exp.camera_t <= 300 * exp.period], exp.alpha0)
    out = rollout(short, [p], integrator=INTEGRATOR, nthread=1)
    enc, stamps, alpha = _serial(p, None, short)
    np.testing.assert_array_equal(out.encoders[0], enc)
    np.testing.assert_array_equal(out.camera_alpha[0], alpha[: short.camera_t.size])


def test_logs_roll_out_on_a_dask_cluster_as_here(logged):
    from distributed import LocalCluster

    from neck_sim.campaign import ExecutorSpec
    from identification.output_error.rollouts import rollout_logs

    p, log = logged
    exp = Experiment.from_log(log)
    halves = [Experiment(exp.force[:300], exp.period, exp.camera_t[exp.camera_t <= 0.6], exp.alpha0, name="a"),
              Experiment(exp.force[300:600], exp.period, exp.camera_t[exp.camera_t <= 0.6], exp.alpha0, name="b")]
    sets = _sets(p)[:2]
    here = rollout_logs(halves, sets, integrator=INTEGRATOR, nthread=1)
    with LocalCluster(host="127.0.0.1", protocol="tcp", n_workers=1, threads_per_worker=1, processes=False,
                      dashboard_address="127.0.0.1:0", silence_logs=40) as cluster:
        there = rollout_logs(halves, sets, integrator=INTEGRATOR, nthread=2,
                             executor=ExecutorSpec(cluster=cluster.scheduler_address))
    for h, t, e in zip(here, there, halves):
        np.testing.assert_array_equal(h.encoders, t.encoders)
        np.testing.assert_array_equal(h.camera_alpha, t.camera_alpha)
        np.testing.assert_array_equal(h.encoders, rollout(e, sets, integrator=INTEGRATOR, nthread=1).encoders)
    assert not np.array_equal(here[0].encoders, here[1].encoders)
