"""The data side for any routing: a log of the 10-joint, 4-cable neck through identify and diagnose.

One log per module: 15.6 s of the nominal MuJoCo plant of ``neck-sim params --example neck10x4``
moved through the equilibria of tension waypoints (``open_world.generator.simulate_reachable``:
inverse statics and a motor PID; every cable's tension sweeps 35-80 N and its motor turns both
ways), measured topics only.  The identification must give one row per cable of the routing,
compared with the parameter file's values (never the paper's columns), and the plant's friction
back; the diagnosis must size every column by the routing.

What this short log allows (the 60 s run of ``benchmarks/bench_any_neck.py`` reaches f_s within
4 %): f_s within 6.3 % (cable 1) here, so 8 % is asserted.  k and lambda separately are off by up to
21 % on the soft cables: the 1 deg camera noise through ten joints' Z gives 0.4-0.5 mm of
elongation noise against a 1.5-2 mm elongation range, an errors-in-variables bias that trades k
against lambda; their sum at the working tension, k + 60 N lambda (the stiffness the tension rows
see), is within 1 %, so that is asserted at 2 %.
"""

from __future__ import annotations

import dataclasses
import json
import os

import numpy as np
import pytest

from neck_sim.cli import main
from neck_sim.params import default_params, example_params, save

pytestmark = pytest.mark.slow

SEED = 1


@pytest.fixture(scope="module")
def neck10(tmp_path_factory):
    """(log path, parameter file, params) of the clean 10-joint, 4-cable run."""
    from open_world.generator import make_spec, simulate_reachable

    d = tmp_path_factory.mktemp("neck10x4")
    p = example_params("neck10x4")
    save(p, d / "p10.toml")
    log = simulate_reachable(d / "clean.mcap", make_spec("none", SEED, params=p), SEED, moves=8)
    return log, d / "p10.toml", p


def test_identify_any_routing(neck10, tmp_path, capsys):
    log, p10, p = neck10
    out = tmp_path / "ident.json"
    assert main(["identify", log, "--params", str(p10), "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert f"ours (relative sigma) | --params {p10} (our difference)" in text
    assert "the paper's Tables 1-2 are for its 3-joint routing and are not compared" in text
    rows = [line for line in text.splitlines() if line.startswith("cable ")]
    assert [r.split()[1] for r in rows] == ["1", "2", "3", "4"] * 2          # Tables 1 and 2, one row per cable
    assert "nan" not in text
    assert "eq (35) needs at least as many cables as joints (this neck: 4 cables, 10 joints)" in text
    res = json.loads(out.read_text())
    assert res["paper"] is None
    el, var = res["models"]["elastic"]["parameters"], res["models"]["variable"]["parameters"]
    names = [n for n in el if n.startswith("f_s")]
    assert names == ["f_s(1)", "f_s(2)", "f_s(3)", "f_s(4)"]
    f_s = np.array([el[n]["value"] for n in names])
    np.testing.assert_allclose(f_s, p.friction.f_s, rtol=0.08)
    k = np.array([var[f"k({i})"]["value"] for i in range(1, 5)])
    lam = np.array([var[f"lambda({i})"]["value"] for i in range(1, 5)])
    np.testing.assert_allclose(k + 60.0 * lam, np.asarray(p.cables.k) + 60.0 * np.asarray(p.cables.lam), rtol=0.02)


def test_diagnose_any_routing_with_a_nominal_file(neck10, tmp_path, capsys):
    """``diagnose --params nominal.toml``: columns per cable (4) and per joint (10), not N + 1."""
    log, p10, p = neck10
    out = tmp_path / "diag.json"
    assert main(["diagnose", log, "--params", str(p10), "--steps", "1", "--no-resim", "--quiet",
                 "--candidates", "joint_friction,payload", "--json", str(out), "--report", str(tmp_path / "rep")]) == 0
    capsys.readouterr()
    d = json.loads(out.read_text())
    names = list(d["baseline"]["parameters"])
    assert [n for n in names if n.startswith("f_s(")] == [f"f_s({i})" for i in range(1, 5)]
    assert [n for n in names if n.startswith("lambda(")] == [f"lambda({i})" for i in range(1, 5)]
    assert {c["effect"] for c in d["steps"][0]["candidates"]} == {"joint_friction", "payload"}
    assert any("alpha_hat not evaluated: eq (35) needs at least as many cables as joints" in n for n in d["notes"])
    # the report's residual figures plot every joint against the motor speed of its strongest cable
    assert (tmp_path / "rep" / "residuals_torque.png").stat().st_size > 0 and (tmp_path / "rep" / "report.md").exists()


def test_what_the_routing_cannot_do_is_refused_in_one_line(neck10, tmp_path, capsys):
    log, _, _ = neck10
    assert main(["identify", log, "--simulators", "--json", str(tmp_path / "o.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.splitlines() == [err] and "--simulators: cannot handle this log's routing (10 joints, 4 cables)" in err
    assert not (tmp_path / "o.json").exists()


def test_a_params_file_of_another_routing_is_refused(neck10, tmp_path, capsys):
    log, _, _ = neck10
    other = tmp_path / "p10_paper.toml"
    save(default_params(10), other)                  # 10 joints on the paper's routing: 11 cables
    for cmd in (["identify", log, "--json", str(tmp_path / "o.json")],
                ["diagnose", log, "--json", str(tmp_path / "o.json"), "--quiet"]):
        assert main([*cmd, "--params", str(other)]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1
        assert f"--params {other}: n_cables = 11, the log's neck record has 4" in err
        assert not (tmp_path / "o.json").exists()
    # a parameter file whose per-cable arrays disagree with its own routing
    good = neck10[1].read_text()
    start = good.index("f_s = [")
    bad = tmp_path / "bad.toml"
    bad.write_text(good[:start] + "f_s = [1.0, 2.0, 3.0, 4.0, 5.0]" + good[good.index("]", start) + 1:])
    assert main(["identify", log, "--params", str(bad), "--json", str(tmp_path / "o.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.splitlines() == [err]
    assert "friction.f_s: expected 4 values (one per cable, 4 in routing.cables), got 5" in err
    assert not (tmp_path / "o.json").exists()


def _diagnose_blind(path, model="paper"):
    """The blind diagnosis of the detection benchmark: one step, no re-simulation, from the
    baseline ``model`` (the paper's unless the case removes a term) on the log's own neck record."""
    from identification.diagnosis import DiagnosisSettings, diagnose_log

    return diagnose_log(path, model=model, settings=DiagnosisSettings(resimulate=False, max_steps=1), progress=False)


def test_the_clean_ten_joint_log_is_diagnosed_none(neck10):
    """No hidden effect: the structure tests find nothing beyond noise (``none``, not
    ``unexplained``), and the 15 s log is long enough to decide (no gap blocks a verdict)."""
    from identification.diagnosis.materiality import undecided_lines

    diag = _diagnose_blind(neck10[0])
    assert not any(g.fatal for g in diag.gaps)
    assert diag.verdict == "none" and not diag.findings
    assert diag.leftover is not None and not diag.leftover.significant
    assert undecided_lines(diag) == []          # no "a longer log would decide" on a clean log


@pytest.fixture(scope="module")
def blind10(tmp_path_factory):
    """(name, seed, level, moves) -> (spec, diagnosis) of a blind log of the 10x4 neck (``moves``
    waypoint moves: 8 give 15.6 s, 16 give 30.8 s, 31 give 59.3 s, 62 give 118 s), simulated and
    diagnosed once when first asked (15.6 s: about 80 s on one core, 60 s of plant and 20 s of
    diagnosis; 30.8 s about twice that; a 118 s dry log took 90 s on a shared 2-core machine)."""
    from open_world.generator import make_spec, simulate_reachable

    root, cache, p = tmp_path_factory.mktemp("blind10"), {}, example_params("neck10x4")

    def get(name, seed, level=1.0, moves=8):
        if (name, seed, moves) not in cache:
            spec = make_spec(name, seed, level=level, params=p)
            log = simulate_reachable(root / f"{name}_{seed}_{moves}.mcap", spec, seed, moves=moves)
            cache[name, seed, moves] = spec, _diagnose_blind(log, spec.model)
        return cache[name, seed, moves]

    get.path = lambda name, seed, moves=8: root / f"{name}_{seed}_{moves}.mcap"
    return get


# The whole blind grid of this neck (every case, seeds 1-3) is benchmarks/bench_any_neck.py
# --detection; the suite keeps the cases the 3-joint tests do not already cover in kind (the
# hinge's column and the payload, seed 1; the one-joint spring, seed 2) and runs the others only when
# asked, to stay in its time budget.
full_grid = pytest.mark.skipif(os.environ.get("NECK_SIM_FULL_GRID") != "1",
                               reason="NECK_SIM_FULL_GRID=1 runs it (bench_any_neck.py --detection runs seeds 1-3)")

def _own_candidate(diag, spec):
    """The hidden effect's own candidate at step 1, whether or not it was named."""
    return next(c for c in diag.steps[0].candidates if c.term.name == spec.expect)


def test_joint_friction_column_on_the_ten_joint_neck_locates_and_sizes_the_hinge(blind10):
    """Joint friction hidden in joint 5 (MuJoCo's hinge frictionloss, seed 1): the candidate's
    column takes the joint speed from the camera when C < N (4 motor speeds do not determine 10
    joint speeds; eq 35's minimum-norm solution read 0.015 N m of the 0.036 hidden), projected on
    the own channel's band (materiality.in_own_band).  Its largest tau_j / sigma is at the hidden
    joint and the value within 25 % (seed 1: +23 % +- 20 %).  The verdict itself misses it on this
    short log: in its band joint 5's torque residual is 48 % lower cross-validated, but its F-test
    over the band's 26 effective training samples gives p 0.01 with the factors 2N and 2 (against
    1e-3).  The summary says so in a line that names joint 5 and the log length at which the same
    gain would pass (about 18 s: ``materiality.undecided_lines``); named on joint 5 on the 30.8 s
    log of the same seed (-29 %), and within 10 % on the 59.3 s one (-8.6 %)."""
    from identification.diagnosis.materiality import undecided_lines
    from identification.diagnosis.report import format_summary

    spec, diag = blind10("joint_friction", SEED)
    fit = _own_candidate(diag, spec).fit
    names = list(fit.names)
    own = [k for k, n in enumerate(names) if n.startswith("tau_j(")]
    top = max(own, key=lambda k: fit.value[k] / fit.sigma[k])
    assert names[top] == spec.symbol, (spec.description, names[top])
    np.testing.assert_allclose(fit.value[top], spec.magnitude, rtol=0.25)
    (line,) = undecided_lines(diag)
    assert diag.verdict == "none" and line in format_summary(diag).splitlines()
    assert f"joint_friction not decided: joint {spec.joints[0] + 1}'s torque channel" in line
    need = float(line.split("about ")[1].split(" s would decide")[0])
    assert 15.6 < need < 30.8                   # longer than this log, shorter than the one that names it


@full_grid
def test_a_hidden_actuation_delay_on_the_ten_joint_neck_is_named(blind10):
    """A FIFO of commanded forces (``open_world.generator``), diagnosed blind: named, its delay
    within the 3-joint tests' 10 %."""
    spec, diag = blind10("actuation_delay", SEED)
    assert diag.verdict == "actuation_delay"
    np.testing.assert_allclose(diag.findings[0].parameters[spec.symbol].value, spec.magnitude, rtol=0.10)


#: Extra dry friction on one cable: (named alone, f_s within 10 %, f_travel within 10 %) per seed and
#: log length (moves: 8 give 15.6 s, 31 give 59.3 s, 62 give 118 s), as measured (docs/your-own-neck.md
#: section 7).
#: On 15.6 s seed 1's dry and pulley laws compared on cable 1 do not separate (alternatives, with
#: what would separate them); on 59.3 s they do.  f_s is the level of a law flat above a knee, which
#: these logs cannot tell from eq 37, read on the fit settled (``dry_level.py``): -12.4, +1.3, +8.5 %
#: on 15.6 s, -0.3 and +15.2 % on seeds 1 and 3 at 59.3 s (seed 1 at 15.6 s reads low by every law:
#: the model's other terms take about 10 % there, f_travel -13 %; seed 3's channels disagree, the
#: cable's row +22 %, the torque rows +8.5 %).  Its sigma, eq 50 and half the range of eq 37 and the
#: channels' levels, covers the hidden value within 1.30 sigma on these five logs (1.58 on the 13 blind
#: logs of seeds 1-7).  On 118 s logs, which extend the 59.3 s ones (the same waypoints and noise for
#: their first 59 s), seeds 1-3 read +4.5, -0.2, +4.8 % (within 0.99 sigma; the sigma 4-6 % of f_s):
#: at 59.3 s the log's own noise spreads the level by 4-7 % of F (a block bootstrap), at 118 s by
#: 2.8-3.9 %.  Known misses are asserted as such (a fix must update this table).
DRY_CELLS = {(1, 8): (False, False, False), (2, 8): (True, True, True), (3, 8): (True, True, True),
             (1, 31): (True, True, True), (3, 31): (True, False, True),
             (1, 62): (True, True, True), (2, 62): (True, True, True), (3, 62): (True, True, True)}
#: The hidden F lies within this many sigmas of the reported f_s (1.58 at most on the 22 blind logs).
DRY_SIGMAS = 2.0


def _within(value, hidden, rtol=0.10):
    return abs(value / hidden - 1) <= rtol


@full_grid
@pytest.mark.parametrize("seed,moves", sorted(DRY_CELLS))
def test_extra_dry_friction_on_one_cable_of_the_ten_joint_neck_is_named_first(blind10, seed, moves):
    """A tanh Coulomb force on cable 1's commanded force (the baseline without eq 37's friction,
    as in the 3-joint tests): ``dry_friction`` named first, on cable 1, on every seed and length.
    Compared with ``pulley_friction`` on that cable (``selection.one_cable_pair``) it is named alone
    where ``DRY_CELLS`` says so; where not, the verdict lists both as alternatives and the report's
    line says which tension range or log length would separate them (``report.look_alike_lines``).
    f_s (the flat law's level, ``dry_level.py``) against the hidden F, within its value and within
    ``DRY_SIGMAS`` of its sigma; f_travel against the hidden law's own mean force per unit of travel
    over the same encoder speeds (the generator's formula F tanh(theta_dot / 0.3), not eq 37)."""
    from identification.diagnosis.report import look_alike_lines

    alone, sized, travel = DRY_CELLS[seed, moves]
    spec, diag = blind10("dry_friction", seed, moves=moves)
    names = list(diag.verdict) if isinstance(diag.verdict, list) else [diag.verdict]
    assert names[0] == "dry_friction", diag.verdict
    assert (names == ["dry_friction"]) == alone, diag.verdict
    f = diag.findings[0]
    assert f.cables == [c + 1 for c in spec.cables]
    fs = f.parameters[spec.symbol]
    assert _within(fs.value, spec.magnitude) == sized, (seed, moves, fs)
    assert abs(fs.value - spec.magnitude) <= DRY_SIGMAS * fs.sigma, (seed, moves, fs)
    v = np.abs(diag.data.theta_dot_fast[:, spec.cables[0]])
    hidden_travel = np.sum(spec.magnitude * np.tanh(v / 0.3) * v) / np.sum(v)
    got = f.parameters[f"f_travel({spec.cables[0] + 1})"].value
    assert _within(got, hidden_travel) == travel, (seed, moves, got, hidden_travel)
    if not alone:
        line, = look_alike_lines(diag)
        assert "on cable 1" in line and "deg apart after the baseline" in line and "would separate them" in line


@full_grid
def test_viscous_friction_on_a_fast_cable_of_the_ten_joint_neck_is_read_on_its_settled_fit(blind10):
    """MuJoCo damping on cable 4's motor slide (seed 3, 59.3 s; the generator's own model field,
    not the candidate's column), a cable whose encoder speed reaches tens of rad/s: named, on cable
    4, c_v within 1 % of the hidden value and one of its sigmas (measured +0.3 %, +0.22 sigma), where
    the candidate's fit as made (3 passes of its tension/stiffness iteration) reads it more than
    10 % low (-17.6 %, -11.3 sigma): the finding is read on the fit settled (``settled.py``)."""
    spec, diag = blind10("viscous_friction", 3, moves=31)
    assert spec.symbol == "c_v(4)" and diag.verdict == "viscous_friction", (spec.symbol, diag.verdict)
    f = diag.findings[0]
    assert 4 in f.cables
    p = f.parameters[spec.symbol]
    assert abs(p.value / spec.magnitude - 1) <= 0.01 and abs(p.value - spec.magnitude) <= p.sigma, p
    made = f.evidence.fit
    assert made.value[list(made.names).index(spec.symbol)] / spec.magnitude - 1 < -0.10


def test_the_travel_mean_friction_is_the_laws_work_over_the_distance():
    """``travel_mean_friction`` against the closed form: over speeds swept uniformly through
    [-V, V], sum f |v| / sum |v| = (2/pi) f_s int_0^V arctan(c v) v dv / (V^2 / 2), with
    int v arctan(c v) dv = (v^2 / 2) arctan(c v) - v / (2 c) + arctan(c v) / (2 c^2).  A named dry
    friction reports it per cable at its fitted f_s and c_s, sigma scaled alike."""
    from identification.diagnosis.columns.dry_friction import DryFrictionColumns, travel_mean_friction

    V, c, f_s = 7.0, 1.3, 12.0
    v = np.linspace(-V, V, 400001)
    integral = V ** 2 / 2 * np.arctan(c * V) - V / (2 * c) + np.arctan(c * V) / (2 * c ** 2)
    expected = (2 / np.pi) * f_s * integral / (V ** 2 / 2)
    assert travel_mean_friction(v, f_s, c) == pytest.approx(expected, rel=1e-5)
    assert np.isnan(travel_mean_friction(np.zeros(10), f_s, c))
    speeds = np.stack([v, 0.5 * v], axis=1)
    out = DryFrictionColumns.derived_parameters(speeds, {"f_s(2)": (f_s, 0.3), "c_s": (c, None)}, {"c_s": c})
    assert list(out) == ["f_travel(2)"]
    value, sigma, unit, _ = out["f_travel(2)"]
    assert value == pytest.approx(travel_mean_friction(0.5 * v, f_s, c)) and unit == "N"
    assert sigma == pytest.approx(0.3 * value / f_s)


def test_the_flat_level_is_read_where_the_friction_is_flat_and_not_from_eq_37():
    """``dry_level``'s rule on channels built here from their own formulas (speeds log-uniform over
    0.05-20 rad/s with random signs, white noise of 0.5 N, the rows the force itself): a friction
    flat above a knee, F tanh(|v| / 0.3) (the generator's law), is read by the flat law at F within
    2 % and the rule takes it (eq 37's arctan fits it no better); eq (37) itself with c_s = 0.5 (the
    paper's plant, still rising at 20 rad/s) fits far better than any flat law, so the rule keeps
    eq 37's f_s."""
    from identification.diagnosis.dry_level import C_GRID, chooses_flat, flat_fit

    rng = np.random.default_rng(5)
    v = np.exp(rng.uniform(np.log(0.05), np.log(20.0), 40000)) * rng.choice([-1.0, 1.0], 40000)
    F, rows = 10.0, (lambda fast: fast)

    def eq37(Y):                 # the arctan's least residual over its c_s (the candidate's search)
        fits = [np.linalg.lstsq(a[:, None], Y, rcond=None) for a in
                ((2 / np.pi) * np.arctan(c * v) for c in C_GRID)]
        return min(float(f[1][0]) for f in fits)

    for law, flat in ((F * np.tanh(np.abs(v) / 0.3), True), (F * (2 / np.pi) * np.arctan(0.5 * np.abs(v)), False)):
        Y = np.sign(v) * law + rng.normal(0.0, 0.5, v.size)
        level, knee, rss = flat_fit(rows, Y, v)
        share = float(np.mean(np.abs(v) >= knee))
        assert chooses_flat(rss, eq37(Y), share, 0.02) == flat, (level, knee, rss / eq37(Y))
        if flat:
            assert level == pytest.approx(F, rel=0.02) and knee < 1.0


def test_the_dry_levels_form_error_is_half_the_range_of_its_channels_levels():
    """``channel_levels`` on two channels built here from their own formulas (the generator's law
    F tanh(|v| / 0.3), the torque rows with gain 2 and level 10 N, the cable's own row with gain
    1 / 3 and level 8 N, white noise): each channel alone returns its own level within 2 %, both
    together a level between them; ``form_error`` is half the range of eq 37's value and the
    three levels."""
    from identification.diagnosis.dry_level import channel_levels, form_error

    rng = np.random.default_rng(7)
    v = np.exp(rng.uniform(np.log(0.05), np.log(20.0), 20000)) * rng.choice([-1.0, 1.0], 20000)
    law = np.sign(v) * np.tanh(np.abs(v) / 0.3)
    rows = lambda fast: np.concatenate([2.0 * fast, fast / 3.0])
    Y = np.concatenate([2.0 * 10.0 * law, 8.0 * law / 3.0]) + rng.normal(0.0, 0.2, 2 * v.size)
    (both, torque, own), knee, _ = channel_levels(rows, Y, v.size, v)
    assert torque == pytest.approx(10.0, rel=0.02) and own == pytest.approx(8.0, rel=0.02)
    assert own < both < torque and knee < 1.0
    assert form_error(11.0, (both, torque, own)) == pytest.approx(0.5 * (11.0 - own))
    assert form_error(9.0, (both, torque, own)) == pytest.approx(0.5 * (torque - own))


def test_settle_passes_until_the_located_values_stop_moving():
    """``settle`` on a pass built here, x -> a x + b (a contraction with fixed point b / (1 - a)),
    on one of two values: it stops at the first pass that moves that value by less than
    ``SETTLED`` sigma, which puts it within SETTLED sigma a / (1 - a) of the fixed point after more
    than one pass; a pass that never settles stops at ``max_passes``."""
    from types import SimpleNamespace

    from identification.diagnosis.settled import SETTLED, settle

    a, b, sigma, calls = 0.7, 3.0, 0.01, []

    def step(fit):
        calls.append(1)
        return SimpleNamespace(value=np.array([fit.value[0], a * fit.value[1] + b]), sigma=np.full(2, sigma))

    out = settle(step, SimpleNamespace(value=np.array([5.0, 0.0]), sigma=np.full(2, sigma)), [1])
    assert len(calls) > 1
    assert abs(out.value[1] - b / (1 - a)) <= SETTLED * sigma * a / (1 - a)
    calls.clear()
    drift = lambda fit: SimpleNamespace(value=fit.value + 1.0, sigma=fit.sigma)
    settle(lambda f: (calls.append(1), drift(f))[1], SimpleNamespace(value=np.zeros(1), sigma=np.ones(1)), [0],
           max_passes=4)
    assert len(calls) == 4


def test_the_separating_angle_is_where_the_leaders_tests_would_pass():
    """``separating_angle``: scaling what the leader adds to its look-alike by the first-order law
    (improvement with sin^2 of the columns' angle, each test's normal score with sin of it) to the
    angle it returns makes that comparison pass the encompassing test's own rule
    (``Comparison.significant`` at alpha and half the minimum improvement) exactly there, and fail
    just below; the log length likewise when only the p values fall short; None when the leader
    adds nothing."""
    from scipy import stats

    from identification.diagnosis.selection import separating_angle
    from identification.diagnosis.statistics import Comparison

    alpha, half = 0.01, 0.01

    def scaled(c, k):
        z = lambda p: stats.norm.isf(p) * np.sqrt(k)
        return Comparison(c.improvement * k, c.holdout_improvement * k, float(stats.norm.sf(z(c.p_holdout))),
                          float(stats.norm.sf(z(c.p_train))))

    for c, angle in ((Comparison(0.0068, 0.005, 0.086, 0.011), 14.7),      # seed 1, 15.6 s: improvement and p short
                     (Comparison(0.0128, 0.01, 0.019, 8.9e-4), 17.8)):     # seed 3, 30.8 s: the Wilcoxon p short
        needed, length = separating_angle(angle, c, half, alpha)
        k = (np.sin(np.radians(needed)) / np.sin(np.radians(angle))) ** 2
        assert scaled(c, k * (1 + 1e-9)).significant(alpha, half)
        assert not scaled(c, k * (1 - 1e-3)).significant(alpha, half)
        if c.improvement >= half:               # only the p values short: a longer log would do
            assert length == pytest.approx(k) and scaled(c, length * (1 + 1e-9)).significant(alpha, half)
        else:
            assert length is None
    assert separating_angle(15.0, Comparison(-0.001, 0.0, 0.3, 0.2), half, alpha) == (None, None)
    assert separating_angle(80.0, Comparison(0.0001, 0.0, 0.4, 0.3), half, alpha)[0] is None


def test_look_alike_laws_are_compared_on_the_one_cable_the_leader_rests_on():
    """``selection.leader_cable``: a motor-side candidate rests on one cable when its one-cable
    form says so, or when only one cable's magnitude is clearly > 0 in its every-cable form (seed
    1's dry friction: f_s(1) 9.36 +- 0.29, the others within 1.3 sigma of 0); two such cables, or a
    joint-side candidate, give None.  A pulley term put on that cable has that cable's column only
    and keeps the every-cable form's places (it is not searched cable by cable)."""
    from types import SimpleNamespace

    from identification.diagnosis.candidates import Term
    from identification.diagnosis.columns.pulley_friction import PulleyFrictionColumns
    from identification.diagnosis.selection import leader_cable

    def cand(name, shape, value, sigma):
        v, sg = np.array(value), np.array(sigma)
        return SimpleNamespace(term=Term(name, shape), fit=SimpleNamespace(group=lambda _: v, group_sigma=lambda _: sg))

    sig = [0.29, 0.18, 0.04, 0.04]
    assert leader_cable(cand("dry_friction", (("c_s", 2.2),), [9.36, 0.03, -0.05, 0.04], sig), 4) == 1
    assert leader_cable(cand("dry_friction", (("c_s", 2.2),), [9.36, 3.0, -0.05, 0.04], sig), 4) is None
    assert leader_cable(cand("dry_friction", (("c_s", 2.2), ("cable", 3)), [9.36], [0.29]), 4) == 3
    assert leader_cable(cand("pulley_friction", (("c", 2.9),), [0.147, -0.0065, -0.0006, 0.0004],
                             [0.0048, 0.0032, 0.0008, 0.0008]), 4) == 1
    assert leader_cable(cand("spring_error", (), [30.0] + [0.0] * 19, [1.0] * 20), 4) is None
    on2 = {"c": 2.0, "cable": 2.0}
    assert PulleyFrictionColumns.column_names(10, 4, on2) == (("mu(2)", "-"),)
    assert PulleyFrictionColumns.places(on2, 10, 4) == PulleyFrictionColumns.places({"c": 2.0}, 10, 4) == 1


def test_a_weak_side_spring_on_the_ten_joint_neck_is_named_on_its_joint(blind10):
    """One side spring 20 % weak (MuJoCo's tendon stiffness, seed 2: joint 1's left spring, 600 ->
    483 N/m) on a 15.6 s log: the spring-error candidate searched joint by joint picks the hidden
    joint over the other nine and over every joint at once, and is named on its own channel in its
    band (materiality.py: joint 1's torque residual below half the common cutoff 88 % lower
    cross-validated, F-test p 4.7e-9 and Wilcoxon p 3e-7 with the factors 2N and 2 counted, against
    0.01 / 13 candidates), while the whole score moves by 1.8 % (below its 2 %).  Named alone, on
    joint 1, dk of the hidden spring within the 3-joint tests' 10 % (-0.4 %)."""
    spec, diag = blind10("spring_error", 2, 0.4)
    assert diag.verdict == "spring_error", diag.verdict
    f = diag.findings[0]
    assert f.joints == [spec.joints[0] + 1] and not f.cables
    np.testing.assert_allclose(f.parameters[spec.symbol].value, spec.magnitude, rtol=0.10)


def _located_fit(diag, spec):
    """(joint the hidden effect's own candidate was located on, or None, and its fit)."""
    own = _own_candidate(diag, spec)
    return own.term.identification.joint_of(dict(own.term.shape)), own.fit


@full_grid
def test_a_weak_spring_whose_side_is_unresolved_is_sized_by_the_combination_its_row_sees(blind10):
    """Seed 1 (joint 1 left 600 -> 480 N/m, 15.6 s): named on joint 1, but joint 1's two side
    springs are nearly collinear in its torque row (the other combination is resolved 0.11 times
    as well), so the hidden side's dk reads -140 +- 93 (+17 %).  The combination the row resolves
    (``spring_error.resolved_stiffness``) is within the 3-joint tests' 10 % of the hidden one's
    (+2.3 %)."""
    from identification.diagnosis.columns.spring_error import resolved_stiffness
    from neck_sim.logs import read_log

    spec, diag = blind10("spring_error", SEED, 0.4)
    assert diag.verdict == "spring_error", diag.verdict
    joint, fit = _located_fit(diag, spec)
    assert joint == spec.joints[0] + 1 and diag.findings[0].joints == [joint]
    u, ratio = resolved_stiffness(read_log(blind10.path("spring_error", SEED), topics=("camera",)).camera.alpha,
                                  spec.params, joint)
    names = list(fit.names)
    fitted = u @ [fit.value[names.index(f"dk({joint}{side})")] for side in "LR"]
    hidden = u @ [spec.magnitude if spec.symbol.endswith(side + ")") else 0.0 for side in "LR"]
    assert ratio < 0.2
    np.testing.assert_allclose(fitted, hidden, rtol=0.10)


@full_grid
def test_the_located_spring_error_sizes_the_hidden_spring_within_ten_percent(blind10):
    """Seed 3 (joint 5 right 200 -> 164 N/m, 15.6 s): named on the hidden joint, dk of the hidden
    spring within the 3-joint tests' 10 % (+5.5 %)."""
    spec, diag = blind10("spring_error", 3, 0.4)
    assert diag.verdict == "spring_error", diag.verdict
    joint, fit = _located_fit(diag, spec)
    assert joint == spec.joints[0] + 1, (spec.description, joint)
    np.testing.assert_allclose(fit.value[list(fit.names).index(spec.symbol)], spec.magnitude, rtol=0.10)


def test_resolved_stiffness_is_the_direction_the_row_sees_most():
    """At random poses of the 10x4 neck, the combination u of joint 3's side springs that
    ``resolved_stiffness`` returns is the unit direction that maximises the norm of the joint's
    torque column (found here by a scan over 3600 directions), and its ratio is the scan's
    min / max norm."""
    from identification.diagnosis.columns.spring_error import resolved_stiffness, spring_torque

    p = example_params("neck10x4")
    alpha = np.random.default_rng(1).uniform(-0.25, 0.25, (200, p.n_joints))
    u, ratio = resolved_stiffness(alpha, p, 3)
    th = np.linspace(0.0, np.pi, 3600, endpoint=False)
    norms = np.linalg.norm(spring_torque(alpha, p)[:, 2, :] @ np.stack([np.cos(th), np.sin(th)]), axis=0)
    best = np.array([np.cos(th[norms.argmax()]), np.sin(th[norms.argmax()])])
    assert abs(abs(u @ best) - 1.0) < 1e-5 and max(u, key=abs) > 0
    assert ratio == pytest.approx(norms.min() / norms.max(), rel=1e-4)


def _hinge_named_on_its_joint_within_ten_percent(spec, diag):
    assert diag.verdict == "joint_friction", diag.verdict
    f = diag.findings[0]
    assert f.joints == [spec.joints[0] + 1] and not f.cables
    np.testing.assert_allclose(f.parameters[spec.symbol].value, spec.magnitude, rtol=0.10)


def _hinge_within_two_sigma_with_its_form_error(spec, diag, max_relative_sigma):
    """The named hinge's size (the middle of its estimates, ``hinge_size.hinge_interval``), its
    sigma labelled as including its form error, holds the hidden value within 2 sigma, and that
    sigma is at most ``max_relative_sigma`` of the value (the form error must not make it useless)."""
    from identification.diagnosis.parameters import note_label

    p = diag.findings[0].parameters[spec.symbol]
    assert note_label(p.note) == " (includes form error)", p.note
    assert abs(p.value - spec.magnitude) < 2 * p.sigma, (p.value, p.sigma, spec.magnitude)
    assert p.sigma < max_relative_sigma * p.value, (p.sigma, p.value)


@full_grid
def test_hinge_friction_in_the_top_joint_is_named_and_located(blind10):
    """Seed 2 (frictionloss 0.046 N m in joint 10) on a 30.8 s log: named ``joint_friction`` on
    joint 10 alone, within 10 % (the middle of its estimates +8.5 %, the fit +5.9 %; 59.3 s: -2.1 %
    and +0.1 %) and within 2 sigma of its sigma with the form error (sigma 17 % of the value).  On the 15.6 s log the column projected
    on its band leaves it ``unexplained`` (held-out p 0.0019 against 7.7e-4; named +7.5 % with the
    full band, which sized the low joints' hinges -41 % and +19 %: docs/your-own-neck.md section 7)."""
    spec, diag = blind10("joint_friction", 2, moves=16)
    _hinge_named_on_its_joint_within_ten_percent(spec, diag)
    _hinge_within_two_sigma_with_its_form_error(spec, diag, 0.2)


@full_grid
def test_hinge_friction_in_a_low_joint_is_named_located_and_sized_on_a_sixty_second_log(blind10):
    """Seed 1 (frictionloss 0.036 N m in joint 5) on a 59.3 s log: named ``joint_friction`` on joint 5
    alone (its band's F-test p 1.1e-15 with the factors, Wilcoxon 2.3e-11), within the 3-joint
    tests' 10 % (the middle of its estimates -2.9 % +- 15 % with the form error; the fit -8.6 %,
    eq 50's sigma 11 %): the column takes the
    camera's speed in its band only (-41 % with the full band, where the joint chatters under the
    camera's differentiated noise; -12 % with the plant's own speed, MuJoCo's friction constraint)."""
    spec, diag = blind10("joint_friction", SEED, moves=31)
    _hinge_named_on_its_joint_within_ten_percent(spec, diag)
    _hinge_within_two_sigma_with_its_form_error(spec, diag, 0.2)


@full_grid
def test_hinge_friction_in_a_low_joint_is_named_and_located_on_a_sixty_second_log(blind10):
    """Seed 3 (frictionloss 0.033 N m in joint 4) on a 59.3 s log: named ``joint_friction`` on joint 4
    alone (its band's F-test p 2.8e-6 with the factors, Wilcoxon 2.6e-4; on 15.6 and 30.8 s logs it
    is not named, docs/your-own-neck.md section 7).  Its size, the middle of its estimates
    (``hinge_size.py``), is within 10 % (+1.3 %; the fit +26 %, +25 % on 118 s: a form error, the
    plant's own speed reads +4 %), and its sigma with the form error says how well the data size it:
    0.0331 +- 0.011 N m, a third of the value (the fit's eq 50 sigma 0.0075)."""
    spec, diag = blind10("joint_friction", 3, moves=31)
    _hinge_named_on_its_joint_within_ten_percent(spec, diag)
    _hinge_within_two_sigma_with_its_form_error(spec, diag, 0.35)


def test_a_located_term_has_its_joints_columns_and_its_p_values_count_the_joints_searched():
    """A located term (shape ``joint``) of spring_error / joint_friction: its columns are those of
    the every-joint design named for its joint (looked up by name), the plant map puts its values
    on that joint, and its p values are multiplied by 2 N (Bonferroni over the two forms tried and
    the N joints of the one-joint form), the every-joint form's by 2."""
    from types import SimpleNamespace

    from identification.diagnosis.candidates import Term
    from identification.diagnosis.columns import FitContext, get
    from identification.diagnosis.search import located_comparison
    from identification.diagnosis.statistics import Comparison

    p = example_params("neck10x4")
    rng = np.random.default_rng(0)
    S, n, C = 40, p.n_joints, p.n_cables
    alpha = rng.uniform(-0.2, 0.2, (S, n))
    speed = rng.normal(0, 0.3, (S, n))
    data = _consistent_data(p, np.arange(S) / 31.25, alpha, speed, speed, np.full((S, C), 40.0), 2.75)
    ctx = FitContext(np.zeros((S, C)), None, None)
    for name, shape in (("spring_error", {}), ("joint_friction", {"width": 0.05})):
        cols = get(name)
        every = cols.design(data, shape, ctx).torque
        names = [nm for nm, _ in cols.column_names(n, C, shape)]
        one = cols.design(data, {**shape, "joint": 7}, ctx).torque
        own = [nm for nm, _ in cols.column_names(n, C, {**shape, "joint": 7})]
        assert own == [nm for nm in names if nm.split("(")[1].rstrip("LR)") == "7"]
        at = [names.index(nm) for nm in own]
        np.testing.assert_array_equal(one, every[:, :, at])
        values = np.arange(1.0, len(own) + 1.0)
        effect = cols.to_plant(p, {cols.columns[0].symbol: values}, {**shape, "joint": 7})[1]
        spread = np.asarray(effect.dk if name == "spring_error" else effect.torque)
        assert np.count_nonzero(spread) == len(own) and list(spread[at]) == list(values)
    cmp = Comparison(0.05, 0.05, 1e-4, 2e-3)
    located = located_comparison(cmp, Term("spring_error", (("joint", 3),)), n, C)
    assert (located.p_holdout, located.p_train) == pytest.approx((2 * n * 1e-4, 2 * n * 2e-3))
    every = located_comparison(cmp, Term("spring_error", ()), n, C)
    assert (every.p_holdout, every.p_train) == pytest.approx((2e-4, 4e-3))
    assert located_comparison(cmp, Term("payload", ()), n, C) == cmp
    assert located_comparison(Comparison(0.05, 0.05, 0.3, 0.5), Term("joint_friction", (("joint", 1), ("width", 0.05))),
                              n, C).p_train == 1.0


def test_the_hinge_column_of_a_neck_with_fewer_cables_than_joints_keeps_the_band_the_camera_reads():
    """The 10x4 neck's hinge column takes the camera's joint speed, which follows the joint's
    motion only below half the common cutoff (1.375 Hz here): the column is lever x
    tanh(alpha_dot / w) projected on that band.  32 s at 31.25 Hz, whole periods.  Joint 2 moves at
    0.25 Hz (0.3 rad/s, w = 0.2 rad/s: a smooth tanh): its column is lever x tanh(alpha_dot / w)
    within 1 %.  Joint 3 chatters at 2.5 Hz, above the band with all its harmonics: its column is
    zero but for the 13th harmonic, 32.5 Hz sampled at 31.25 Hz (1.25 Hz), of order 1e-5.  Joint 4
    does both: a fit of its full-band column to its projected one reads exactly 1 (a projection:
    the full band's excess is orthogonal to the band), where a Butterworth low-pass of the same
    cutoff reads more (its transition band passes part of the chatter, attenuated)."""
    from identification.diagnosis.columns import FitContext, get
    from identification.diagnosis.columns.joint_friction import hinge_lever
    from identification.filtering import lowpass

    p = example_params("neck10x4")
    rate, S, n, C, w = 31.25, 1000, p.n_joints, p.n_cables, 0.2
    t = np.arange(S) / rate
    alpha = np.full((S, n), 0.05)
    slow, chatter = 0.3 * np.sin(2 * np.pi * 0.25 * t), 0.3 * np.sin(2 * np.pi * 2.5 * t)
    speed = np.zeros((S, n))
    speed[:, 1], speed[:, 2], speed[:, 3] = slow, chatter, slow + chatter
    # camera and encoders agree (no noise): the fused speed is this speed
    data = _consistent_data(p, t, alpha, speed, speed, np.full((S, C), 40.0), 2.75)
    col = get("joint_friction").design(data, {"width": w}, FitContext(np.zeros((S, C)), None, None)).torque
    full = hinge_lever(alpha, p) * np.tanh(speed / w)
    assert np.abs(col[:, 1, 1] - full[:, 1]).max() < 0.01 * np.abs(full[:, 1]).max()
    assert np.abs(col[:, 2, 2]).max() < 1e-4 * np.abs(full[:, 2]).max()
    c = col[:, 3, 3]
    assert (c @ full[:, 3]) / (c @ c) == pytest.approx(1.0, abs=1e-9)
    smooth = lowpass(full[:, 3], rate, 1.375)
    assert (smooth @ full[:, 3]) / (smooth @ smooth) > 1.01


def _stick_slip_channel(tau=0.04, rate=31.25, S=2000):
    """A joint's torque channel (64 s, 31.25 Hz) with Coulomb friction of limit tau x lever that
    sticks: the joint slides at 0.4 sin(2 pi t / 8) rad/s while |sin| > 0.5 and rests otherwise,
    where the hinge holds 0.6 of its limit in the direction it last slid; plus a 2.5 Hz torque
    (whole periods, above the band) and white noise.  The measured speed carries 0.04 rad/s of
    band-limited noise, so a tanh of it is not zero where the joint rests."""
    from identification.diagnosis.materiality import project_band

    rng = np.random.default_rng(0)
    t = np.arange(S) / rate
    s = np.sin(2 * np.pi * t / 8.0)
    v = np.where(np.abs(s) > 0.5, 0.4 * s, 0.0)
    lever = 0.5 + 0.1 * np.sin(2 * np.pi * 0.05 * t)
    friction = np.where(v != 0, np.sign(v), 0.6 * np.sign(s)) * tau * lever
    r = friction + 0.01 * np.sin(2 * np.pi * 2.5 * t) + 0.002 * rng.standard_normal(S)
    measured = v + 3.0 * project_band(0.03 * rng.standard_normal(S), rate, 3.0)
    return r, lever, measured, rate


def test_the_hinge_size_from_sliding_samples_is_free_of_the_stick_that_biases_every_sample():
    """On a stick-slip channel built here (:func:`_stick_slip_channel`), the tanh column of the
    noisy speed (w = 0.01 rad/s) projected on the band (1.375 Hz) and fitted on every sample reads
    the limit more than 10 % low (where the joint rests the column is the noise's sign, the torque
    the held load: it adds to the column's power, not to its product with the torque);
    ``hinge_size.slide_size``, on the samples whose in-band speed exceeds 0.1 rad/s, reads it
    within 1 %.  (Fails when its mask keeps every sample: -13 %.)"""
    from identification.diagnosis.hinge_size import slide_size
    from identification.diagnosis.materiality import project_band

    tau, band = 0.04, 1.375
    r, lever, measured, rate = _stick_slip_channel(tau)
    col = project_band(lever * np.tanh(measured / 0.01), rate, band)
    every = np.ones(r.size, bool)
    assert (col @ r) / (col @ col) < 0.9 * tau
    assert slide_size(r, col, measured, every, rate, band) == pytest.approx(tau, rel=0.01)


def test_the_hinge_size_per_band_finds_the_width_and_size_of_a_tanh_channel_and_the_interval_spans_the_estimates():
    """A channel that is exactly tau lever tanh(v / w0) projected on the band, plus a torque at
    2.5 Hz (whole periods, out of the band): ``hinge_size.band_size`` returns tau and w0 of the grid
    (the projection makes the out-of-band torque orthogonal to every column).  ``interval`` is
    the middle and half the range of the estimates and the fit, ignoring one that could not be
    formed (NaN)."""
    from identification.diagnosis.hinge_size import band_size, interval
    from identification.diagnosis.materiality import project_band

    rate, S, band, tau, w0 = 31.25, 2000, 1.375, 0.04, 0.05
    t = np.arange(S) / rate
    v = 0.3 * np.sin(2 * np.pi * t / 8.0) + 0.1 * np.sin(2 * np.pi * t / 3.2)
    lever = 0.5 + 0.1 * np.sin(2 * np.pi * 0.05 * t)
    r = tau * project_band(lever * np.tanh(v / w0), rate, band) + 0.01 * np.sin(2 * np.pi * 2.5 * t)
    got, width = band_size(r, lever, v, np.ones(S, bool), rate, band, widths=(0.02, 0.05, 0.1))
    assert width == w0 and got == pytest.approx(tau, rel=1e-9)
    assert interval({"a": 0.03, "b": float("nan"), "c": 0.045}, 0.04) == pytest.approx((0.0375, 0.0075))
    assert interval({"a": 0.03}, 0.05) == pytest.approx((0.04, 0.01))


def _consistent_data(p, t, alpha, speed, camera_speed, tension, common_hz):
    """A ``ColumnData`` on the slow grid ``t`` (s): poses ``alpha`` (S, N) rad moving at ``speed``
    (S, N) rad/s, the camera reading ``camera_speed``, the cables at ``tension`` (S, C) N and the
    encoders turning as eq (27) says they must: (R/r_d)(Z^T alpha_dot + dx/dt), x the elastic
    elongation of eq (54) at rest, its rate by the chain rule (dx/dt = k / (k + lambda t)^2 dt/dt,
    dt/dt by ``numpy.gradient`` of the tensions, a smooth signal)."""
    from types import SimpleNamespace

    from neck_sim.analytic import transmission_matrix

    act, k, lam = p.actuation, np.asarray(p.cables.k), np.asarray(p.cables.lam)
    Z = transmission_matrix(alpha, p)
    x_dot = k / (k + lam * tension) ** 2 * np.gradient(tension, t, axis=0)
    theta_dot = (act.R / act.r_d) * (np.einsum("snc,sn->sc", Z, speed) + x_dot)
    cache: dict = {}
    return SimpleNamespace(params=p, n=p.n_joints, C=p.n_cables, S=t.size, t=t, alpha=alpha, alpha_dot=camera_speed,
                           Z=Z, theta_dot_fast=theta_dot, to_slow=lambda v: v, tension0=tension,
                           prep=SimpleNamespace(rate_hz=1.0 / (t[1] - t[0]),
                                                cutoffs={"common": SimpleNamespace(hz=common_hz)}),
                           cached=lambda key, f: cache[key] if key in cache else cache.setdefault(key, f()))


@pytest.mark.parametrize("seed", [SEED, pytest.param(2, marks=full_grid), pytest.param(3, marks=full_grid)])
def test_a_hidden_payload_on_the_ten_joint_neck_is_named(blind10, seed):
    """A payload hidden by MuJoCo's head body (mass, centre and inertia of a 2 cm cube 6 mm off the
    bar's middle: ``open_world.generator``), diagnosed blind: named alone, at the head (no cable,
    no joint), its mass within the 3-joint tests' 10 % once corrected for the camera's 1 deg noise
    by simulation-extrapolation (``identification/diagnosis/errors_in_variables.py``; least
    squares alone reads 9-16 % low on seeds 1-3), and within two of its sigmas, which hold the
    log's own noise realization (seeds 1-3: +1.3 +- 9.2 %, -9.0 +- 4.6 %, -0.0 +- 7.3 %;
    docs/your-own-neck.md, section 7)."""
    from identification.diagnosis.report import format_summary

    spec, diag = blind10("payload", seed)
    assert diag.verdict == "payload"
    f = diag.findings[0]
    assert not f.cables and not f.joints
    p = f.parameters[spec.symbol]
    assert "simulation-extrapolation" in p.note
    assert f"{spec.symbol} = " in format_summary(diag) and " kg (SIMEX)" in format_summary(diag)
    np.testing.assert_allclose(p.value, spec.magnitude, rtol=0.10)
    assert abs(p.value - spec.magnitude) <= 2 * p.sigma


def test_joint_excitation_reads_range_speed_and_reversals_of_known_sines():
    """Two joints on sines (0.3 rad at 0.5 Hz, 0.1 rad at 1 Hz) from t = 0 to 11 s: after the first
    second, range 2A, peak speed 2 pi f A and 2 f reversals per second (10 and 20 in 10 s),
    computed here from the sines' formulas."""
    from identification.excitation import joint_excitation

    t = np.arange(0.0, 11.0, 0.001)
    amp, freq = np.array([0.3, 0.1]), np.array([0.5, 1.0])
    ex = joint_excitation(t, amp * np.sin(2 * np.pi * freq * t[:, None]))
    np.testing.assert_allclose(ex.angle_range, 2 * amp, rtol=1e-6)
    np.testing.assert_allclose(ex.speed_max, 2 * np.pi * freq * amp, rtol=1e-5)
    assert ex.reversals.tolist() == [10, 20]


def test_a_one_joint_term_is_measured_on_its_own_channel():
    """Residuals of a 10-joint, 4-cable neck in which the candidate removes 40 % of joint 3's torque
    residual and changes nothing else: on its own channel the improvement is 0.4 (the whole score's
    0.4 / 20 = 2 % minus nothing), the F-test is that of one channel's effective samples (computed
    here from the F distribution) times 2N, and the term is named on it although the whole score's
    tests fail; a term on joint 4 sees nothing there, and one that makes the whole score worse on
    held-out data is not named.  The channel is compared in its band (below half the common
    cutoff, baseline and candidate low-passed alike), so the F-test counts that band's samples."""
    from types import SimpleNamespace

    from scipy import stats

    from identification.diagnosis.candidates import Term
    from identification.diagnosis.materiality import (candidate_decision, own_band_hz, own_comparison,
                                                      own_min_improvement)
    from identification.diagnosis.statistics import Comparison

    rng = np.random.default_rng(3)
    S, n, C, rate, fc = 900, 10, 4, 30.0, 2.6
    fold = (np.arange(S) // 50) % 3
    split = SimpleNamespace(chunk=np.arange(S) // 8, n_chunks=S // 8 + (S % 8 > 0), train=fold != 1, holdout=fold == 1)
    prep = SimpleNamespace(cutoffs={"common": SimpleNamespace(hz=fc)}, rate_hz=rate)
    data = SimpleNamespace(n=n, C=C, S=S, prep=prep)
    settings = SimpleNamespace(min_improvement=0.02, borderline=0.1, borderline_decades=0.3)
    alpha_c = 0.01 / 10
    ctx = SimpleNamespace(data=data, split=split, settings=settings, alpha_candidate=alpha_c,
                          candidate_margins=lambda c: c.margins(alpha_c, 0.02),
                          candidate_significant=lambda c: c.significant(alpha_c, 0.02))
    base = rng.normal(0.0, 1.0, (S, n + C))
    cand = base.copy()
    cand[:, 2] *= np.sqrt(0.6)                   # joint 3's residual: 40 % of its mean square removed
    ref = SimpleNamespace(cv=base, fit=SimpleNamespace(residuals=lambda: base))
    new = SimpleNamespace(cv=cand, fit=SimpleNamespace(residuals=lambda: cand))
    term = Term("spring_error", (("joint", 3),))
    own = own_comparison(ctx, ref, new, term, 3)
    assert own.improvement == pytest.approx(0.4) and own.holdout_improvement == pytest.approx(0.4)
    n_eff = int(split.train.sum() * 2 * own_band_hz(fc) / rate)        # its band's effective samples
    F = (0.4 / 3) / (0.6 / (n_eff - 3))
    assert own.p_train == pytest.approx(min(1.0, 2 * n * stats.f.sf(F, 3, n_eff - 3)), rel=1e-6)
    assert own.p_holdout < alpha_c
    assert own_comparison(ctx, ref, new, Term("payload", ()), 1) is None
    elsewhere = own_comparison(ctx, ref, new, Term("spring_error", (("joint", 4),)), 3)
    assert elsewhere.improvement == 0.0 and elsewhere.p_train == 1.0

    whole = Comparison(0.4 / (2 * n), 0.4 / (2 * n), 0.02, 0.3)      # fails the step's tests
    passes, held_to, margins, note = candidate_decision(ctx, whole, own)
    # held to the better of two tests: both p values times 2 (Bonferroni)
    assert passes and (held_to.p_train, held_to.p_holdout) == (2 * own.p_train, 2 * own.p_holdout)
    assert held_to.improvement == whole.improvement and margins["improvement"] == pytest.approx(0.4 / 0.12 - 1)
    assert own_min_improvement(0.02) == pytest.approx(0.12) and "own channel" in note
    worse = Comparison(-0.001, -0.001, 0.02, 0.3)
    assert not candidate_decision(ctx, worse, own)[0]
    assert candidate_decision(ctx, whole, None)[:2] == (False, whole)
    # an own channel whose p values pass at alpha but not at alpha / 2 is not named; a whole
    # score that passes at alpha / 2 is, held to its own p values times 2
    edge = Comparison(0.4, 0.4, 0.7 * alpha_c, 0.7 * alpha_c)
    assert edge.significant(alpha_c, 0.12) and not candidate_decision(ctx, whole, edge)[0]
    strong = Comparison(0.05, 0.05, 0.3 * alpha_c, 0.3 * alpha_c)
    passes, held_to, _, note = candidate_decision(ctx, strong, edge)
    assert passes and held_to.p_train == pytest.approx(0.6 * alpha_c) and not note
    assert candidate_decision(ctx, strong, None)[1] == strong


def test_a_material_own_channel_short_of_samples_names_the_log_length_that_would_decide():
    """A one-joint term whose own channel is 45 % lower in its band (at least the 12 % minimum)
    but whose F-test over 26 effective samples (3 parameters, factors 2N x 2 = 40) misses 1e-3:
    its note and the summary line name the joint and the log length at which the same relative
    gain passes, found here by counting samples up with the F distribution (scipy) until 40 p <
    1e-3, scaled by the log's 14.5 s.  No line when the channel is below 12 %, the whole score
    worse held out, the F-test already passes, or the candidate was named."""
    from types import SimpleNamespace

    from scipy import stats

    from identification.diagnosis.candidates import Term
    from identification.diagnosis.materiality import OwnComparison, deciding_length, undecided_lines, undecided_note
    from identification.diagnosis.statistics import Comparison

    def p40(n):
        F = ((1.0 - 0.5) / 3) / (0.5 / (n - 3))
        return 40 * stats.f.sf(F, 3, n - 3)

    own = OwnComparison(0.5, 0.5, 1e-3, p40(26) / 2, ms_ref=1.0, ms_cand=0.5, added=3, n_eff=26, places=20,
                        joint=5, duration_s=14.5)
    assert p40(26) > 1e-3
    n = 26
    while not p40(n) < 1e-3:
        n += 1
    assert deciding_length(own, 1e-3) == pytest.approx(14.5 * n / 26)
    whole = Comparison(0.005, 0.004, 0.2, 0.1)
    note = undecided_note(own, whole, 1e-3, 0.02)
    assert "joint 5" in note and f"about {14.5 * n / 26:.0f} s would decide" in note
    assert undecided_note(dataclasses.replace(own, improvement=0.11), whole, 1e-3, 0.02) == ""
    assert undecided_note(own, dataclasses.replace(whole, improvement=-0.001), 1e-3, 0.02) == ""
    assert undecided_note(dataclasses.replace(own, n_eff=n), whole, 1e-3, 0.02) == ""
    # the data must lean towards the term: F-test p with its factors below 0.1 (here 0.040)
    assert 0.03 < p40(26) < 0.1
    weak = dataclasses.replace(own, ms_cand=0.55, p_train=0.11 / 2)
    assert deciding_length(weak, 1e-3) is not None and undecided_note(weak, whole, 1e-3, 0.02) == ""
    cand = SimpleNamespace(term=Term("joint_friction", (("joint", 5), ("width", 0.05))), significant=False,
                           note="measured on its own channel; " + note)
    diag = SimpleNamespace(findings=(), steps=[SimpleNamespace(candidates=[cand])])
    (line,) = undecided_lines(diag)
    assert "joint_friction not decided: joint 5" in line and f"about {14.5 * n / 26:.0f} s would decide" in line
    named = SimpleNamespace(findings=(SimpleNamespace(effect="joint_friction"),), steps=diag.steps)
    assert undecided_lines(named) == []


def test_the_one_joint_form_is_placed_on_the_joint_whose_own_channel_it_lowers_most():
    """Three joints' torque channels and a cable's: a one-joint fit on joint 1 lowers the whole
    training score most (it halves the cable channel, a shared parameter's refit) and leaves its
    own channel as it was; one on joint 3 removes 40 % of joint 3's channel in its band.  The
    one-joint form is placed where it is tested, on joint 3 (``search.search_one_joint``), though
    the whole training score ranks joint 1 first."""
    from types import SimpleNamespace

    from identification.diagnosis.candidates import Term
    from identification.diagnosis.search import search_one_joint

    rng = np.random.default_rng(5)
    S, n, C, rate = 600, 3, 1, 31.25
    base = rng.normal(0.0, 1.0, (S, n + C))
    ctx = SimpleNamespace(data=SimpleNamespace(n=n, C=C, S=S, prep=SimpleNamespace(
                              rate_hz=rate, cutoffs={"common": SimpleNamespace(hz=2.75)})),
                          split=SimpleNamespace(train=np.arange(S) % 3 != 1),
                          base=SimpleNamespace(fit=SimpleNamespace(residuals=lambda: base)))
    res = {1: base * [1.0, 1.0, 1.0, 0.5], 2: base * 0.99, 3: base * [1.0, 1.0, np.sqrt(0.6), 1.0]}

    def trial(term):
        r = res[int(term.get("joint"))]
        return float(np.mean(r[ctx.split.train] ** 2)), term, SimpleNamespace(residuals=lambda r=r: r)

    every = (0.0, Term("spring_error", ()), None)
    whole_best = min((trial(Term("spring_error", (("joint", j),))) for j in (1, 2, 3)), key=lambda e: e[0])
    assert whole_best[1].get("joint") == 1
    assert search_one_joint(ctx, trial, "spring_error", every)[1].get("joint") == 3


def test_the_own_channel_is_compared_in_the_band_where_the_term_acts():
    """Joint 2's torque residual: a 0.3 Hz wave of 0.3 N m (an effect at the motion's frequencies)
    plus a 2.5 Hz wave of 1 N m (the camera's noise differentiated, near the 2.9 Hz common cutoff).
    A candidate that removes the slow wave removes a^2 / (a^2 + b^2) = 8.3 % of the raw channel,
    below the 12 % minimum; in the band below half the cutoff (1.45 Hz: a 4th-order zero-phase
    Butterworth passes 2.5 Hz at |H|^2 = 1 / (1 + (2.5 / 1.45)^8) in amplitude) it removes nearly all
    of it, computed here from the two sines' amplitudes."""
    from types import SimpleNamespace

    from identification.diagnosis.candidates import Term
    from identification.diagnosis.materiality import own_band_hz, own_comparison

    rate, fc, S, n, C = 31.25, 2.9, 1200, 10, 4
    t = np.arange(S) / rate
    fold = (np.arange(S) // 60) % 3
    split = SimpleNamespace(chunk=np.arange(S) // 8, train=fold != 1, holdout=fold == 1)
    prep = SimpleNamespace(cutoffs={"common": SimpleNamespace(hz=fc)}, rate_hz=rate)
    data = SimpleNamespace(n=n, C=C, S=S, prep=prep)
    ctx = SimpleNamespace(data=data, split=split)
    slow, fast = 0.3 * np.sin(2 * np.pi * 0.3 * t), 1.0 * np.sin(2 * np.pi * 2.5 * t)
    base = np.zeros((S, n + C))
    base[:, 1] = slow + fast
    cand = base.copy()
    cand[:, 1] = fast
    ref = SimpleNamespace(cv=base, fit=SimpleNamespace(residuals=lambda: base))
    new = SimpleNamespace(cv=cand, fit=SimpleNamespace(residuals=lambda: cand))
    own = own_comparison(ctx, ref, new, Term("spring_error", (("joint", 2),)), 2)
    gain = (1.0 / (1.0 + (2.5 / own_band_hz(fc)) ** 8)) ** 2          # two passes of |H|, in power
    expected = 0.3 ** 2 / (0.3 ** 2 + gain * 1.0 ** 2)
    assert 0.3 ** 2 / (0.3 ** 2 + 1.0) < 0.12 < own.improvement
    assert own.improvement == pytest.approx(expected, abs=0.01)
    assert own.p_holdout < 1e-6 and own.p_train < 1e-6


def test_a_step_of_look_alikes_is_reported_as_alternatives():
    """A step whose verdict lists two look-alikes (neither adds to the other fitted together) is
    reported as one or the other, the first (the leader) named as the better; a step with one
    name, or none chosen, adds no such line."""
    from types import SimpleNamespace

    from identification.diagnosis.report import look_alike_lines

    tied = SimpleNamespace(verdict=["dry_friction", "pulley_friction"], chosen=object())
    alone = SimpleNamespace(verdict="payload", chosen=object())
    nothing = SimpleNamespace(verdict="none", chosen=None)
    lines = look_alike_lines(SimpleNamespace(steps=(alone, tied, nothing)))
    assert lines == ["step 2: dry_friction or pulley_friction: fitted together neither adds to the other, so this "
                     "log supports one of them and cannot tell which; dry_friction has the larger cross-validated "
                     "improvement"]
    assert look_alike_lines(SimpleNamespace(steps=(alone, nothing))) == []
    # compared on one cable (selection.one_cable_pair): the line names it
    from identification.diagnosis.selection import EncompassingTest, Step

    on1 = Step(None, None, (), ["dry_friction", "pulley_friction"], object(),
               (EncompassingTest("dry_friction", "pulley_friction", None, None, False, False, cable=1),))
    assert look_alike_lines(SimpleNamespace(steps=(on1,))) == [
        "step 1: dry_friction or pulley_friction: fitted together on cable 1 neither adds to the other, so this log "
        "supports one of them and cannot tell which; dry_friction has the larger cross-validated improvement"]
    # with the columns' angle (selection.columns_angle): what would separate them
    from identification.diagnosis.statistics import Comparison

    adds = Comparison(0.0068, 0.005, 0.086, 0.011)
    angled = Step(None, None, (), ["dry_friction", "pulley_friction"], object(),
                  (EncompassingTest("dry_friction", "pulley_friction", None, adds, False, False, cable=1,
                                    angle_deg=14.7, needed=(27.0, None)),))
    assert look_alike_lines(SimpleNamespace(steps=(angled,))) == [
        "step 1: dry_friction or pulley_friction: fitted together on cable 1 neither adds to the other, so this log "
        "supports one of them and cannot tell which; dry_friction has the larger cross-validated improvement; their "
        "columns are 14.7 deg apart after the baseline (about the coefficient of variation of cable 1's tension while "
        "it moves: tan 14.7 deg = 0.26); a recording where that tension varies by a CV of about 0.51 (columns 27 deg "
        "apart) would separate them"]
    # two laws that do not differ by the tension: the angles only
    import dataclasses

    other = Step(None, None, (), ["dry_friction", "viscous_friction"], object(),
                 (dataclasses.replace(angled.pairwise[0], b="viscous_friction", needed=(21.0, 1.6)),))
    assert look_alike_lines(SimpleNamespace(steps=(other,)))[0].endswith(
        "improvement; their columns are 14.7 deg apart after the baseline; a recording where they are 21 deg apart "
        "would separate them, or a log about 1.6 times as long")
