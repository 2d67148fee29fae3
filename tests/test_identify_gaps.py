"""``identify`` says what a log cannot identify instead of printing a confident number.

A gentle log (joint angles of 2-3 deg: every cable stays within about 8-17 N) made without a plant
from the model's flat outputs (``identification.excitation.predict_run``, 1 deg camera noise):
lambda cannot be told from k on the least loaded cable, and damping is never excited.  The same
log with three of the optimised excitation sequences identifies every k and lambda.
"""

import json

import numpy as np
import pytest

from neck_sim.params import default_params

pytestmark = pytest.mark.slow


def _measurements(amplitudes_deg, seed=0):
    from identification.excitation import predict_run, sequences_trajectory, synthetic_measurements

    p = default_params(3)
    traj = sequences_trajectory(np.radians(amplitudes_deg), move_time=2.5, hold_time=0.5)
    t = np.arange(0.0, traj.duration, 1.0 / p.control.rate_hz)
    s = traj.sample(t)
    run = predict_run(s.alpha, s.alpha_dot, s.alpha_ddot, t, p)
    return synthetic_measurements(run, p, np.random.default_rng(seed)), run, p


def _identify(meas, p):
    from identification.paper import IdentificationSettings, identify

    return identify(meas, p, IdentificationSettings(reconstruct_alpha=False, bootstrap=12))


def test_a_gentle_log_reports_lambda_and_damping_as_not_identified():
    meas, run, p = _measurements([[3.0, 2.0, 2.0]])
    assert run.tension.max() < 20.0          # the premise: no cable is pulled hard
    r = _identify(meas, p)
    u = r.uncertainty["variable"]
    missing = [n for n, ok in zip(u.names, u.identified) if not ok]
    assert {"c_a(1)", "c_a(2)", "c_a(3)", "c_a(4)"} <= set(missing)
    lam = [n for n in missing if n.startswith("lambda")]
    assert lam, f"every lambda identified on a log within {run.tension.max():.0f} N: {u.group('sigma', 'lambda')}"
    for name in lam:
        line = next(g for g in r.gaps if f"{name} cannot be separated from k(" in g)
        assert "record moves" in line and " N" in line
    # every parameter marked identified is known to 20 %, and the JSON lists the others
    ok = u.identified
    assert np.all(np.abs(u.value[ok]) >= 5 * u.sigma[ok])
    assert set(r.to_dict()["not_identified"]) >= {f"variable: {n}" for n in missing}


def test_a_well_excited_log_identifies_every_k_and_lambda():
    # three of the optimised excitation sequences (tests/test_identify.py), tensions up to 40-60 N
    meas, run, p = _measurements([[42.0, 26.0, 32.0], [-50.0, 27.0, 25.0], [50.0, 43.0, -20.0]])
    r = _identify(meas, p)
    u = r.uncertainty["variable"]
    assert u.group("identified", "lambda").all(), r.gaps
    assert u.group("identified", "k").all(), r.gaps
    assert not any("lambda(" in g for g in r.gaps)


def test_command_prints_the_gaps_and_marks_them_in_json(tmp_path, capsys):
    from neck_sim.cli import main
    from neck_sim.logs import LogWriter

    meas, _, p = _measurements([[3.0, 2.0, 2.0]])
    log = tmp_path / "gentle.mcap"
    with LogWriter(log, p) as w:
        for i in range(meas.t_motor.size):
            w.motors(meas.t_motor[i], meas.theta[i], meas.force[i])
        for i in range(meas.t_camera.size):
            w.camera(meas.t_camera[i], meas.alpha_camera[i])
    out = tmp_path / "ident.json"
    # the flat-output model commands slightly negative forces on a slack-free gentle move
    assert main(["identify", str(log), "--no-alpha", "--bootstrap", "12", "--json", str(out),
                 "--accept-out-of-range-forces"]) == 0
    text = capsys.readouterr().out
    assert "Not identified by this log" in text and "eq (50) sigma" in text
    data = json.loads(out.read_text())
    var = data["uncertainty"]["variable"]["parameters"]
    assert var["c_a(1)"]["identified"] is False and "sigma_eq50_paper" in var["k(1)"]
    assert "variable: c_a(1)" in data["not_identified"] and data["gaps"]
    assert main(["identify", str(log), "--bootstrap", "1", "--accept-out-of-range-forces"]) == 2


def test_what_to_record_stays_within_the_motors_force():
    from identification.gaps import tension_to_record

    assert tension_to_record(11.0, 37.0, 75.0, f_max=100.0) == "pull it to 75 N"
    # a 10-joint neck's cable between 39 and 76 N was told to reach 152 N with 100 N motors
    capped = tension_to_record(39.0, 76.0, 152.0, f_max=100.0)
    assert capped.startswith("pull it to 95 N") and "100 N" in capped
    # nothing left above it: ask for the other end of the range instead
    low = tension_to_record(60.0, 96.0, 192.0, f_max=100.0)
    assert low.startswith("let it relax to 30 N") and "152" not in low and "192" not in low
