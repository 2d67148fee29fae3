"""Routing comparison: inverse statics, friction band, strategies and the `neck-sim design` command."""

import json

import numpy as np
import pytest

import neck_sim.params
from neck_sim.analytic import cable_lengths, potential_energy
from neck_sim.analytic.statics import equilibrium_for_forces, friction_band, inverse_statics
from neck_sim.cli import main
from neck_sim.params import default_params

ROUTING = hasattr(neck_sim.params, "Routing")
needs_routing = pytest.mark.skipif(not ROUTING, reason="routing as data not merged yet")


def test_inverse_statics_reaches_a_pose_of_a_fully_actuated_neck():
    """With N + 1 cables a C curve is reachable: the forces found hold it (gradient of the
    independent potential vanishes there) and respect the box."""
    p = default_params(3)
    target = np.radians([20.0, 20.0, 20.0])
    sol = inverse_statics(p, alpha_target=target, f_min=p.actuation.t_min)
    assert np.degrees(np.max(np.abs(sol.equilibrium.alpha - target))) < 1e-4
    assert np.all(sol.forces >= p.actuation.t_min - 1e-9) and np.all(sol.forces <= p.actuation.f_max)
    h = 1e-6
    grad = [(potential_energy(target + e, p) + sol.forces @ cable_lengths(target + e, p)
             - potential_energy(target - e, p) - sol.forces @ cable_lengths(target - e, p)) / (2 * h)
            for e in np.eye(3) * h]
    assert np.max(np.abs(grad)) < 1e-6


@needs_routing
def test_inverse_statics_finds_the_nearest_reachable_pose_of_an_underactuated_neck():
    """A 10-X, 4-cable neck cannot bend into an exact C: the answer is a local minimum of the pose
    error over forces in the box (no random nearby force does better)."""
    from neck_sim.design import routing_strategies, typical_shapes
    p = routing_strategies(default_params(10), 4)[0].params
    target = typical_shapes(p)["S"]["alpha_target"]
    sol = inverse_statics(p, alpha_target=target, regularisation=0.0)
    best = np.sum(sol.task_error ** 2)
    assert best > 0
    rng = np.random.default_rng(0)
    lo, hi = p.actuation.f_min, p.actuation.f_max
    trials = np.clip(sol.forces + rng.normal(0, 0.5, (12, 4)), lo, hi)
    eq = equilibrium_for_forces(trials, p, sol.equilibrium.alpha)
    errs = np.sum((eq.alpha[eq.converged] - target) ** 2, -1)
    assert errs.size and np.all(errs >= best * (1 - 1e-6))


def test_friction_band_grows_with_friction_and_vanishes_without():
    p = default_params(3)
    forces = np.array([30.0, 25.0, 35.0, 40.0])
    nominal = equilibrium_for_forces(forces, p)
    spreads = []
    for scale in (0.0, 0.1, 0.2):
        band = friction_band(forces, nominal.alpha, p, f_s=scale * np.asarray(p.friction.f_s))
        assert band.alpha.shape == (16, 3) and band.converged.all()
        spreads.append(np.ptp(band.alpha, 0).max())
    assert spreads[0] < 1e-9
    assert 0 < spreads[1] < spreads[2]
    # the corners bracket the nominal pose joint by joint (friction either way)
    band = friction_band(forces, nominal.alpha, p, f_s=0.1 * np.asarray(p.friction.f_s))
    assert np.all(band.alpha.min(0) < nominal.alpha) and np.all(band.alpha.max(0) > nominal.alpha)


@needs_routing
def test_strategies_are_what_they_claim():
    """segmented: the distal pair barely acts on the proximal half (strut passes); nested: it does;
    doubled: all four cables act on every joint."""
    from neck_sim.analytic import transmission_matrix
    from neck_sim.design import routing_strategies
    strategies = {s.name: s.params for s in routing_strategies(default_params(10), 4)}
    assert set(strategies) == {"segmented", "nested", "doubled"}
    a = np.zeros(10)
    Zs = transmission_matrix(a, strategies["segmented"])
    Zn = transmission_matrix(a, strategies["nested"])
    Zd = transmission_matrix(a, strategies["doubled"])
    assert all(p.n_cables == 4 for p in strategies.values())
    assert np.max(np.abs(Zs[:5, 2:])) < 0.1 * np.min(np.abs(Zs[5:, 2:]))   # distal pair, proximal joints
    assert np.min(np.abs(Zn[:5, 2:])) > 0.5 * np.min(np.abs(Zn[5:, 2:]))
    assert np.all(np.abs(Zd) > 0.01)
    assert np.max(np.abs(Zs[5:, :2])) == 0                                    # proximal pair ends at 5


@needs_routing
def test_design_command_writes_report_and_results(tmp_path, capsys):
    out = tmp_path / "report"
    assert main(["design", "--n-joints", "3", "--samples", "20", "-o", str(out)]) == 0
    for name in ("report.md", "results.json", "workspace.png", "joint_maps.png", "shapes.png", "forces.png",
                 "stiffness.png"):
        assert (out / name).stat().st_size > 0, name
    res = json.loads((out / "results.json").read_text())
    names = [s["name"] for s in res["strategies"]]
    assert names == ["given", "segmented", "nested", "doubled"]
    report = (out / "report.md").read_text()
    for s in res["strategies"]:
        assert f"| {s['name']} |" in report
        w = s["workspace"]
        assert 0 <= w["force_control_stable_fraction"] <= w["feasible_fraction"] <= 1
        for shape in ("C", "S", "reach"):
            assert shape in s["shapes"]
        # the holding forces reported for the C curve give back the reported pose
        c = s["shapes"]["C"]
        p = default_params(3) if s["name"] == "given" else None
        if p is not None and c["reachable"]:
            eq = equilibrium_for_forces(np.array(c["forces"]), p, np.radians(c["alpha_deg"]) + 0.01)
            assert np.max(np.abs(np.degrees(eq.alpha) - c["alpha_deg"])) < 1e-6


def test_design_command_refuses_bad_input(tmp_path, capsys):
    params_file = tmp_path / "results.json"
    neck_sim.params.save(default_params(3), params_file)
    before = params_file.read_bytes()
    assert main(["design", "--params", str(params_file), "-o", str(tmp_path), "--no-strategies"]) == 2
    assert "would write over the parameter file" in capsys.readouterr().err
    assert params_file.read_bytes() == before
    assert main(["design", "--samples", "0", "-o", str(tmp_path / "x")]) == 2
    assert "--samples" in capsys.readouterr().err
