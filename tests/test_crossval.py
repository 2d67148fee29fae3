"""The MuJoCo model agrees with the analytic model: cable lengths to 1e-9 m, Z, M and g to 1e-6
relative (the thresholds ``neck-sim crossval`` holds the model to)."""

import json
import math

import pytest

from neck_sim import crossval as CV
from neck_sim.cli import main
from neck_sim.params import EXAMPLES, default_params, example_params
from neck_sim.routing import CableRoute, Routing

ISSUE_THRESHOLDS = {"lengths": 1e-9, "Z": 1e-6, "M": 1e-6, "g": 1e-6}


@pytest.mark.parametrize("n", [3, 5])
def test_mujoco_agrees_with_the_analytic_model(n):
    rep = CV.crossval(default_params(n), samples=40, seed=n)
    rows = {r.quantity: r for r in rep.rows}
    assert rows["lengths"].max_abs <= ISSUE_THRESHOLDS["lengths"]
    for q in ("Z", "M", "g"):
        assert rows[q].max_rel <= ISSUE_THRESHOLDS[q], q
    assert rows["dq/dalpha"].max_rel <= 1e-6
    assert rep.ok


@pytest.mark.parametrize("name", [k for k in EXAMPLES if k != "paper"])
def test_mujoco_agrees_for_every_example_routing(name):
    """The builder and the analytic model read the same routing: every segment
    kind and its mirror, helpers on both sides, m != N + 1 -- to the paper neck's thresholds."""
    p = example_params(name)
    rep = CV.crossval(p, samples=25, seed=7)
    rows = {r.quantity: r for r in rep.rows}
    assert rep.n_cables == p.n_cables
    assert rows["lengths"].max_abs <= ISSUE_THRESHOLDS["lengths"]
    for q in ("Z", "M", "g", "dq/dalpha"):
        assert rows[q].max_rel <= 1e-6, q
    assert rep.ok


def test_a_wrong_routing_fails(params):
    """One joint routed differently on the analytic side (strut instead of side) is caught."""
    p = example_params("mixed4")
    cables = list(p.routing.cables)
    cables[1] = CableRoute("right", ("strut", "strut", "side"), 4)
    rep = CV.crossval(p, samples=5, analytic_params=p.replace(routing=Routing(tuple(cables))))
    assert {r.quantity for r in rep.rows if not r.ok} == {"lengths", "Z"}


def test_payload_and_spring_changes_agree_too(params):
    p = params.replace(**{"inertia.payload_mass": 0.08, "springs.stiffness": (900.0, 100.0, 300.0),
                          "springs.rest_length": 0.05})
    assert CV.crossval(p, samples=15, seed=1).ok


@pytest.mark.parametrize("change, bad", [
    ({"geometry.r": 0.0046 * 1.001}, {"lengths", "Z"}),    # 5 um pulley radius error
    ({"inertia.bar_mass": 0.020 * 1.0001}, {"M", "g"}),    # 2 mg on a 20 g bar
    ({"springs.rest_length": 0.046 + 1e-7}, {"g"}),
])
def test_a_mis_specified_model_fails(params, change, bad):
    """The comparison is sharp: tiny parameter differences on the analytic side are caught."""
    rep = CV.crossval(params, samples=10, analytic_params=params.replace(**change))
    failing = {r.quantity for r in rep.rows if not r.ok}
    assert failing == bad


def test_bad_arguments(params):
    with pytest.raises(ValueError, match="samples"):
        CV.crossval(params, samples=0)
    with pytest.raises(ValueError, match="alpha_range"):
        CV.crossval(params, alpha_range=math.pi)
    with pytest.raises(ValueError, match="analytic_params"):
        CV.crossval(params, analytic_params=default_params(2))


def test_cli_table_json_and_exit_codes(tmp_path, capsys, monkeypatch):
    out = tmp_path / "cv.json"
    assert main(["crossval", "--n-joints", "3", "--samples", "5", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    for q in ("lengths", "Z", "M", "g"):
        assert q in text
    data = json.loads(out.read_text())
    assert data["ok"] and data["n_joints"] == 3 and len(data["rows"]) == len(CV.THRESHOLDS)
    monkeypatch.setitem(CV.THRESHOLDS, "M", ("rel", 0.0))
    assert main(["crossval", "--samples", "3"]) == 1
    assert "FAIL" in capsys.readouterr().out
    assert main(["crossval", "--samples", "0"]) == 2


def test_cli_crossval_of_the_ten_joint_example(tmp_path, capsys):
    path = tmp_path / "neck10x4.toml"
    assert main(["params", "--example", "neck10x4", "-o", str(path)]) == 0
    out = tmp_path / "cv.json"
    assert main(["crossval", "--params", str(path), "--samples", "5", "--json", str(out)]) == 0
    assert "N = 10, m = 4 cables" in capsys.readouterr().out
    data = json.loads(out.read_text())
    assert data["ok"] and data["n_joints"] == 10 and data["n_cables"] == 4 and len(data["routing"]) == 4


def test_dynamics_report_logic():
    base = dict(timestep=5e-4, hold_duration=10.0, max_loop_gap=5e-5, max_tension=30.0, tensions_finite=True,
                free_duration=1.0, max_alpha_error_deg=0.2, rms_alpha_error_deg=0.02, max_theta_error=0.02,
                tolerance_deg=0.3, gap_limit=1e-4)
    assert CV.DynamicsReport(**base).ok
    for bad in ({"max_loop_gap": 2e-4}, {"tensions_finite": False}, {"max_alpha_error_deg": 0.31}):
        assert not CV.DynamicsReport(**{**base, **bad}).ok
    assert "FAIL" in CV.format_dynamics(CV.DynamicsReport(**{**base, "tensions_finite": False}))
