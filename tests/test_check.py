"""`neck-sim check`: logged truth against the analytic model; tampered truth fails."""

from __future__ import annotations

import json

import numpy as np
import pytest
from test_logs_fixtures import log_arrays, plant_run, simulated_run, synthetic_arrays, write_arrays

from neck_sim.check import check_log
from neck_sim.cli import main
from neck_sim.logs import read_log
from neck_sim.params import default_params


@pytest.fixture(scope="module")
def plant_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("check") / "plant.mcap"
    plant_run(path, seconds=1.0)
    return path


@pytest.fixture(scope="module")
def analytic_log(tmp_path_factory):
    """Truth from the analytic elastic model (scipy), not from MuJoCo: a second producer."""
    params = default_params(3)
    arrays = simulated_run(params, duration=0.4)
    arrays.pop("_theta_true")
    path = tmp_path_factory.mktemp("check") / "analytic.mcap"
    write_arrays(path, params, arrays)
    return path


def tampered(src, dst, topic, field, change):
    log = read_log(src)
    arrays = log_arrays(log)
    arrays[topic][field] = change(arrays[topic][field].copy())
    write_arrays(dst, log.params, arrays, run_info=dict(log.run_info))
    return dst


def verdicts(result):
    return {r.name: r.passed for r in result.relations}


@pytest.mark.parametrize("which", ["plant_log", "analytic_log"])
def test_consistent_truth_passes(which, request):
    result = check_log(request.getfixturevalue(which))
    assert result.passed, result.table()
    rel = {r.name: r for r in result.relations}
    assert rel["cable lengths"].samples > 100 and rel["joint torques"].samples > 100


def test_plant_log_uses_the_plant_parameters(plant_log):
    assert check_log(plant_log).params_source.startswith("plant parameters")


def test_tampered_tension_fails_the_torque_relation(plant_log, tmp_path):
    def scale(x):
        x[:, 1] *= 1.10
        return x
    result = check_log(tampered(plant_log, tmp_path / "t.mcap", "truth", "tension", scale))
    assert verdicts(result) == {"cable lengths": True, "joint torques": False, "elongation sign": True}


def test_tampered_elongation_fails_the_length_relation(plant_log, tmp_path):
    def shift(x):
        x[200:, 2] += 0.5e-3
        return x
    result = check_log(tampered(plant_log, tmp_path / "t.mcap", "truth", "elongation", shift))
    assert verdicts(result) == {"cable lengths": False, "joint torques": True, "elongation sign": True}
    rel = result.relations[0]
    assert rel.index == 2 and rel.max_error == pytest.approx(0.5e-3, rel=0.2) and rel.t >= 0.4


def test_flipped_elongation_sign_fails(analytic_log, tmp_path):
    result = check_log(tampered(analytic_log, tmp_path / "t.mcap", "truth", "elongation", lambda x: -x))
    v = verdicts(result)
    assert not v["cable lengths"] and not v["elongation sign"]
    assert result.relations[2].violations > 100


def test_tampered_alpha_fails(plant_log, tmp_path):
    def bend(x):
        x[:, 1] += np.radians(1.0)
        return x
    result = check_log(tampered(plant_log, tmp_path / "t.mcap", "truth", "alpha", bend))
    assert not verdicts(result)["cable lengths"]


def test_check_command(plant_log, tmp_path, capsys):
    assert main(["check", str(plant_log), "--json", str(tmp_path / "c.json")]) == 0
    out = capsys.readouterr().out
    assert "cable lengths" in out and "joint torques" in out and "elongation sign" in out and "FAIL" not in out
    data = json.loads((tmp_path / "c.json").read_text())
    assert data["passed"] and len(data["relations"]) == 3
    bad = tampered(plant_log, tmp_path / "bad.mcap", "truth", "tension", lambda x: 1.2 * x)
    assert main(["check", str(bad)]) == 1
    assert "FAIL" in capsys.readouterr().out


def test_check_needs_truth(tmp_path, capsys):
    p = default_params(3)
    arrays = synthetic_arrays(p, seconds=0.05)
    write_arrays(tmp_path / "m.mcap", p, {"motors": arrays["motors"]})
    assert main(["check", str(tmp_path / "m.mcap")]) == 2
    assert "missing required topic /neck/truth" in capsys.readouterr().err


def test_a_log_whose_neck_left_its_range_is_refused_in_words_for_the_command_line(plant_log, tmp_path, capsys):
    """The check names the first sample out of range and what a user can do, never a Python keyword."""
    from neck_sim.joint_range import first_excursion

    def bend(x):
        x[300:, 1] = np.radians(93.0)
        x[420, 0] = np.radians(-95.0)
        return x
    bad = tampered(plant_log, tmp_path / "bent.mcap", "truth", "alpha", bend)
    truth = read_log(bad, topics=["truth"], require=["truth"]).truth
    first = first_excursion(truth.t, truth.alpha, default_params(3).geometry.alpha_max)
    assert main(["check", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "allow_outside_range" not in err, err
    assert f"joint 2 at 93.00 deg at t = {truth.t[300]:.3f} s" in err and first.sample == 300
    assert "left its joint range" in err and "neck-sim simulate" in err


def test_the_command_line_words_the_model_range_error_without_the_python_keyword(plant_log, capsys, monkeypatch):
    """Any command whose model evaluation meets a pose out of range (here check, made to) says so
    without `allow_outside_range=True`, which the Python API's message keeps."""
    import neck_sim.check
    from neck_sim.analytic.geometry import PoseRangeError, check_alpha

    def out_of_range(log):
        check_alpha([[0.0, 1.7, 0.0]], 3, alpha_max=default_params(3).geometry.alpha_max)
    monkeypatch.setattr(neck_sim.check, "check_log", out_of_range)
    assert main(["check", str(plant_log)]) == 2
    err = capsys.readouterr().err
    assert "joint 2 at 97.40 deg" in err and "allow_outside_range" not in err and err.count("\n") == 1, err
    with pytest.raises(PoseRangeError, match=r"pass allow_outside_range=True"):
        out_of_range(None)
