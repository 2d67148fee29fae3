"""Cable routing as data: the paper's routing unchanged, closed-form Z
against finite differences for every example routing, validation naming the field."""

import os

import numpy as np
import pytest

from neck_sim.analytic.cables import cable_kinematics, cable_lengths, transmission_matrix, transmission_matrix_dot
from neck_sim.params import ParameterError, default_params

# Produced by tests/fixtures/make_paper_routing_reference.py from the code before routing became
# data (main at 2df2be7): lengths, Z, Zdot at random poses and a closed-loop run.
REFERENCE = os.path.join(os.path.dirname(__file__), "fixtures", "paper_routing_reference.npz")


@pytest.fixture(scope="module")
def reference():
    with np.load(REFERENCE) as ref:
        return dict(ref)


@pytest.mark.parametrize("n", [1, 2, 3, 5])
def test_paper_routing_gives_the_hard_wired_numbers(reference, n):
    p = default_params(n)
    a, ad = reference[f"n{n}_alpha"], reference[f"n{n}_alpha_dot"]
    np.testing.assert_allclose(cable_lengths(a, p), reference[f"n{n}_lengths"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(transmission_matrix(a, p), reference[f"n{n}_Z"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(transmission_matrix_dot(a, ad, p), reference[f"n{n}_Zdot"], rtol=0, atol=1e-12)
    k = cable_kinematics(a, ad, p)
    np.testing.assert_allclose(k.lengths, reference[f"n{n}_lengths"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(k.Z, reference[f"n{n}_Z"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(k.Zdot, reference[f"n{n}_Zdot"], rtol=0, atol=1e-12)


def test_paper_routing_closed_loop_unchanged(reference):
    from controllers.closed_loop import run_closed_loop
    from controllers.computed_torque import ComputedTorqueController
    from neck_sim.plant import Plant
    from neck_sim.trajectory import control_test_trajectory

    p = default_params(3)
    traj = control_test_trajectory(p, move_time=0.6, hold_time=0.1)
    res = run_closed_loop(Plant(p, seed=3), ComputedTorqueController(p, 2), traj, progress=False)
    for name in ("alpha", "theta", "force"):
        np.testing.assert_allclose(getattr(res, name), reference[f"loop_{name}"], rtol=1e-12, atol=1e-12, err_msg=name)


def test_mirrored_routing_is_the_paper_at_minus_alpha(rng):
    """b(alpha) = a(-alpha), c'(alpha) = c(-alpha), d'(alpha) = d(-alpha): the mirrored neck's
    cable j at alpha is the paper's cable j at -alpha (eqs 3-6 written once, mirrors separately)."""
    from neck_sim.routing import mirrored_paper_routing

    for n in (1, 3, 4):
        paper, mirrored = default_params(n), default_params(n, mirrored_paper_routing(n))
        alpha = rng.uniform(-1.0, 1.0, (50, n))
        np.testing.assert_allclose(cable_lengths(alpha, mirrored), cable_lengths(-alpha, paper), atol=1e-15)
        np.testing.assert_allclose(transmission_matrix(alpha, mirrored), -transmission_matrix(-alpha, paper),
                                   atol=1e-15)


def _cables(*tables):
    from neck_sim.routing import Routing
    return Routing(cables=list(tables))


@pytest.mark.parametrize("tables, n, message", [
    ([{"side": "top", "ends_at": 1}], 3, r"routing.cables\[0\].side: must be 'left' or 'right'"),
    ([{"side": "left", "passes": ["side", "diagonal"], "ends_at": 3}], 3, r"cables\[0\].passes\[1\]: joint 2"),
    ([{"side": "left", "passes": ["side", "side"], "ends_at": 2}], 3,
     r"cables\[0\].ends_at: the cable ends at joint 2 but passes joints 1..2"),
    ([{"side": "left", "passes": ["side"], "ends_at": 3}], 3, r"cables\[0\].passes: 1 entries, .* joints 1..2"),
    ([{"side": "right", "passes": ["strut"], "ends_at": 2}, {"side": "left", "passes": ["side"] * 4, "ends_at": 5}],
     3, r"routing.cables\[1\].ends_at: joint 5 does not exist \(n_joints = 3\)"),
    ([{"side": "left", "passes": ["side"], "ends_at": 2, "extra_turns": [0]}], 3,
     r"cables\[0\].extra_turns\[0\]: a side-routed pass needs exactly one extra turn"),
    ([{"side": "left", "passes": ["strut"], "ends_at": 2, "extra_turns": [1]}], 3,
     r"cables\[0\].extra_turns\[0\]: a strut-routed pass"),
    ([{"side": "left", "passes": ["side"], "ends_at": 2, "extra_turns": [1, 1]}], 3,
     r"cables\[0\].extra_turns: expected 1 values"),
    ([{"side": "right", "ends_at": 1, "row": 0}], 3, r"cables\[0\].row: row 0 is the plane of the bars, which has no pulleys"),
    ([{"side": "right", "ends_at": 2, "passes": ["strut"], "row": 2}, {"side": "right", "ends_at": 1, "row": 2}], 3,
     r"cables\[1\].row: cables 0 and 1 are both in row 2 and both use the hinge axis B1"),
    ([{"side": "right", "ends_at": 2, "passes": ["strut"], "row": 1}, {"side": "left", "ends_at": 2,
                                                                        "passes": ["side"], "row": 1}], 3,
     r"cables\[1\].row: cables 0 and 1 are both in row 1 and both use the hinge axis C1"),
    ([{"side": "right", "ends_at": 1, "colour": "red"}], 3, r"routing.cables\[0\].colour: unknown field"),
    ([], 3, r"routing.cables: a neck needs at least one cable"),
])
def test_validation_names_the_field(tables, n, message):
    from neck_sim.params import from_dict

    with pytest.raises(ParameterError, match=message):
        from_dict({"geometry": {"n_joints": n}, "routing": {"cables": tables}})


def test_rows_may_be_shared_by_cables_on_disjoint_pulleys():
    # a right cable attached at D_1 and a left cable side-routed to C_3 touch no common axis:
    # the paper's c1 and c4 could share a row
    r = _cables({"side": "right", "ends_at": 1, "row": 1}, {"side": "left", "passes": ["side", "side"],
                                                             "ends_at": 3, "row": 1})
    assert [c.row for c in r.cables] == [1, 1]


def test_per_cable_values_follow_the_routing():
    from neck_sim.params import from_dict

    with pytest.raises(ParameterError, match=r"friction.f_s: expected 4 values \(one per cable, 4 in routing.cables\)"):
        from_dict({"geometry": {"n_joints": 10}, "routing": P.to_dict(P.example_params("neck10x4"))["routing"],
                   "friction": {"f_s": [1.0] * 11}})
    p = P.example_params("neck10x4")
    # defaults by side: right cables take the paper's c1, c2 values in order, left cables c4's
    assert p.friction.f_s == (14.42, 16.18, 17.65, 16.18)
    assert p.cables.k == (5378.0, 1908.0, 5364.0, 1908.0)


import neck_sim.params as P  # noqa: E402  (used by the tests below and above)


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_example_file_round_trip(tmp_path, suffix, capsys):
    from neck_sim.cli import main

    path = tmp_path / f"neck{suffix}"
    assert main(["params", "--example", "neck10x4", "-o", str(path)]) == 0
    loaded = P.load(path)
    assert loaded == P.example_params("neck10x4") and loaded.n_cables == 4 and loaded.n_joints == 10
    assert main(["params", "--load", str(path)]) == 0
    out = capsys.readouterr().out
    assert "routing (4 cables" in out and "c3: right row +2  cases d d d d d c' c' c' c' b" in out
    assert main(["params", "--example", "neck10x4", "--n-joints", "4"]) == 2


def test_paper_controllers_refuse_other_routings():
    from controllers.computed_torque import ComputedTorqueController
    from neck_sim.analytic import estimate_alpha_triangular

    p = P.example_params("neck10x4")
    with pytest.raises(ValueError, match="paper's kind of routing"):
        ComputedTorqueController(p)
    with pytest.raises(ValueError, match="eq \\(33\\) needs the paper's routing"):
        estimate_alpha_triangular(np.zeros(4), p)
    ComputedTorqueController(P.default_params(4))           # the paper's kind for any N is accepted


def test_mcap_carries_the_cable_count_and_routing(tmp_path):
    from neck_sim.logs import LogError, read_log
    from neck_sim.logs.contract import neck_metadata, params_from_metadata
    from neck_sim.logs.writer import LogWriter

    p = P.example_params("mixed4")
    rng = np.random.default_rng(0)
    path = tmp_path / "run.mcap"
    with LogWriter(path, p) as w:
        for k in range(5):
            w.motors(k * 0.002, rng.normal(size=4), rng.uniform(0, 50, 4))
            w.camera(k / 30, rng.uniform(-1, 1, 4))     # plausible: 30 Hz, inside the joint range
    log = read_log(path)
    assert log.params.routing == p.routing and log.motors.theta.shape == (5, 4)
    meta = neck_metadata(p)
    assert meta["n_cables"] == "4"
    assert "routing" not in neck_metadata(P.default_params(3))       # the paper's: n_cables = N + 1 says it all
    del meta["routing"]
    with pytest.raises(LogError, match="n_cables = 4 differs from the paper's N \\+ 1 = 5 and there is no 'routing'"):
        params_from_metadata(meta)


def test_plant_with_fewer_cables_than_joints_measures_the_analytic_elongation():
    """MuJoCo's tendons along a moving 10-joint, 4-cable neck against l_c(alpha) of the analytic model."""
    from neck_sim.analytic.cables import elongation
    from neck_sim.plant import Plant

    p = P.example_params("neck10x4")
    plant = Plant(p)
    plant.reset(np.radians(np.linspace(-10, 10, 10)))
    moved = 0.0
    for k in range(150):
        plant.step([25.0, 20.0, 15.0, 30.0])
        tr = plant.truth()
        assert tr.tension.shape == (4,) and tr.alpha.shape == (10,) and plant.encoders().shape == (4,)
        # the soft loop closures leave gaps of a few um: the difference stays within 2.5 gaps (the
        # paper's neck on the same run: 2.2); a wrong segment would be off by millimetres
        diff = float(np.abs(elongation(tr.theta, tr.alpha, p) - tr.elongation).max())
        assert diff <= 2.5 * tr.loop_gap + 1e-9 and tr.loop_gap < 1e-4, (k, diff, tr.loop_gap)
        moved = max(moved, float(np.abs(tr.alpha - np.radians(np.linspace(-10, 10, 10))).max()))
    assert moved > np.radians(5)              # the neck really moved


def test_plant_with_as_many_cables_as_joints_follows_the_analytic_dynamics():
    """Every segment kind on a 4-joint, 4-cable neck: the plant's free response against eqs 29-30
    (LSODA) -- the check of ``neck_sim.crossval.dynamics_check``, at half its timestep (first-order convergence)."""
    from neck_sim.crossval import dynamics_check

    rep = dynamics_check(P.example_params("mixed4"), timestep=2.5e-4, hold_duration=0.1, free_duration=0.1)
    assert rep.ok, rep
    assert rep.max_alpha_error_deg < 0.15
