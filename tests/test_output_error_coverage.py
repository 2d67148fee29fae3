"""Coverage of the output-error intervals (``identification.output_error.intervals``) over a few
seeds of short simulated runs: each seed's run goes through its own random poses (law 1 does not
read the camera, so the poses are what make the encoders differ), the fit starts 3 % off the
truth (every parameter), and its errors in units of its sigma are pooled over the seeds' 16 parameters.

The targets are about 68 % within 1 sigma and 95 % within 1.96 sigma; this test fails below
55 % / 88 % (``benchmarks/bench_output_error_coverage.py`` prints the table over 20 seeds).
"""

from __future__ import annotations

import os

import numpy as np
import pytest

pytestmark = pytest.mark.slow

SEEDS = (0, 1, 2, 3)
#: s per move and per hold, random poses per run: 8 s runs, the benchmark's
MOVE_S, HOLD_S, POSES = 1.5, 0.5, 3


@pytest.fixture(scope="module")
def z_scores(tmp_path_factory):
    from controllers.closed_loop import run_closed_loop
    from controllers.computed_torque import ComputedTorqueController
    from controllers.trajectories import cycloidal_path
    from identification.output_error.fit import fit
    from identification.output_error.problem import Layout, Measured
    from neck_sim.logs import read_log
    from neck_sim.params import default_params
    from neck_sim.plant import Plant

    p = default_params(3)
    amp = np.radians([40.0, 30.0, 20.0])
    d = tmp_path_factory.mktemp("oecov")
    zs, names, converged = [], None, []
    for seed in SEEDS:
        rng = np.random.default_rng(seed)
        poses = [np.zeros(3)] + [rng.uniform(-amp, amp) for _ in range(POSES)] + [np.zeros(3)]
        path = d / f"cov{seed}.mcap"
        run_closed_loop(Plant(p, seed=seed), ComputedTorqueController(p, law=1),
                        cycloidal_path(poses, MOVE_S, HOLD_S, name="coverage"), log_path=path, progress=False)
        log = read_log(path, topics=("motors", "camera", "reference"))
        layout = Layout.of(log.params)
        truth = layout.vector()
        x0 = truth * (1 + 0.03 * np.random.default_rng(1000 + seed).choice([-1.0, 1.0], truth.size))
        res = fit([Measured.from_log(log, log.params, name=path.name)], layout, x0)
        zs.append((res.value - truth) / res.sigma)
        names = res.names
        converged.append(res.converged)
    return np.array(zs), names, converged


@pytest.mark.skipif(os.environ.get("NECK_SIM_FULL_GRID") != "1",
                    reason="NECK_SIM_FULL_GRID=1 runs it (the suite's time budget; "
                           "bench_output_error_coverage.py measures 20 seeds)")
def test_intervals_cover_the_truth_over_seeds(z_scores):
    """Every fit converges and the pooled coverage meets 55 % / 88 % (measured on seeds 0-3 by
    bench_output_error_coverage.py, the same fits: 63 % / 91 %, seed by seed 69/100, 50/94,
    44/69, 88/100 %; 61 % / 89 % before the fit's cheaper Jacobian)."""
    from identification.output_error.intervals import coverage

    z, names, converged = z_scores
    assert all(converged), converged
    within_1, within_95, count = coverage(z, names)["all"]
    assert count == len(SEEDS) * 16
    assert within_1 >= 0.55 and within_95 >= 0.88, (within_1, within_95, np.round(z, 2))


def test_coverage_counts_against_the_two_bars():
    """coverage() groups by symbol and counts |z| below 1 and below 1.96."""
    from identification.output_error.intervals import coverage

    z = np.array([[0.5, -1.5, 2.5, 0.1], [1.2, 0.0, -0.9, 1.97]])
    cov = coverage(z, ("k(1)", "k(2)", "c_a(1)", "c_a(2)"), groups=("k", "c_a"))
    assert cov["k"] == (0.5, 1.0, 4)
    assert cov["c_a"] == (0.5, 0.5, 4)
    assert cov["all"] == (0.5, 0.75, 8)
