"""The sigmas ``identify`` reports cover the plant's true values at their nominal rates.

One closed-loop run of the paper's 15 s control test (law 2) on the default MuJoCo plant with a
perfect camera; 20 logs are made from it by adding the camera's Gaussian noise (1 deg per frame
and joint, drawn here) to its frames.  That is the same as 20 plant seeds: the camera noise is the
plant's only random draw and the controller never sees the camera (two plant seeds give the same
motor topics bit for bit; only the camera frames differ), so the run itself does not depend on
the seed.  Each log is identified with the calibrated sigmas (fewer bootstrap replicates than the
CLI's 40 + 20, for time: 20 at the camera's noise variance, 10 at twice it); per parameter group
the share of estimates within 1 and 2 sigma of the truth must reach MIN_1SIGMA and MIN_2SIGMA
(nominal 68 % and 95 %; set near what the benchmark measures on other seeds).  The paper's eq (50) sigmas, measured on the
same logs, must fail that bar for at least three of the four groups: the test tells the two apart.

The elastic model's k and c_a have no true value (a linear fit of a tension-dependent stiffness)
and are not checked; c_a of the variable model is not identified on this log (checked: marked so),
and most of the lambdas are.
``benchmarks/bench_coverage.py`` measures the same on more seeds and on the 85 s identification run.
"""

import numpy as np
import pytest

from neck_sim.params import default_params

pytestmark = pytest.mark.slow

SEEDS = 20
REPLICATES = 20
# measured on these seeds: 0.70-0.71 / 0.96-0.99 (f_s of the friction model, k, lambda), 1.0 / 1.0
# (f_s of the elastic model); eq (50): 0.16-0.31 / 0.42-0.56 (0.85 / 1.0 for the elastic f_s)
MIN_1SIGMA, MIN_2SIGMA = 0.65, 0.93
GROUPS = (("friction", "f_s"), ("elastic", "f_s"), ("variable", "k"), ("variable", "lambda"))


@pytest.fixture(scope="module")
def quiet_run(tmp_path_factory):
    from controllers.closed_loop import run_closed_loop
    from controllers.computed_torque import ComputedTorqueController
    from controllers.trajectories import make_trajectory
    from identification.preprocessing import Measurements
    from neck_sim.logs import read_log
    from neck_sim.plant import Plant

    p = default_params(3)
    path = tmp_path_factory.mktemp("coverage") / "control_test.mcap"
    run_closed_loop(Plant(p.replace(**{"sensors.camera_noise": 0.0}), seed=0), ComputedTorqueController(p, law=2),
                    make_trajectory("control-test", p), log_path=path, progress=False)
    return Measurements.from_log(read_log(path, topics=("motors", "camera"))), p


@pytest.fixture(scope="module")
def identified(quiet_run):
    from identification.paper import IdentificationSettings, identify
    from identification.preprocessing import Measurements, PreprocessSettings, prepare

    m, p = quiet_run
    noise = np.radians(1.0)     # the paper's camera precision, independent of params.sensors
    out, motors = [], None
    for seed in range(SEEDS):
        rng = np.random.default_rng(7000 + seed)
        noisy = Measurements(m.t_motor, m.theta, m.force, m.t_camera,
                             m.alpha_camera + noise * rng.normal(size=m.alpha_camera.shape))
        s = IdentificationSettings(reconstruct_alpha=False, bootstrap=REPLICATES, seed=seed)
        # every seed has the same motor arrays: their cutoff (residual analysis, 0.3-0.5 s) and filtered
        # signals come from the first seed's preparation (prepare's reuse: the same values bit for bit)
        if motors is None:
            prep = motors = prepare(noisy, p)
        else:
            prep = prepare(noisy, p, PreprocessSettings(motor_cutoff_hz=motors.cutoffs["motors"].hz), reuse=motors)
        out.append(identify(prep, p, s).uncertainty)
    return out, p


def _truth(p, symbol):
    return np.array({"f_s": p.friction.f_s, "k": p.cables.k, "lambda": p.cables.lam, "c_a": p.cables.c_a}[symbol])


def _coverage(runs, p, model, symbol, value, sigma):
    z = np.array([(u[model].group(value, symbol) - _truth(p, symbol)) / u[model].group(sigma, symbol) for u in runs])
    return np.mean(np.abs(z) < 1), np.mean(np.abs(z) < 2)


@pytest.mark.parametrize("model,symbol", GROUPS)
def test_calibrated_sigmas_cover_the_truth(identified, model, symbol):
    runs, p = identified
    c1, c2 = _coverage(runs, p, model, symbol, "value", "sigma")
    assert c1 >= MIN_1SIGMA and c2 >= MIN_2SIGMA, f"{model} {symbol}: coverage {c1:.2f} (1 sigma), {c2:.2f} (2 sigma)"


def test_the_papers_eq50_sigmas_fail_the_same_bar(identified):
    runs, p = identified
    failed = [g for g in GROUPS if (lambda c: c[0] < MIN_1SIGMA or c[1] < MIN_2SIGMA)(_coverage(runs, p, *g, "value_ls", "sigma_eq50"))]
    assert len(failed) >= 3, f"eq (50) passes for {set(GROUPS) - set(failed)}: the coverage bar does not discriminate"


def test_damping_is_reported_as_not_identified(identified):
    runs, _ = identified
    flags = np.array([u["variable"].group("identified", "c_a") for u in runs])
    assert not flags.any(), f"c_a marked identified in {np.count_nonzero(flags)} of {flags.size} estimates"
    # lambda(2) and lambda(3) sit near the 20 % bar on this 15 s log (86 % of the estimates pass it
    # here, 87 % over the benchmark's 30 seeds); the log never loses most of them
    ok = np.array([u["variable"].group("identified", "lambda") for u in runs])
    assert ok.mean() >= 0.8 and ok.sum(axis=1).min() >= 2, ok


def test_the_threaded_bootstrap_is_the_replicates_run_one_after_another(quiet_run):
    """The camera-noise bootstrap runs its replicates in threads: its values are, bit for bit and in
    the order drawn, those of the replicates prepared and refitted one after another here (fresh
    frames around the log's filtered camera angles, the motors' cutoff fixed, prepare's reuse)."""
    from identification.preprocessing import Measurements, PreprocessSettings, prepare
    from identification.uncertainty import camera_noise_bootstrap, refit

    m, p = quiet_run
    prep = prepare(Measurements(m.t_motor, m.theta, m.force, m.t_camera, m.alpha_camera), p)
    settings = PreprocessSettings()
    models = ("friction", "elastic")
    got = camera_noise_bootstrap(prep, p, None, weight=1.0, models=models, settings=settings, n=3, seed=5,
                                 second_order=False)
    rng = np.random.default_rng(5)
    tc, _ = prep.camera
    clean = np.stack([np.interp(tc, prep.t, prep.alpha[:, j]) for j in range(p.n_joints)], axis=1)
    fixed = PreprocessSettings(motor_cutoff_hz=prep.cutoffs["motors"].hz)
    rate = prep.motor_rate_hz / prep.decimation
    serial = []
    for _ in range(3):
        frames = clean + float(p.sensors.camera_noise) * rng.standard_normal(clean.shape)
        rep = prepare(Measurements(prep.fast.t, prep.fast.theta, prep.fast.force, tc, frames), p, fixed,
                      camera_rate_hz=rate, reuse=prep)
        serial.append(refit(rep, p, None, weight=1.0, models=models))
    for name in models:
        np.testing.assert_array_equal(got[name].at_1x, np.asarray([v[name] for v in serial]))
