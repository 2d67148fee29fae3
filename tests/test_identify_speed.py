"""The identification's fast paths against the computations they replace, bit for bit (one to rounding).

The camera-noise bootstrap repeats the camera's residual analysis, the cable kinematics and the
joint dynamics on every replicate; each has a faster form (one compiled call for all candidate
cutoffs, computing only the candidates the choice reads; one compiled pass over the samples for the
lengths, Z and Zdot; one pass for Z, M, c and g; one O(N) pass for M alpha_ddot + c + g without M,
the bootstrap's torque rows, equal to rounding).  The others must give the very numbers of the plain
computation kept here as the reference.  (That the threaded bootstrap's prepare with
``transmission=True`` equals prepare without it is held by
``test_identify_coverage.py::test_the_threaded_bootstrap_is_the_replicates_run_one_after_another``.)
"""

import numpy as np
import pytest

from identification.filtering import lowpass, residual_cutoff
from neck_sim.analytic import (bias_forces, cable_kinematics, gravity_spring_torque, mass_matrix,
                               transmission_matrix)
from neck_sim.analytic.dynamics import joint_dynamics
from neck_sim.params import default_params, example_params


def _reference_cutoff(x, fs, order=4, n_candidates=120, fit_band=(0.5, 0.95)):
    """Winter's residual analysis as written before the fast path: every candidate filtered by
    ``lowpass`` and its rms taken by numpy, then the same line fit and first crossing."""
    x = np.asarray(x, dtype=float).reshape(len(x), -1)
    nyq = 0.5 * fs
    fc = np.linspace(0.01, 0.95, n_candidates) * nyq
    res = np.stack([np.sqrt(np.mean((x - lowpass(x, fs, f, order)) ** 2, axis=0)) for f in fc])
    band = (fc >= fit_band[0] * nyq) & (fc <= fit_band[1] * nyq)
    _, intercept = np.polyfit(fc[band], res[band], 1)
    chosen = []
    for c in range(x.shape[1]):
        below = np.nonzero(res[:, c] <= intercept[c])[0]
        if below.size == 0 or intercept[c] <= 0:
            chosen.append(fc[-1])
        elif below[0] == 0:
            chosen.append(fc[0])
        else:
            i = below[0]
            r0, r1 = res[i - 1, c], res[i, c]
            w = (r0 - intercept[c]) / (r0 - r1) if r0 != r1 else 1.0
            chosen.append(fc[i - 1] + w * (fc[i] - fc[i - 1]))
    return tuple(float(v) for v in chosen), tuple(np.maximum(intercept, 0.0).tolist())


@pytest.mark.parametrize("channels, samples, fs, order", [(1, 1819, 31.25, 4), (3, 1819, 31.25, 4),
                                                         (10, 1819, 31.25, 4), (4, 6000, 500.0, 4),
                                                         (7, 400, 100.0, 2)])
def test_residual_cutoff_is_the_per_candidate_computation(channels, samples, fs, order):
    """Random walks plus noise of several levels (one channel noise-free, whose residual never
    reaches the line): the chosen cutoffs and noise levels equal the reference's exactly."""
    rng = np.random.default_rng(channels * 1000 + samples)
    x = (np.cumsum(rng.standard_normal((samples, channels)), axis=0) * 0.01
         + rng.uniform(0.0, 0.05, channels) * rng.standard_normal((samples, channels)))
    if channels > 2:
        x[:, 1] = np.sin(2 * np.pi * 0.025 * np.arange(samples))
    got = residual_cutoff(x, fs, order=order)
    chosen, noise = _reference_cutoff(x, fs, order)
    assert got.per_channel_hz == chosen
    assert got.noise_rms == noise
    assert got.hz == max(chosen)


@pytest.mark.parametrize("neck", ["paper", "neck10x4", "payload"])
def test_joint_dynamics_is_the_four_functions(neck):
    """Z, M and c with the motors, and g, in one pass: the arrays of transmission_matrix,
    mass_matrix, bias_forces and gravity_spring_torque, bit for bit, with Z and Zdot evaluated or
    taken from cable_kinematics (the bootstrap's prepare)."""
    if neck == "payload":
        p = default_params(3).replace(**{"inertia.payload_mass": 0.2})
    else:
        p = default_params(3) if neck == "paper" else example_params(neck)
    rng = np.random.default_rng(11)
    limit = 0.8 * p.geometry.alpha_max
    a = rng.uniform(-limit, limit, (257, p.n_joints))
    ad = rng.uniform(-2.0, 2.0, a.shape)
    want = (transmission_matrix(a, p), mass_matrix(a, p), bias_forces(a, ad, p), gravity_spring_torque(a, p))
    kin = cable_kinematics(a, ad, p)
    for got in (joint_dynamics(a, ad, p), joint_dynamics(a, ad, p, transmission=(kin.Z, kin.Zdot))):
        for g, w in zip(got, want):
            np.testing.assert_array_equal(g, w)


@pytest.mark.parametrize("neck", ["paper", "paper5", "neck10x4", "paper10"])
def test_cable_kinematics_of_a_series_is_the_segment_arrays(neck):
    """Lengths, Z and Zdot of a series of poses (the compiled pass over samples) equal the
    segment arrays' (``_segments`` gathered by the routing, as before), bit for bit and with the
    same memory layout (the products downstream and the lengths' sum over joints depend on it)."""
    from neck_sim.analytic import cables

    p = {"paper": default_params(3), "paper5": default_params(5), "paper10": default_params(10)}.get(neck) \
        or example_params(neck)
    rng = np.random.default_rng(5)
    a = rng.uniform(-p.geometry.alpha_max, p.geometry.alpha_max, (301, p.n_joints))
    ad = rng.uniform(-3.0, 3.0, a.shape)
    seg = cables._evaluate(a, p, (0, 1, 2))
    want = (cables._lengths(a, p, seg[0]),) + cables._z_and_dot(seg, ad, p)
    got = cable_kinematics(a, ad, p)
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)
        assert g.strides == w.strides


def test_slow_friction_basis_from_the_memo_is_the_chain_of_the_arctan():
    """The eq (37) basis on the slow grid, its control-rate part kept in the memo that a reusing
    preparation (a bootstrap replicate) shares, equals the whole chain applied to the arctan of the
    encoders' speed: on the log, on a replicate whose lower camera cutoff moves the common
    bandwidth, and for another c_s."""
    from identification.preprocessing import Measurements, PreprocessSettings, prepare
    from identification.regressors import friction_basis, slow_friction_basis

    p = default_params(3)
    rng = np.random.default_rng(2)
    t = np.arange(6000) / 500.0
    theta = np.cumsum(rng.standard_normal((t.size, 4)), axis=0) * 0.01 + 3.0 * np.sin(np.outer(t, [0.7, 1.1, 1.3, 0.5]))
    force = 20.0 + rng.standard_normal((t.size, 4))
    tc = np.arange(0.0, 12.0, 1 / 30.0)
    alpha = 0.2 * np.sin(np.outer(tc, [0.4, 0.6, 0.9]))
    log = prepare(Measurements(t, theta, force, tc, alpha), p,
                  PreprocessSettings(motor_cutoff_hz=8.0, camera_cutoff_hz=3.0))
    rep = prepare(Measurements(t, theta, force, tc, alpha + 0.001 * rng.standard_normal(alpha.shape)), p,
                  PreprocessSettings(motor_cutoff_hz=8.0, camera_cutoff_hz=2.0), reuse=log)
    assert rep.chain.common_hz != log.chain.common_hz
    other = p.replace(**{"friction.c_s": 3.0 * p.friction.c_s})
    for prep, params in ((log, p), (rep, p), (rep, p), (log, other), (rep, other)):
        want = prep.chain(friction_basis(prep.fast.theta_dot, params))
        np.testing.assert_array_equal(slow_friction_basis(prep, params), want)
    assert rep._memo is log._memo and len(log._memo) == 2


@pytest.mark.parametrize("neck", ["paper", "neck10x4", "mirrored3", "payload"])
def test_inverse_dynamics_is_m_alpha_ddot_plus_c_plus_g(neck):
    """tau of the O(N) pass (the bodies' forces carried down the chain, no M) equals M alpha_ddot + c + g of
    joint_dynamics (M formed) on random poses, speeds and accelerations, to 1e-14 of the largest
    term (5e-16 achieved), with Z and Zdot evaluated or taken from cable_kinematics."""
    from neck_sim.analytic.dynamics import inverse_dynamics

    p = default_params(3).replace(**{"inertia.payload_mass": 0.2}) if neck == "payload" else \
        default_params(3) if neck == "paper" else example_params(neck)
    rng = np.random.default_rng(7)
    limit = 0.8 * p.geometry.alpha_max
    a = rng.uniform(-limit, limit, (301, p.n_joints))
    ad = rng.uniform(-2.0, 2.0, a.shape)
    add = rng.uniform(-20.0, 20.0, a.shape)
    dyn = joint_dynamics(a, ad, p)
    want = np.einsum("sij,sj->si", dyn.M, add) + dyn.c + dyn.g
    scale = np.abs(np.einsum("sij,sj->sij", dyn.M, add)).max() + np.abs(dyn.c).max() + np.abs(dyn.g).max()
    kin = cable_kinematics(a, ad, p)
    for got in (inverse_dynamics(a, ad, add, p), inverse_dynamics(a, ad, add, p, transmission=(kin.Z, kin.Zdot))):
        assert got.shape == want.shape
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-14 * scale)
    # the batch axes are kept and a single sample works
    np.testing.assert_allclose(inverse_dynamics(a[5], ad[5], add[5], p), want[5], rtol=0, atol=1e-14 * scale)


def test_torque_rows_from_joint_torques_are_those_from_joint_dynamics():
    """The bootstrap's torque rows (Z and tau = M alpha_ddot + c + g of the O(N) pass) equal those
    of the joint dynamics with M, on a prepared log of the 10-joint, 4-cable neck with and without
    the cable kinematics kept by prepare: W bit for bit, Y to 1e-14 of its largest entry."""
    from identification.preprocessing import Measurements, PreprocessSettings, prepare
    from identification import regressors as reg

    p = example_params("neck10x4")
    rng = np.random.default_rng(3)
    t = np.arange(4000) / 500.0
    theta = 3.0 * np.sin(np.outer(t, [0.7, 1.1, 1.3, 0.5])) + 0.01 * rng.standard_normal((t.size, 4))
    force = 20.0 + rng.standard_normal((t.size, 4))
    tc = np.arange(0.0, 8.0, 1 / 30.0)
    alpha = 0.1 * np.sin(np.outer(tc, np.linspace(0.4, 1.3, p.n_joints)))
    settings = PreprocessSettings(motor_cutoff_hz=8.0, camera_cutoff_hz=3.0)
    for kept in (False, True):
        prep = prepare(Measurements(t, theta, force, tc, alpha), p, settings, transmission=kept)
        assert (prep.transmission_for(p) is not None) == kept
        torques, dyn = reg.joint_torques(prep, p), reg.joint_dynamics(prep, p)
        for model in (lambda d: reg.friction_model(prep, p, d), lambda d: reg.elastic_model(prep, p, dyn=d)):
            got, want = model(torques), model(dyn)
            np.testing.assert_array_equal(got.W, want.W)
            np.testing.assert_allclose(got.Y, want.Y, rtol=0, atol=1e-14 * np.abs(want.Y).max())


@pytest.mark.parametrize("neck", ["paper", "neck10x4"])
def test_refit_is_identify_on_the_same_preparation(neck):
    """A bootstrap replicate's values (``refit``: torques of the O(N) pass, normal equations of W)
    are identify's least-squares values (M formed, lstsq's SVD) on one prepared log with its slack
    mask, per model to 1e-10 of the largest |value| (3e-11 achieved: the variable-stiffness
    model's scaled condition number is 270-480 on this log)."""
    from identification.paper import IdentificationSettings, identify
    from identification.preprocessing import Measurements, PreprocessSettings, prepare
    from identification.uncertainty import refit

    p = default_params(3) if neck == "paper" else example_params(neck)
    rng = np.random.default_rng(3)
    t = np.arange(4000) / 500.0
    m = p.n_cables
    theta = 3.0 * np.sin(np.outer(t, np.linspace(0.5, 1.3, m))) + 0.01 * rng.standard_normal((t.size, m))
    force = 20.0 + rng.standard_normal((t.size, m))
    tc = np.arange(0.0, 8.0, 1 / 30.0)
    alpha = 0.1 * np.sin(np.outer(tc, np.linspace(0.4, 1.3, p.n_joints)))
    prep = prepare(Measurements(t, theta, force, tc, alpha), p,
                   PreprocessSettings(motor_cutoff_hz=8.0, camera_cutoff_hz=3.0), transmission=True)
    s = IdentificationSettings(bootstrap=0, reconstruct_alpha=False)
    res = identify(prep, p, s)
    got = refit(prep, p, res.series["taut"], weight=s.weight, models=("elastic", "variable"))
    assert set(got) == {"friction", "elastic", "variable"}
    for name, values in got.items():
        want = getattr(res, name).value
        np.testing.assert_allclose(values, want, rtol=0, atol=1e-10 * np.abs(want).max(), err_msg=name)
