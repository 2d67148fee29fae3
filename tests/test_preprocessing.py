"""Pre-processing for identification: cutoff choice, zero-phase filtering, decimation, elongations."""

import numpy as np
import pytest

from controllers.trajectories import cycloidal_path
from identification.excitation import predict_run, synthetic_measurements
from identification.preprocessing import (Measurements, PreprocessSettings, decimate, decimation_factor, lowpass,
                                          prepare, residual_cutoff)
from neck_sim.analytic import cable_lengths


def short_trajectory(params, move_time=1.5, hold_time=0.3):
    """Four two-sided motions with the sign patterns of §5.2.2 (about 22 s)."""
    base = np.radians([40.0, 30.0, 20.0])
    poses = [np.zeros(3)]
    for flip in range(4):
        a = base.copy()
        if flip:
            a[flip - 1] *= -1
        poses += [a, -a, np.zeros(3)]
    return cycloidal_path(poses, move_time, hold_time, name="short identification")


def predicted(params, rate=500.0, **kw):
    traj = short_trajectory(params, **kw)
    t = np.arange(0.0, traj.duration, 1.0 / rate)
    s = traj.sample(t)
    return predict_run(s.alpha, s.alpha_dot, s.alpha_ddot, t, params)


@pytest.fixture(scope="module")
def run():
    from neck_sim.params import default_params
    return predicted(default_params(3))


def test_residual_cutoff_lies_between_signal_and_noise():
    fs = 100.0
    t = np.arange(0, 60, 1 / fs)
    clean = np.sin(2 * np.pi * 0.5 * t) + 0.3 * np.sin(2 * np.pi * 1.5 * t)
    rng = np.random.default_rng(1)
    quiet = residual_cutoff(clean + 0.01 * rng.standard_normal(t.size), fs)
    noisy = residual_cutoff(clean + 0.1 * rng.standard_normal(t.size), fs)
    # keeps the 1.5 Hz component, stops well below Nyquist, and more noise pushes it down
    assert 1.5 < noisy.hz < quiet.hz < 25.0
    # the line's intercept estimates the noise rms (Winter's straight line overshoots it a little)
    assert 0.1 <= noisy.noise_rms[0] < 0.15


def test_lowpass_is_zero_phase():
    fs = 500.0
    t = np.arange(0, 10, 1 / fs)
    x = np.sin(2 * np.pi * 0.7 * t)
    y = lowpass(x, fs, 5.0)
    mid = slice(500, -500)
    assert np.max(np.abs(y[mid] - x[mid])) < 1e-3


@pytest.mark.parametrize("shape, axis, order, fs, cutoff", [((470, 3), 0, 4, 31.25, 2.3), ((3, 470), 1, 4, 31.25, 14.9),
                                                          ((2000,), 0, 2, 500.0, 5.0), ((60, 4, 2), 0, 6, 31.25, 0.4)])
def test_lowpass_is_scipys_sosfiltfilt_bit_for_bit(shape, axis, order, fs, cutoff):
    from scipy import signal

    x = np.random.default_rng(3).normal(size=shape).cumsum(axis=axis)
    sos = signal.butter(order, cutoff, btype="low", fs=fs, output="sos")
    for _ in range(2):                                  # the second call reads the cached design
        assert np.array_equal(lowpass(x, fs, cutoff, order, axis), signal.sosfiltfilt(sos, x, axis=axis))


def test_decimate_keeps_unit_gain_and_alignment():
    fs = 500.0
    t = np.arange(0, 20, 1 / fs)
    mid = slice(20, -20)
    steady = decimate(np.full(t.size, 28.0), 16)      # a motor angle far from zero
    # scipy's default even-order Chebyshev filter would lose 2.3 % (0.64 rad) here
    assert np.max(np.abs(steady[mid] - 28.0)) < 1e-6
    wave = np.sin(2 * np.pi * 0.4 * t)
    y = decimate(wave, 16)
    # sample k is input sample 16 k (no delay); the passband ripple costs < 0.1 %
    assert np.max(np.abs(y[mid] - wave[::16][mid])) < 1e-3


@pytest.mark.parametrize("shape, axis, q", [((7500, 4), 0, 16), ((3, 2000), 1, 12), ((2000,), 0, 3),
                                            ((600, 2, 3), 0, 26)])
def test_decimate_is_scipys_staged_decimate_bit_for_bit(shape, axis, q):
    """Each stage is scipy.signal.decimate with the unit-gain filter, its coefficients derived once."""
    from scipy import signal

    x = np.random.default_rng(5).normal(size=shape).cumsum(axis=axis)
    ref = x
    for f in {16: (8, 2), 12: (12,), 3: (3,), 26: (13, 2)}[q]:
        b, a = signal.cheby1(8, 0.05, 0.8 / f)
        ref = signal.decimate(ref, f, ftype=signal.dlti(b * (a.sum() / b.sum()), a), axis=axis, zero_phase=True)
    for _ in range(2):                                  # the second call reads the cached coefficients
        assert np.array_equal(decimate(x, q, axis), ref)


def test_decimation_factor_is_the_papers():
    assert decimation_factor(500.0, 30.0) == 16          # 31.25 Hz
    assert decimation_factor(500.0, 31.25) == 16
    assert decimation_factor(100.0, 30.0) == 3
    with pytest.raises(ValueError, match="prime factor"):
        decimate(np.zeros(2000), 17)


def test_prepare_recovers_elongation_and_motor_speed(run, params):
    meas = synthetic_measurements(run, params, np.random.default_rng(0), camera_noise=0.0)
    prep = prepare(meas, params, PreprocessSettings(common_bandwidth=False))
    assert prep.decimation == 16 and prep.rate_hz == pytest.approx(31.25)
    true_x = np.stack([np.interp(prep.t, run.t, run.x_c[:, i]) for i in range(4)], axis=1)
    true_td = np.stack([np.interp(prep.t, run.t, run.theta_dot[:, i]) for i in range(4)], axis=1)
    # x_c spans a few mm; quantisation and filtering leave a few micrometres
    assert np.sqrt(np.mean((prep.x_c - true_x) ** 2)) < 5e-5
    assert np.sqrt(np.mean((prep.theta_dot - true_td) ** 2)) < 0.02 * np.sqrt(np.mean(true_td ** 2))
    # eq (27) with the corrected sign: elongation = length change + wound length
    np.testing.assert_allclose(prep.x_c, cable_lengths(prep.alpha, params) + (params.actuation.r_d / params.actuation.R)
                               * prep.theta, atol=1e-12)


def test_camera_noise_chooses_a_lower_cutoff(run, params):
    quiet = prepare(synthetic_measurements(run, params, np.random.default_rng(0), camera_noise=0.0), params)
    noisy = prepare(synthetic_measurements(run, params, np.random.default_rng(0)), params)
    assert noisy.cutoffs["camera"].hz < quiet.cutoffs["camera"].hz
    assert noisy.cutoffs["common"].hz == min(noisy.cutoffs["camera"].hz, noisy.cutoffs["motors"].hz)


def test_prepare_does_not_depend_on_the_start_time(run, params):
    meas = synthetic_measurements(run, params, np.random.default_rng(3))
    shifted = Measurements(meas.t_motor + 1234.5, meas.theta, meas.force, meas.t_camera + 1234.5, meas.alpha_camera)
    a, b = prepare(meas, params), prepare(shifted, params)
    np.testing.assert_allclose(b.t - 1234.5, a.t, atol=1e-9)
    np.testing.assert_allclose(b.x_c, a.x_c, atol=1e-9)
    np.testing.assert_allclose(b.theta_ddot, a.theta_ddot, rtol=1e-6, atol=1e-9)


def test_given_cutoffs_are_used(run, params):
    meas = synthetic_measurements(run, params, np.random.default_rng(0))
    prep = prepare(meas, params, PreprocessSettings(motor_cutoff_hz=8.0, camera_cutoff_hz=2.0))
    assert prep.cutoffs["motors"].hz == 8.0 and prep.cutoffs["camera"].hz == 2.0
    assert prep.cutoffs["common"].hz == 2.0
    with pytest.raises(ValueError, match="Nyquist"):
        prepare(meas, params, PreprocessSettings(camera_cutoff_hz=20.0))


def test_bad_measurements_are_refused(run, params):
    t, th, f = run.t, run.theta, run.force
    with pytest.raises(ValueError, match="NaN"):
        Measurements(t, np.where(np.arange(t.size)[:, None] == 5, np.nan, th), f)
    with pytest.raises(ValueError, match=r"motors.force: expected shape"):
        Measurements(t, th, f[:, :3])
    with pytest.raises(ValueError, match="increase strictly"):
        Measurements(t[::-1], th, f)
    with pytest.raises(ValueError, match="both"):
        Measurements(t, th, f, t_camera=t[::16])
    gap = t.copy()
    gap[100:] += 0.5
    with pytest.raises(ValueError, match="not evenly spaced"):
        prepare(Measurements(gap, th, f), params)
    from neck_sim.params import default_params, example_params
    with pytest.raises(ValueError, match=r"motors.theta: expected shape \(\d+, 5\) for the routing's 5 cables, "
                                         r"got \(\d+, 4\)"):
        prepare(Measurements(t, th, f), default_params(4))
    # the routing, not N + 1, sets the motors' width: 4 motors fit the 10-joint, 4-cable neck, whose
    # camera must then show 10 joints
    tc = t[::16]
    cam3 = np.zeros((tc.size, 3))
    with pytest.raises(ValueError, match=rf"camera.alpha: expected shape \({tc.size}, 10\) for the routing's "
                                         rf"10 joints, got \({tc.size}, 3\)"):
        prepare(Measurements(t, th, f, tc, cam3), example_params("neck10x4"))


def test_a_replicate_reusing_the_motor_side_is_prepared_bit_for_bit(run, params):
    """The camera-noise bootstrap's replicate: new camera frames, the log's own motor arrays and motor
    cutoff.  Prepared with ``reuse`` (the motor signals taken from the log's preparation) and without
    (computed again): the same arrays, bit for bit; other motors or another cutoff are refused."""
    rng = np.random.default_rng(0)
    meas = synthetic_measurements(run, params, rng)
    prep = prepare(meas, params)
    fixed = PreprocessSettings(motor_cutoff_hz=prep.cutoffs["motors"].hz)
    other = Measurements(meas.t_motor, meas.theta, meas.force, meas.t_camera,
                         meas.alpha_camera + np.radians(1.0) * rng.standard_normal(meas.alpha_camera.shape))
    fresh = prepare(other, params, fixed)
    reused = prepare(other, params, fixed, reuse=prep)
    # the new frames moved the common bandwidth, which the reused motor signals go through again
    assert reused.cutoffs["common"].hz != prep.cutoffs["common"].hz
    assert reused.cutoffs == fresh.cutoffs
    for name in ("t", "theta", "theta_dot", "theta_ddot", "force", "alpha", "alpha_dot", "alpha_ddot", "x_c",
                 "x_c_dot", "x_c_ddot"):
        assert np.array_equal(getattr(reused, name), getattr(fresh, name)), name
    assert np.array_equal(reused.fast.theta_dot, fresh.fast.theta_dot)
    with pytest.raises(ValueError, match="same theta and force arrays"):
        prepare(Measurements(meas.t_motor, meas.theta.copy(), meas.force, meas.t_camera, meas.alpha_camera), params,
                fixed, reuse=prep)
    with pytest.raises(ValueError, match="motor cutoff"):
        prepare(other, params, PreprocessSettings(motor_cutoff_hz=0.5 * fixed.motor_cutoff_hz), reuse=prep)


def test_chain_takes_any_control_rate_signal_to_the_slow_grid(run, params):
    prep = prepare(synthetic_measurements(run, params, np.random.default_rng(0)), params)
    slow_wave = np.sin(2 * np.pi * 0.2 * run.t)[:, None] * np.array([1.0, -2.0])
    on_grid = prep.chain(slow_wave)
    assert on_grid.shape == (prep.n_samples, 2)
    np.testing.assert_allclose(on_grid, np.sin(2 * np.pi * 0.2 * prep.t)[:, None] * np.array([1.0, -2.0]), atol=2e-3)
    np.testing.assert_array_equal(prep.chain(run.force), prep.force)
