"""Output-error identification (``identification.output_error``) on short windows of a clean
simulated identification run: accuracy and interval coverage from a start 3 % off the truth,
the noise floor and the misfit report, rejected diverging candidates, the parameter layout of an
extended model, the Jacobian covariance against the linear least squares, and bad input.

The full 85 s run from the least-squares start is measured in docs/identification.md
("Output-error identification"); here 2 s windows keep the suite cheap (about 30 s of CPU per
fit on the serial engine).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from neck_sim.params import default_params

pytestmark = pytest.mark.slow

WINDOW_S = 2.0


# The tests read at most the first 4.5 s of a run (``identify --end 4.5``; the fits 2 s): the runs
# stop at 6 s, whose first seconds are those of the whole runs bit for bit (a closed-loop run does not
# look ahead), for a twentieth of their simulation.
CUT_S = 6.0


class _Prefix:
    """The first ``duration`` seconds of trajectory ``traj``: its own samples, a shorter run."""

    def __init__(self, traj, duration):
        self._traj, self.duration = traj, min(float(duration), traj.duration)

    def __getattr__(self, name):
        return getattr(self._traj, name)


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """Two clean identification runs (law 1): camera-noise seeds 0 and 1, moves and holds at their
    nominal durations and 0.8 times them (law 1 does not read the camera: the second run's other
    timing is what gives it other forces and encoder quantisation errors), their first ``CUT_S`` s."""
    from controllers import selection
    from neck_sim.cli import main

    whole = selection.make_run_trajectory
    d = tmp_path_factory.mktemp("oe")
    paths = []
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(selection, "make_run_trajectory", lambda *a, **k: _Prefix(whole(*a, **k), CUT_S))
        for seed, scale in ((0, "1"), (1, "0.8")):
            path = d / f"ident{seed}.mcap"
            assert main(["simulate", "--trajectory", "identification", "--law", "1", "-o", str(path), "--no-progress",
                         "--seed", str(seed), "--duration-scale", scale]) == 0
            paths.append(path)
    return paths


def _measured(path, start=0.0, span=WINDOW_S):
    from identification.output_error.problem import Measured
    from neck_sim.logs import read_log

    log = read_log(path, start=start, end=start + span, topics=("motors", "camera", "reference"))
    return Measured.from_log(log, log.params, name=str(path)), log.params


def _start(x_true, seed=1, off=0.03):
    """3 % off the truth in random directions; c_a from 1 to 51 N s/m (the least squares cannot see it)."""
    rng = np.random.default_rng(seed)
    x0 = x_true * (1 + off * rng.choice([-1, 1], x_true.size))
    x0[-4:] = [1.0, 3.0, 51.0, 35.0]
    return x0


@pytest.fixture(scope="module")
def fits(logs):
    """Fits on the first 2 s of each run (a re-simulation starts at rest: a window must too)."""
    from identification.output_error.fit import fit
    from identification.output_error.problem import Layout

    out = []
    for path in logs:
        meas, params = _measured(path)
        layout = Layout.of(params)
        out.append((fit([meas], layout, _start(layout.vector())), layout.vector()))
    return out


def test_accuracy_from_a_start_3_percent_off(fits):
    # measured: f_s within 0.010 / 0.003 %, k and lambda 0.57 / 0.40 %, c_a 3.6 / 2.1 % (run 1 / run 2)
    for res, truth in fits:
        err = np.abs(res.value - truth) / truth
        g = {sym: err[[i for i, n in enumerate(res.names) if n.startswith(sym + "(")]]
             for sym in ("f_s", "k", "lambda", "c_a")}
        assert g["f_s"].max() < 2e-4, g["f_s"]
        assert g["k"].max() < 8e-3 and g["lambda"].max() < 8e-3, (g["k"], g["lambda"])
        assert g["c_a"].max() < 0.06, g["c_a"]
        assert res.converged and not res.misfit


def test_cost_is_at_the_noise_floor(fits):
    """Weighted by the true noise, the clean run's mean square residual is 1 per signal, within
    3 standard deviations of a chi-square over its n samples, 3 sqrt(2 / n) (measured: encoders
    0.994 / 0.993 over 8000 samples, camera 0.92 / 0.78 over 180)."""
    for res, _ in fits:
        for sig, ratio in res.cost_ratio.items():
            assert abs(ratio - 1.0) < 3.0 * np.sqrt(2.0 / res.n_samples[sig]), (sig, ratio, res.n_samples[sig])


def test_interval_coverage(fits):
    """|error| / sigma over the 32 parameters of the two runs: about 68 % within 1 sigma, 95 %
    within 1.96 (measured: 75 / 81 % and 100 / 100 % on the two runs)."""
    z = np.concatenate([np.abs(res.value - truth) / res.sigma for res, truth in fits])
    assert 0.5 <= np.mean(z < 1.0) <= 0.9, np.round(z, 2)
    assert np.mean(z < 1.96) >= 0.85, np.round(z, 2)


def test_jacobian_covariance_is_the_linear_least_squares_one():
    """For a linear model the Jacobian covariance is eq (50)'s (``solve_weighted``'s)."""
    from identification.least_squares import solve_weighted
    from identification.output_error.intervals import jacobian_covariance

    rng = np.random.default_rng(3)
    W = rng.normal(size=(200, 3)) * [1.0, 1e3, 1e-2]
    Y = W @ [1.0, 2.0, 3.0] + rng.normal(size=200)
    ls = solve_weighted(W, Y)
    cov, s2 = jacobian_covariance(W, ls.residual)
    np.testing.assert_allclose(cov, ls.cov, rtol=1e-9)
    assert s2 == pytest.approx(ls.sigma_rho ** 2)


def test_hac_intervals_widen_for_held_quantisation_errors():
    """White residuals: the sandwich agrees with s^2 (J^T J)^-1 within its sampling spread; the
    same variance held constant over blocks of 50 samples (a resting motor's quantisation error)
    widens it by about sqrt(50) (the plain formula cannot see the difference)."""
    from identification.output_error.intervals import hac_jacobian_covariance, jacobian_covariance

    rng = np.random.default_rng(5)
    n = 20000
    t = np.arange(n)
    J = np.stack([np.sin(2 * np.pi * t / 4000), np.cos(2 * np.pi * t / 7000) * 1e3], axis=1)
    white = rng.normal(size=n)
    held = np.repeat(rng.normal(size=n // 50), 50)
    for r, low, high in ((white, 0.8, 1.25), (held, 4.0, 10.0)):
        plain, _ = jacobian_covariance(J, r)
        hac, _ = hac_jacobian_covariance(J, r, t, n)
        ratio = np.sqrt(np.diag(hac) / np.diag(plain))
        assert np.all((ratio > low) & (ratio < high)), ratio


def test_misfit_is_reported_with_a_pointer_to_diagnose(logs):
    """The truth is at the noise floor; 5 % too little friction is flagged and points to diagnose."""
    from identification.output_error.fit import cost_at
    from identification.output_error.misfit import misfit_lines
    from identification.output_error.problem import Layout

    meas, params = _measured(logs[0])
    layout = Layout.of(params)
    x = layout.vector()
    truth = cost_at([meas], layout, x, "implicitfast")
    assert all(0.85 < r < 1.15 for r in truth.values()), truth
    assert misfit_lines(truth, [meas.name]) == []
    off = x.copy()
    off[:4] *= 0.95
    wrong = cost_at([meas], layout, off, "implicitfast")
    lines = misfit_lines(wrong, [meas.name])
    assert wrong["encoders"] > 10 and any("neck-sim diagnose" in line and "encoders" in line for line in lines)


def test_a_diverging_candidate_is_a_rejected_step(logs, monkeypatch):
    """The engine reports the first candidate after the start as diverged: the fit goes on."""
    from identification.output_error import fit as fit_mod
    from identification.output_error.problem import Layout

    meas, params = _measured(logs[0], span=0.5)
    layout = Layout.of(params)
    real, calls = fit_mod._rollout, []

    def flaky(replay, plist, effects, integrator):
        out = real(replay, plist, effects, integrator)
        calls.append(len(plist))
        if len(plist) == 1 and len(calls) == 3:        # start, Jacobian, then the first trial step
            return type(out)(np.full_like(out.encoders, np.nan), np.full_like(out.camera_alpha, np.nan),
                             np.ones(1, bool), np.zeros(1), ("diverged: test",))
        return out

    monkeypatch.setattr(fit_mod, "_rollout", flaky)
    res = fit_mod.fit([meas], layout, _start(layout.vector()),
                      fit_mod.OutputErrorSettings(max_evaluations=3))
    assert len(res.rejected) == 1 and "diverged: test" in res.rejected[0]
    assert np.all(np.isfinite(res.value))


def test_a_start_that_diverges_is_a_one_line_error(logs, monkeypatch):
    from identification.output_error import fit as fit_mod
    from identification.output_error.problem import Layout

    meas, params = _measured(logs[0], span=0.2)
    layout = Layout.of(params)

    def dead(replay, plist, effects, integrator):
        K, T, F = len(plist), replay.n_periods, replay.camera_t.size
        return fit_mod.engine.Rollouts(np.full((K, T, 4), np.nan), np.full((K, F, 3), np.nan), np.ones(K, bool),
                                       np.zeros(K), ("diverged: MuJoCo reported bad qacc",) * K)

    monkeypatch.setattr(fit_mod, "_rollout", dead)
    with pytest.raises(ValueError, match=r"cannot be simulated.*bad qacc") as exc:
        fit_mod.fit([meas], layout, layout.vector())
    assert "\n" not in str(exc.value)


def test_integrator_is_fixed_for_the_whole_fit(logs, monkeypatch):
    from identification.output_error import fit as fit_mod
    from identification.output_error.problem import Layout

    meas, params = _measured(logs[0], span=0.3)
    layout = Layout.of(params)
    seen = set()
    real = fit_mod._rollout

    def spy(replay, plist, effects, integrator):
        seen.add(integrator)
        return real(replay, plist, effects, integrator)

    monkeypatch.setattr(fit_mod, "_rollout", spy)
    x0 = layout.vector()
    x0[-4:] = 55.0                  # near the plant's own switch (60 N s/m at these bars)
    res = fit_mod.fit([meas], layout, x0, fit_mod.OutputErrorSettings(max_evaluations=2))
    assert seen == {res.integrator} == {"implicitfast"}


def test_layout_of_an_extended_model_round_trips():
    from identification.output_error.problem import Layout
    from neck_sim.effects import Effects, make_effect
    from neck_sim.params import to_dict

    p = default_params(3)
    eff = Effects.of(make_effect("viscous_friction", c_v=(0.1, 0.3), cables=(0, 2)))
    layout = Layout.of(p, eff)
    assert layout.names[-2:] == ("viscous_friction.c_v(1)", "viscous_friction.c_v(3)")
    x = layout.vector()
    assert x[-2:].tolist() == [0.1, 0.3]
    x2 = x.copy()
    x2[layout.names.index("k(2)")] = 1234.0
    x2[-1] = 0.7
    params, effects = layout.plant(x2)
    assert params.cables.k[1] == 1234.0 and effects.viscous_friction.c_v == (0.1, 0.7)
    back, beff = layout.plant(x)
    assert to_dict(back) == to_dict(p) and beff == eff


def test_logs_of_different_necks_are_refused():
    from identification.output_error.problem import same_neck

    p = default_params(3)
    other = p.replace(**{"geometry.L": p.geometry.L * 1.1})
    with pytest.raises(ValueError, match=r"b\.mcap: a different neck from a\.mcap \(geometry\.L differs\)"):
        same_neck(p, other, "b.mcap", "a.mcap")
    same_neck(p, default_params(3), "b.mcap", "a.mcap")


def test_model_file_errors_are_one_line(tmp_path):
    from identification.output_error.identify import load_extended_model

    bad = tmp_path / "m.json"
    bad.write_text(json.dumps({"model": []}))
    with pytest.raises(ValueError, match=r"--model .*expected a model file written by 'neck-sim diagnose --extended'"):
        load_extended_model(bad)
    bad.write_text(json.dumps({"params": {}, "effects": {}, "rigid_cables": True}))
    with pytest.raises(ValueError, match="rigid-cable model"):
        load_extended_model(bad)


def test_cli_json_holds_output_error_beside_least_squares(logs, tmp_path, capsys):
    """`identify --method output-error`: text and JSON carry both methods (a fit cut short at 2
    trial steps says it did not converge)."""
    from neck_sim.cli import main

    out = tmp_path / "id.json"
    assert main(["identify", str(logs[0]), "--method", "output-error", "--end", "4.5", "--max-evaluations", "2",
                 "--bootstrap", "0", "--no-alpha", "--no-progress", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "Table 1" in text and "Output-error identification" in text and "NOT CONVERGED" in text
    data = json.loads(out.read_text())
    assert data["models"]["variable"] is not None
    oe = data["output_error"]
    for group in ("f_s", "k", "lambda", "c_a"):
        rows = oe["parameters"][group]
        assert len(rows) == 4 and all(np.isfinite(r["value"]) and r["ci95"] > 0 for r in rows)
    assert oe["converged"] is False and oe["integrator"] == "implicitfast"
    assert oe["trial_steps"] == 2
