"""The one recorder and the plant spec: every loop that drives a plant logs the same topics and
columns for the same plant, a recorded run reads back as its arrays, and a PlantSpec written into
a log's ``run`` record builds a plant that steps bit-identically."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from mcap.reader import make_reader

from controllers.parallel import RunSpec, run_one
from identification.diagnosis.blind import excitation_trajectory, run_log
from neck_sim import env as neck_env
from neck_sim.effects import Effects, Payload
from neck_sim.logs import read_log
from neck_sim.params import default_params
from neck_sim.plant_spec import PlantSpec
from neck_sim.recorder import Recorder
from neck_sim.replay import replay

SPEC = PlantSpec(default_params(3), Effects(payload=Payload(mass=0.05)), seed=5)
LOOPS = ("closed loop", "blind", "replay", "env")
TOPICS = {"closed loop": {"motors", "reference", "estimate", "truth", "camera"},
          "blind": {"motors", "reference", "truth", "camera"},
          "replay": {"motors", "truth", "camera"},
          "env": {"motors", "reference", "truth", "camera"}}


@pytest.fixture(scope="module")
def loop_logs(tmp_path_factory):
    """Loop name -> (log path, what the loop returned) for one plant (SPEC), each loop briefly."""
    d = tmp_path_factory.mktemp("loops")
    p = SPEC.params
    out = {}
    run = run_one(RunSpec("closed loop", p, law=2, duration_scale=0.08, effects=SPEC.effects, seed=SPEC.seed,
                          log_path=str(d / "closed.mcap")))
    out["closed loop"] = (d / "closed.mcap", run)
    traj = excitation_trajectory(p, sequences=1, move_time=0.3, hold_time=0.1)
    out["blind"] = (run_log(d / "blind.mcap", p, SPEC.effects, trajectory=traj, seed=SPEC.seed), None)
    out["replay"] = (d / "replay.mcap", replay(d / "blind.mcap", output=d / "replay.mcap"))
    env = neck_env.load(params=p, effects=SPEC.effects, seed=1, time_limit=0.3, log_path=str(d / "env.mcap"))
    ts = env.reset()
    while not ts.last():
        ts = env.step(np.full(p.n_cables, 25.0))
    env.close()
    out["env"] = (d / "env.mcap", None)
    return out


def _schemas(path) -> dict:
    """Topic -> (schema name, schema text) through the mcap library's reader."""
    with open(path, "rb") as fh:
        summary = make_reader(fh).get_summary()
    return {ch.topic: (summary.schemas[ch.schema_id].name, summary.schemas[ch.schema_id].data)
            for ch in summary.channels.values()}


def test_every_loop_logs_the_same_topics_and_columns_for_the_same_plant(loop_logs):
    n, m = SPEC.params.n_joints, SPEC.params.n_cables
    schemas = {loop: _schemas(loop_logs[loop][0]) for loop in LOOPS}
    widths = {"motors": {"theta": m, "force": m}, "reference": {"alpha_d": n}, "estimate": {"alpha_hat": n},
              "truth": {"alpha": n, "alpha_dot": n, "tension": m, "elongation": m}, "camera": {"alpha": n}}
    for loop in LOOPS:
        log = read_log(loop_logs[loop][0])
        present = {name for name in widths if getattr(log, name) is not None}
        assert present == TOPICS[loop], loop
        for name in present:
            samples = getattr(log, name)
            for field, width in widths[name].items():
                assert getattr(samples, field).shape == (len(samples.t), width), (loop, name, field)
            # a topic's schema is the same whichever loop wrote it
            assert schemas[loop][f"/neck/{name}"] == schemas["blind" if name != "estimate" else loop][f"/neck/{name}"]
        np.testing.assert_array_equal(log.truth.t, log.motors.t)        # truth rows are the motor rows
        assert np.all(np.diff(log.camera.t) > 0) and len(log.camera.t) >= 8
        # the same plant: every loop records its plant's spec (an env episode draws its own seed)
        spec = PlantSpec.from_record(log.run_info)
        expected = SPEC.replace(seed=spec.seed) if loop == "env" else SPEC
        assert spec.to_record() == expected.to_record(), loop


def test_loop_results_equal_their_logs_read_back(loop_logs):
    path, run = loop_logs["closed loop"]
    log = read_log(path)
    np.testing.assert_array_equal(log.motors.theta, run.theta)
    np.testing.assert_array_equal(log.motors.force, run.force)
    np.testing.assert_array_equal(log.truth.alpha, run.alpha)
    np.testing.assert_array_equal(log.camera.alpha, run.camera_alpha)
    path, rep = loop_logs["replay"]
    log = read_log(path)
    np.testing.assert_array_equal(log.motors.theta, rep.theta)
    np.testing.assert_array_equal(log.truth.alpha, rep.alpha)
    np.testing.assert_array_equal(log.motors.t, rep.t)


def _drive(spec: PlantSpec, steps: int, rec: Recorder | None = None, period_forces=None) -> dict:
    """Run ``spec``'s plant open loop with smooth forces; plain lists of what it measured, and
    the recorder filled alongside (if given)."""
    plant = spec.build()
    plant.reset(alpha0=np.array([0.05, -0.03, 0.02]))
    m = plant.params.n_cables
    got = {"t": [], "theta": [], "force": [], "alpha": [], "alpha_dot": [], "tension": [], "elongation": [],
           "camera_t": [], "camera_alpha": []}
    for k in range(steps):
        t = k * plant.period
        force = 28.0 + 9.0 * np.sin(2 * np.pi * 1.3 * t + np.arange(m))
        theta, truth = plant.encoders(), plant.truth()
        for key, value in (("t", t), ("theta", theta), ("force", force), ("alpha", truth.alpha),
                           ("alpha_dot", truth.alpha_dot), ("tension", truth.tension),
                           ("elongation", truth.elongation)):
            got[key].append(value)
        if rec is not None:
            rec.sample(k, t, theta, force, truth)
        plant.step(force)
        frame = plant.camera_frame()
        if frame is not None:
            got["camera_t"].append(frame[0])
            got["camera_alpha"].append(frame[1])
            if rec is not None:
                rec.frame(frame)
    return {key: np.array(v) for key, v in got.items()} | {"plant": plant}


def test_a_recorded_run_reads_back_as_its_arrays(tmp_path):
    n, m = SPEC.params.n_joints, SPEC.params.n_cables
    rec = Recorder(n, m, 200)
    got = _drive(SPEC, 200, rec)
    path = rec.write_log(tmp_path / "run.mcap", SPEC.params, mjcf_xml=got["plant"].xml,
                         run_info=PlantSpec.of(got["plant"]).to_record())
    log = read_log(path)                       # independent of the recorder: the reader's decoding
    assert {name for name in ("motors", "reference", "estimate", "truth", "camera")
            if getattr(log, name) is not None} == {"motors", "truth", "camera"}
    np.testing.assert_array_equal(log.motors.t, got["t"])
    np.testing.assert_array_equal(log.motors.theta, got["theta"])
    np.testing.assert_array_equal(log.motors.force, got["force"])
    for field in ("alpha", "alpha_dot", "tension", "elongation"):
        np.testing.assert_array_equal(getattr(log.truth, field), got[field], err_msg=field)
    np.testing.assert_array_equal(log.camera.t, got["camera_t"])
    np.testing.assert_array_equal(log.camera.alpha, got["camera_alpha"])
    np.testing.assert_array_equal(rec.truth_column("tension"), got["tension"])


def test_an_appending_recorder_grows_and_keeps_its_rows():
    rec = Recorder(3, 4, reference=True)
    rows = np.arange(40.0)[:, None] * np.ones(4)
    for k, row in enumerate(rows):
        assert rec.append(k * 0.002, row, -row, alpha_d=row[:3]) == k
    assert rec.length == 40 and rec.theta.shape[1] >= 40
    t, theta, force = rec.topics()["motors"]
    np.testing.assert_array_equal(theta, rows)
    np.testing.assert_array_equal(force, -rows)
    np.testing.assert_array_equal(rec.topics()["reference"][1], rows[:, :3])
    assert np.isnan(rec.topics()["truth"][1]).all()            # never sampled: NaN, not zeros


@pytest.mark.parametrize("given, message", [("alpha_d", "no reference"), ("alpha_hat", "no estimate")])
def test_a_reference_or_estimate_for_a_record_without_it_is_refused(given, message):
    rec = Recorder(3, 4, 2)
    with pytest.raises(ValueError, match=message):
        rec.sample(0, 0.0, np.zeros(4), **{given: np.zeros(3)})
    assert np.isnan(rec.t).all() and set(rec.topics()) == {"motors", "truth", "camera"}   # nothing recorded


@pytest.mark.parametrize("spec", [PlantSpec(default_params(3), Effects(payload=Payload(mass=0.04)), seed=7,
                                            timestep=2.5e-4),
                                  PlantSpec(default_params(3), seed=3, rigid_cables=True),
                                  PlantSpec(default_params(3), seed=2, integrator="discrete")],
                         ids=["elastic, payload, 0.25 ms", "rigid", "discrete integrator"])
def test_plant_spec_round_trips_through_a_logs_run_record(tmp_path, spec):
    assert pickle.loads(pickle.dumps(spec)) == spec                 # travels to campaign workers
    rec = Recorder(spec.params.n_joints, spec.params.n_cables, 150)
    first = _drive(spec, 150, rec)
    path = rec.write_log(tmp_path / "run.mcap", spec.params, run_info=PlantSpec.of(first["plant"]).to_record())
    back = PlantSpec.from_record(read_log(path).run_info)
    assert back == spec.replace(timestep=first["plant"].timestep)       # the record holds the step resolved
    again = _drive(back, 150)
    for key in ("theta", "alpha", "alpha_dot", "tension", "elongation", "camera_t", "camera_alpha"):
        np.testing.assert_array_equal(again[key], first[key], err_msg=key)        # bit-identical


def test_a_record_without_the_plant_says_what_it_assumed():
    nominal = default_params(3)
    spec, notes = PlantSpec.read_record({"seed": "none"}, nominal=nominal)
    assert spec == PlantSpec(nominal)
    assert set(notes) == {"params", "effects", "seed"} and "seed 0" in notes["seed"]
    with pytest.raises(ValueError, match="run record effects: expected a mapping"):
        PlantSpec.from_record({"effects": '["payload"]'}, nominal=nominal)
    with pytest.raises(ValueError, match="no plant_params"):
        PlantSpec.from_record({})
    with pytest.raises(ValueError, match="params: expected NeckParams"):
        PlantSpec("not params")


def test_an_environment_log_replays_its_own_plant(loop_logs, tmp_path):
    """The env writes its plant's spec into the run record, so replay rebuilds that plant: the
    replayed motor angles equal the episode's (the same forces through the same plant)."""
    path = loop_logs["env"][0]
    rep = replay(path, output=tmp_path / "env-replay.mcap")
    log = read_log(path)
    np.testing.assert_array_equal(rep.theta, log.motors.theta)
