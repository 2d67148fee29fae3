"""The output-error fit's cheaper Jacobian (``OutputErrorSettings.jacobian_timestep``): f_s, k
and lambda columns from rollouts at 2 ms on ``discrete``, everything else on the plant.

One short clean run (law 1 through two random poses, 4 s); the fit from 3 % off the truth with
the cheap Jacobian is compared with the same fit whose every column is on the plant
(``jacobian_timestep=None``): an independent Jacobian, the same residuals.
"""

from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def problem(tmp_path_factory):
    from controllers.closed_loop import run_closed_loop
    from controllers.computed_torque import ComputedTorqueController
    from controllers.trajectories import cycloidal_path
    from identification.output_error.problem import Layout, Measured
    from neck_sim.logs import read_log
    from neck_sim.params import default_params
    from neck_sim.plant import Plant

    p = default_params(3)
    rng = np.random.default_rng(4)
    amp = np.radians([40.0, 30.0, 20.0])
    poses = [np.zeros(3), rng.uniform(-amp, amp), rng.uniform(-amp, amp), np.zeros(3)]
    path = tmp_path_factory.mktemp("oejac") / "run.mcap"
    run_closed_loop(Plant(p, seed=4), ComputedTorqueController(p, law=1), cycloidal_path(poses, 1.0, 0.33, name="jac"),
                    log_path=path, progress=False)
    log = read_log(path, topics=("motors", "camera", "reference"))
    layout = Layout.of(log.params)
    truth = layout.vector()
    x0 = truth * (1 + 0.03 * np.random.default_rng(7).choice([-1.0, 1.0], truth.size))
    return [Measured.from_log(log, log.params, name=path.name)], layout, x0, truth


@pytest.fixture(scope="module")
def plant_jacobian_fit(problem):
    from identification.output_error.fit import fit
    from identification.output_error.settings import OutputErrorSettings

    measured, layout, x0, _ = problem
    return fit(measured, layout, x0, OutputErrorSettings(jacobian_timestep=None))


def test_cheap_jacobian_fit_matches_the_plant_jacobian_fit(problem, plant_jacobian_fit):
    """Same optimum within 0.1 sigma, sigmas within 6 % and the same cost (measured: 0.082 sigma,
    4.9 %, cost ratios 1.7e-6 apart; both fits converge at the noise floor); the coarse rollouts
    are 13 per Jacobian (its base and the 12 f_s, k, lambda columns)."""
    from identification.output_error.fit import fit

    measured, layout, x0, truth = problem
    cheap, full = fit(measured, layout, x0), plant_jacobian_fit
    assert cheap.converged and full.converged and not cheap.misfit, (cheap.status, full.status)
    assert full.coarse_rollouts == 0 and cheap.coarse_rollouts == 13 * cheap.iterations
    assert np.all(np.abs(cheap.value - full.value) < 0.1 * full.sigma), (cheap.value - full.value) / full.sigma
    np.testing.assert_allclose(cheap.sigma, full.sigma, rtol=0.06)
    for signal, ratio in full.cost_ratio.items():
        assert cheap.cost_ratio[signal] == pytest.approx(ratio, rel=1e-5), (signal, cheap.cost_ratio, full.cost_ratio)
    # the coarse rollouts are the cheaper ones (measured 7.6 against 10.1 s of CPU in rollouts)
    assert cheap.rollout_cpu_s < full.rollout_cpu_s, (cheap.rollout_cpu_s, full.rollout_cpu_s)


def test_a_diverging_coarse_model_falls_back_to_the_plant(problem, plant_jacobian_fit, monkeypatch):
    """Every coarse rollout reported diverged: every column is taken on the plant, so the fit is
    the plant-Jacobian fit, number for number."""
    from identification.output_error import fit as fit_mod

    measured, layout, x0, _ = problem
    real = fit_mod._coarse_rollout

    def diverged(replay, params, effects, timestep, integrator):
        out = real(replay, params, effects, timestep, integrator)
        K = len(params)
        return type(out)(np.full_like(out.encoders, np.nan), np.full_like(out.camera_alpha, np.nan),
                         np.ones(K, bool), np.zeros(K), ("diverged: test",) * K)

    monkeypatch.setattr(fit_mod, "_coarse_rollout", diverged)
    res = fit_mod.fit(measured, layout, x0)
    np.testing.assert_array_equal(res.value, plant_jacobian_fit.value)
    np.testing.assert_array_equal(res.sigma, plant_jacobian_fit.sigma)
    assert not res.rejected                  # a coarse column is no candidate step


def test_bad_jacobian_settings_are_one_line_errors(problem):
    from identification.output_error.fit import fit
    from identification.output_error.settings import OutputErrorSettings

    with pytest.raises(ValueError, match="jacobian_timestep: must be positive"):
        OutputErrorSettings(jacobian_timestep=0.0)
    with pytest.raises(ValueError, match="jacobian_integrator: unknown 'rk4'"):
        OutputErrorSettings(jacobian_integrator="rk4")
    with pytest.raises(ValueError, match="jacobian_groups: expected a tuple"):
        OutputErrorSettings(jacobian_groups="k")
    measured, layout, x0, _ = problem
    with pytest.raises(ValueError, match=r"^jacobian_timestep: .*not a whole number of physics steps") as exc:
        fit(measured, layout, x0, OutputErrorSettings(jacobian_timestep=3e-3, max_evaluations=1))
    assert "\n" not in str(exc.value)
