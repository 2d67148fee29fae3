"""The diagnosis' fast paths against the plain computations they replace, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from identification.diagnosis.columns.backlash import motor_lead


def _lead_numpy(motor, band):
    """The play operator on arrays, one sample at a time (what :func:`motor_lead` replaced)."""
    half = 0.5 * np.broadcast_to(np.asarray(band, dtype=float), motor.shape[1:])
    step = np.diff(motor, axis=0, prepend=motor[:1])
    out, lead = np.empty_like(motor), np.zeros(motor.shape[1:])
    for k in range(motor.shape[0]):
        lead = np.minimum(np.maximum(lead + step[k], -half), half)
        out[k] = lead
    return out


@pytest.mark.parametrize("band", [0.5e-3, 0.0, np.array([0.0, 1e-3, 2e-3])])
def test_motor_lead_is_the_array_play_operator_bit_for_bit(rng, band):
    """Random walks crossing the band, exact reversals, steps of exactly 0 and a
    NaN sample: the same bits as the array loop (NaN and the sign of zero included)."""
    motor = np.cumsum(rng.normal(scale=2e-4, size=(3000, 3)), axis=0)
    motor[1000:1100] = motor[999]                       # the motor standing: steps of exactly 0
    motor[1100:1200] = -motor[1100:1200]
    motor[2000, 1] = np.nan
    for m in (motor, np.asfortranarray(motor), motor[:, 1]):
        b = band if np.ndim(band) == 0 or m.ndim == 2 else band[1]
        fast, ref = motor_lead(m, b), _lead_numpy(m, b)
        assert fast.shape == ref.shape and fast.tobytes() == ref.tobytes()


def test_solve_weighted_without_the_condition_number_changes_nothing_else(rng):
    """``condition=False`` (the diagnosis' fits): every other field the same bits, the condition
    numbers NaN; the default's ``cond`` is numpy's of the weighted W."""
    from identification.least_squares import solve_weighted

    W = rng.normal(size=(200, 4)) * [1.0, 1e-3, 10.0, 1.0]
    Y = W @ [1.0, 2.0, -3.0, 0.5] + rng.normal(scale=0.1, size=200)
    w = rng.uniform(0.5, 2.0, size=200)
    full, lean = solve_weighted(W, Y, row_weights=w), solve_weighted(W, Y, row_weights=w, condition=False)
    for field in ("value", "sigma", "rel_sigma", "cov", "residual", "sigma_rho", "n_rows"):
        assert np.asarray(getattr(lean, field)).tobytes() == np.asarray(getattr(full, field)).tobytes(), field
    assert np.isnan(lean.cond) and full.cond == np.linalg.cond(W * w[:, None]) and np.isnan(lean.cond_scaled)


@pytest.mark.filterwarnings("ignore:invalid value encountered in sqrt")     # sigma of the 6.6e9 and 2e9 W
@pytest.mark.parametrize("tilt", [0.0, 1e-12, 1.5e-10, 3e-10, 1e-9, 1e-6])
def test_solve_weighted_refuses_the_same_near_collinear_columns_either_way(rng, tilt):
    """Two columns ``tilt`` apart (scaled condition numbers 3e16, 2e12, 1.3e10, 6.6e9, 2e9, 2e6):
    the same error message, or the same values, with and without the condition numbers (lstsq's
    singular values decide far from the 1e10 bound, the exact SVD's within a factor 2 of it)."""
    from identification.least_squares import solve_weighted

    W = rng.normal(size=(300, 3))
    W[:, 2] = W[:, 1] + tilt * rng.normal(size=300)
    Y = W @ [1.0, 2.0, 3.0]
    outcomes = []
    for condition in (True, False):
        try:
            outcomes.append(solve_weighted(W, Y, condition=condition).value.tobytes())
        except ValueError as exc:
            outcomes.append(str(exc))
    assert outcomes[0] == outcomes[1]
    refused = isinstance(outcomes[0], str)
    assert refused == (tilt < 2e-10) and (not refused or "rank-deficient" in outcomes[0]), outcomes[0]


@pytest.mark.parametrize("neck", ["paper", "neck10x4"])
def test_the_slopes_alone_are_the_general_segments_first_derivatives(rng, neck):
    """Z's path (order 1 alone) against the general one that also computes the lengths: the same
    bits for every segment kind, on poses across and beyond the joint range, batched and single."""
    from neck_sim.analytic.cables import _geom, _routing_terms, _segments
    from neck_sim.params import example_params

    p = example_params(neck)
    amax = p.geometry.alpha_max
    for left_strut in (False, True, _routing_terms(p)[2]):
        for a in (rng.uniform(-1.2 * amax, 1.2 * amax, size=(50, p.n_joints)), np.zeros(p.n_joints)):
            lean = _segments(a, *_geom(p), orders=(1,), left_strut=left_strut)
            general = _segments(a, *_geom(p), orders=(0, 1), left_strut=left_strut)
            assert list(lean) == [1] and lean[1].tobytes() == general[1].tobytes()


def _alpha_pinv_by_steps(theta, params, elongation, alpha0):
    """estimate_alpha_pinv's series, one public pinv_increment per step (what its loop replaced)."""
    from neck_sim.analytic import pinv_increment

    a, out = alpha0, [alpha0]
    for t in range(1, theta.shape[-2]):
        dx = None if elongation is None else elongation[..., t, :] - elongation[..., t - 1, :]
        a = a + pinv_increment(a, theta[..., t, :] - theta[..., t - 1, :], params, dx, allow_outside_range=True)
        out.append(a)
    return np.stack(out, axis=-2)


@pytest.mark.filterwarnings("ignore:overflow encountered in subtract")      # the overflowing step
def test_alpha_pinv_series_is_its_steps_bit_for_bit(rng):
    """Two models' elongations under one motor series (the diagnosis' batch), with and without
    elongation: the same bits as pinv_increment step after step; an overflowing elongation step
    raises pinv_increment's own error at the same step."""
    from neck_sim.analytic import estimate_alpha_pinv, motor_angles_rigid
    from neck_sim.params import default_params

    p = default_params(3)
    t = np.linspace(0.0, 4.0, 400)[:, None]
    alpha = 0.3 * np.sin(2 * np.pi * t * [0.3, 0.5, 0.7])
    theta = motor_angles_rigid(alpha, p) + rng.normal(scale=1e-4, size=(400, 4))
    x = rng.normal(scale=1e-5, size=(2, 400, 4))
    a0 = np.broadcast_to(alpha[0], (2, 3))
    th = np.broadcast_to(theta, x.shape)
    for elong in (x, None):
        fast = estimate_alpha_pinv(th, p, elong, alpha0=a0, tol=1.0)
        assert fast.tobytes() == _alpha_pinv_by_steps(th, p, elong, a0).tobytes()
    for k, message in ((200, "alpha_hat"), (0, "d_elongation")):   # the next step's pose, or this step's
        y = x.copy()
        y[1, k, 2], y[1, k + 1, 2] = -1e308, 1e308
        with pytest.raises(ValueError, match=f"^{message}: contains NaN or infinity$"):
            _alpha_pinv_by_steps(th, p, y, a0)
        with pytest.raises(ValueError, match=f"^{message}: contains NaN or infinity$"):
            estimate_alpha_pinv(th, p, y, alpha0=a0, tol=1.0)


def test_check_holdable_solves_each_held_pose_once(monkeypatch):
    """The control-test trajectory on the ten-joint neck holds its poses: one bounded least squares
    per distinct pose, and the refusal names the sample that solving every sample finds furthest
    out of reach."""
    import scipy.optimize

    from controllers import reachable_paths as rp
    from neck_sim.params import example_params
    from neck_sim.trajectory import scaled_trajectory

    p = example_params("neck10x4")
    traj = scaled_trajectory("control-test", p, 0.2)
    t = np.arange(0.0, traj.duration + 0.025, 0.05)
    distinct = len({a.tobytes() for a in traj.sample(t).alpha})
    real, calls = scipy.optimize.lsq_linear, []
    monkeypatch.setattr(scipy.optimize, "lsq_linear", lambda *a, **k: calls.append(1) or real(*a, **k))
    with pytest.raises(ValueError, match="out of this neck's reach") as refused:
        rp.check_holdable(traj, p)
    assert len(calls) == distinct < t.size
    Z, g = rp.transmission_matrix(traj.sample(t).alpha, p), rp.gravity_spring_torque(traj.sample(t).alpha, p)
    hi = rp.FORCE_MARGIN * p.actuation.f_max
    res = np.abs([Zk @ real(Zk, gk, bounds=(0.0, hi)).x - gk for Zk, gk in zip(Z, g)])
    k = int(np.unravel_index(np.argmax(res), res.shape)[0])
    assert f"the pose at t = {t[k]:.2f} s" in str(refused.value)
