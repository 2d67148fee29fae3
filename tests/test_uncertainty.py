"""Pieces of the calibrated uncertainty: the HAC covariance and the rows' sample indices."""

import numpy as np
import pytest

from identification.uncertainty import andrews_bandwidth, hac_covariance, row_samples


def _ar1(n, rho, rng):
    e = rng.normal(size=n)
    out = np.empty(n)
    out[0] = e[0] / np.sqrt(1 - rho ** 2)
    for i in range(1, n):
        out[i] = rho * out[i - 1] + e[i]
    return out


@pytest.mark.parametrize("rho", [0.0, 0.8, 0.95])
def test_hac_variance_of_a_mean_matches_the_long_run_variance(rho):
    """Mean of an AR(1) series: var = 1 / (n (1 - rho)^2) for unit innovations (long-run
    variance), against which eq (50)'s 1 / (n (1 - rho^2)) is (1 + rho) / (1 - rho) too small."""
    rng = np.random.default_rng(3)
    n = 40000
    y = _ar1(n, rho, rng)
    W = np.ones((n, 1))
    res = y - y.mean()
    cov, L = hac_covariance(W, res, np.arange(n), n)
    truth = 1.0 / (n * (1 - rho) ** 2)
    assert cov[0, 0] == pytest.approx(truth, rel=0.25), (cov[0, 0] / truth, L)
    if rho > 0.5:
        eq50 = res @ res / (n - 1) / n
        assert eq50 < 0.3 * truth        # the independent-residual formula is far off here


def test_bandwidth_grows_with_the_correlation():
    rng = np.random.default_rng(4)
    ls = [andrews_bandwidth(_ar1(5000, rho, rng)[:, None]) for rho in (0.0, 0.5, 0.9)]
    assert ls[0] <= 3 and ls[0] < ls[1] < ls[2]


def test_rows_of_several_per_sample_are_summed_before_the_kernel():
    """Two rows per sample carrying the same AR(1) error: the scores of a sample add up, so the
    variance is that of one row's series with twice the weight."""
    rng = np.random.default_rng(5)
    n = 20000
    e = _ar1(n, 0.9, rng)
    W = np.ones((2 * n, 1))
    rows = np.repeat(np.arange(n), 2)
    res = np.repeat(e, 2)
    cov, _ = hac_covariance(W, res - res.mean(), rows, n)
    assert cov[0, 0] == pytest.approx(1.0 / (n * 0.1 ** 2), rel=0.25)


def test_row_samples_follow_the_regressors_row_order(params):
    from identification import regressors as reg
    from identification.excitation import predict_run, prepared_from_prediction, sequences_trajectory

    traj = sequences_trajectory(np.radians([[20.0, 10.0, 10.0]]), move_time=1.0, hold_time=0.2)
    t = np.arange(0.0, traj.duration, 1.0 / params.control.rate_hz)
    s = traj.sample(t)
    run = predict_run(s.alpha, s.alpha_dot, s.alpha_ddot, t, params)
    prep = prepared_from_prediction(run, s.alpha_dot, s.alpha_ddot, 50.0)
    S, N = prep.n_samples, params.n_joints
    taut = np.ones((S, N + 1), bool)
    taut[::3, 1] = False
    rg = reg.elastic_model(prep, params, taut=taut)
    rows = row_samples(S, N, taut)
    assert rows.shape == (rg.W.shape[0],)
    # tension rows: the k column of cable i holds x_c of cable i at the row's sample
    C = N + 1
    n_t = int(taut.sum())
    for r in range(0, n_t, 7):
        i = int(np.flatnonzero(rg.W[r, :C])[0]) if np.any(rg.W[r, :C]) else None
        if i is not None:
            assert rg.W[r, i] == prep.x_c[rows[r], i]
    # torque rows: the f_s columns are Z diag(a) at the row's sample (weight 100)
    dyn = reg.joint_dynamics(prep, params)
    a = reg.friction_basis(prep.theta_dot, params)
    for r in range(n_t, rg.W.shape[0], 11):
        srow = rows[r]
        j = (r - n_t) % N
        np.testing.assert_allclose(rg.W[r, 2 * C:], 100 * dyn.Z[srow, j] * a[srow])


def test_second_order_term_is_what_the_linear_bias_correction_misses():
    """Estimates that depend on the camera's noise variance v as a + b v + c v^2 (the log at
    v = 1, replicates at v = 2 and 3): the first-order correction lands at a - 2 c, and the
    second-order term d2 = 2 c is exactly the distance to the noise-free a, kept in the sigma."""
    from identification.least_squares import solve_weighted
    from identification.uncertainty import Replicates, calibrate

    a, b, c = np.array([5.0, 100.0]), np.array([-0.4, 3.0]), np.array([0.05, -0.8])
    at = lambda v: a + b * v + c * v ** 2          # noqa: E731
    W = np.vstack([np.eye(2), np.eye(2)])
    ls = solve_weighted(W, np.tile(at(1.0), 2), ["k(1)", "k(2)"], ["N/m", "N/m"])
    spread = np.array([[-1.0], [1.0]]) * np.array([0.01, 0.2])      # replicates' spread, mean 0
    reps = Replicates(at(2.0) + np.repeat(spread, 3, axis=0), at(3.0) + spread)
    u = calibrate(ls, W, np.arange(4), 4, reps, camera_noise=0.01)
    np.testing.assert_allclose(u.value, 2 * at(1.0) - at(2.0))
    np.testing.assert_allclose(a - u.value, u.bias_second_order, rtol=1e-9)
    s2 = np.var(np.repeat(spread, 3, axis=0), axis=0, ddof=1) * (1 + 1 / 6)
    np.testing.assert_allclose(u.sigma_bootstrap ** 2, s2 + u.bias ** 2 + u.bias_second_order ** 2)
    assert np.all(np.abs(u.value - a) <= u.sigma)
    assert u.n_bootstrap == 6 and u.n_bootstrap_2x == 2


def test_replicates_at_the_logs_noise_only_give_no_second_order_term():
    from identification.least_squares import solve_weighted
    from identification.uncertainty import calibrate

    W = np.vstack([np.eye(2), np.eye(2)])
    ls = solve_weighted(W, np.array([1.0, 2.0, 1.0, 2.0]), ["k(1)", "k(2)"], ["N/m", "N/m"])
    reps = np.array([[1.1, 2.0], [1.3, 2.2], [1.2, 1.8]])
    u = calibrate(ls, W, np.arange(4), 4, reps, camera_noise=0.01)
    np.testing.assert_allclose(u.bias_second_order, 0.0)
    np.testing.assert_allclose(u.sigma_bootstrap, np.hypot(reps.std(0, ddof=1) * np.sqrt(4 / 3), reps.mean(0) - [1, 2]))
    assert u.n_bootstrap_2x == 0


def test_the_diagnosis_labels_its_sigmas_as_eq50_not_calibrated():
    """The diagnosis's linear parameters carry eq (50)'s sigma of its weighted fit; its JSON says
    so per parameter (it is not the calibrated sigma of ``identify``)."""
    from types import SimpleNamespace

    from identification.diagnosis.parameters import all_parameters

    fit = SimpleNamespace(names=("payload",), units=("kg",), value=np.array([0.068]), sigma=np.array([0.002]),
                          model=SimpleNamespace(terms=()))
    d = all_parameters(fit)["payload"].to_dict()
    assert d["sigma"] == 0.002 and "eq (50)" in d["note"] and "not calibrated" in d["note"], d
