"""`neck-sim replay`: the same plant reproduces a log; a changed plant shows a measured drift."""

from __future__ import annotations

import json

import numpy as np
import pytest
from test_logs_fixtures import plant_run, write_arrays

from neck_sim.cli import main
from neck_sim.effects import Effects, Payload
from neck_sim.logs import read_log
from neck_sim.replay import replay


@pytest.fixture(scope="module")
def plant_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("replay") / "plant.mcap"
    plant_run(path, seconds=1.0, seed=4)
    return path


@pytest.fixture(scope="module")
def payload_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("replay") / "payload.mcap"
    plant_run(path, seconds=0.6, effects=Effects(payload=Payload(mass=0.05)))
    return path


def test_identical_plant_reproduces_the_log(plant_log, tmp_path):
    res = replay(plant_log, output=tmp_path / "r.mcap")
    assert res.notes == ()
    assert np.abs(res.theta_drift).max() == 0.0                    # same encoder counts
    assert res.max_alpha_drift().max() <= 1e-12                     # floating-point tolerance
    out = read_log(tmp_path / "r.mcap", require=("motors", "truth", "camera"))
    log = read_log(plant_log)
    np.testing.assert_array_equal(out.motors.force, log.motors.force)
    np.testing.assert_allclose(out.truth.alpha, log.truth.alpha, rtol=0, atol=1e-12)
    np.testing.assert_allclose(out.camera.alpha, log.camera.alpha, rtol=0, atol=1e-12)   # same seed
    assert json.loads(out.run_info["effects"]) == {}


def test_changed_parameter_shows_a_drift(plant_log):
    res = replay(plant_log, changes={"friction.c_s": 0.6})
    res_spring = replay(plant_log, changes={"springs.stiffness": (660.0, 200.0, 200.0)})
    for r in (res, res_spring):
        assert np.degrees(r.max_alpha_drift().max()) > 0.01
        assert r.max_theta_drift().max() >= 2 * r.encoder_resolution
    assert "alpha1 (deg)" in res.table() and "theta4 (encoder counts)" in res.table()


def test_effects_come_from_the_run_record(payload_log):
    same = replay(payload_log)
    assert same.max_alpha_drift().max() <= 1e-12
    without = replay(payload_log, effects=Effects())
    assert np.degrees(without.max_alpha_drift().max()) > 0.05


def test_replay_without_plant_record_assumes_nominal(plant_log, tmp_path):
    log = read_log(plant_log)
    arrays = {"motors": vars(log.motors), "truth": vars(log.truth)}
    write_arrays(tmp_path / "bare.mcap", log.params, arrays)
    res = replay(tmp_path / "bare.mcap")
    assert any("no plant_params" in n for n in res.notes) and any("no effects" in n for n in res.notes)
    assert res.max_alpha_drift().max() <= 1e-12           # the plant was nominal


def test_replay_rejects_motor_samples_off_the_control_period(tmp_path):
    from neck_sim.params import default_params
    p = default_params(3)
    t = np.array([0.0, 0.002, 0.005])
    write_arrays(tmp_path / "a.mcap", p, {"motors": {"t": t, "theta": np.zeros((3, 4)), "force": np.ones((3, 4))},
                                          "truth": {"t": t, "alpha": np.zeros((3, 3)), "alpha_dot": np.zeros((3, 3)),
                                                    "tension": np.zeros((3, 4)), "elongation": np.zeros((3, 4))}})
    with pytest.raises(ValueError, match=r"one control period \(0.002 s\) apart"):
        replay(tmp_path / "a.mcap")


def test_replay_of_a_log_without_motors_says_so(plant_log):
    import dataclasses
    log = dataclasses.replace(read_log(plant_log), motors=None)     # a Log built in code, not read
    with pytest.raises(ValueError, match="no /neck/motors"):
        replay(log)


def test_replay_command(plant_log, tmp_path, capsys):
    out = tmp_path / "r.mcap"
    assert main(["replay", str(plant_log), "-o", str(out), "--no-progress", "--json", str(tmp_path / "r.json"),
                 "--max-alpha-drift", "1e-6"]) == 0
    text = capsys.readouterr().out
    assert "alpha3 (deg)" in text and f"wrote {out}" in text and out.exists()
    assert max(json.loads((tmp_path / "r.json").read_text())["max_alpha_drift_rad"]) <= 1e-12
    assert main(["replay", str(plant_log), "--no-output", "--no-progress", "--set", "friction.c_s=0.6",
                 "--max-alpha-drift", "0.001"]) == 1
    text = capsys.readouterr().out
    assert "changed: friction.c_s = 0.6" in text and "exceeds 0.001 deg" in text
    assert main(["replay", str(plant_log), "--no-output", "--set", "friction"]) == 2
    assert "expected group.field=VALUE" in capsys.readouterr().err


def test_replay_set_refuses_a_value_in_the_wrong_unit(plant_log, tmp_path, capsys):
    """``--set`` goes through the parameter file's unit check: gravity 98.1 (10x Earth's) and a bar
    length in millimetres are refused in one line before anything runs or is written."""
    out = tmp_path / "r.mcap"
    for change, word in (("inertia.gravity=98.1", "10x Earth's"), ("geometry.L=75", "millimetres")):
        assert main(["replay", str(plant_log), "-o", str(out), "--no-progress", "--set", change]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and word in err[0] and "--accept-implausible-params" in err[0], err
        assert not out.exists()
    assert main(["replay", str(plant_log), "--no-output", "--no-progress", "--set", "inertia.gravity=29.4",
                 "--accept-implausible-params"]) == 0
    assert "warning: --set inertia.gravity = 29.4 m/s^2" in capsys.readouterr().out
