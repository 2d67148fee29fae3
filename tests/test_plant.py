"""The simulated prototype: API, sensors, callbacks (process-global), dynamics (against the analytic model), effects."""

import ctypes
import gc
import subprocess

import mujoco
import numpy as np
import pytest

import neck_sim.analytic as an
from neck_sim import effects as E
from neck_sim import plant as P
from neck_sim.native import DISPATCH, log_warning
from neck_sim.mjcf import build_xml
from neck_sim.params import default_params

F = np.array([25.0, 22.0, 20.0, 30.0])
A0 = np.radians([20.0, -10.0, 15.0])


def run(plant, steps, forces=F, alpha0=A0):
    plant.reset(alpha0)
    out = []
    for _ in range(steps):
        plant.step(forces)
        out.append(plant.truth())
    return out


def test_api_shapes_time_and_truth(params):
    pl = P.Plant(params)
    assert pl.time == 0.0 and pl.params is params and pl.effects == E.Effects()
    assert pl.xml == build_xml(params, timestep=pl.timestep)
    tr = pl.truth()
    assert isinstance(tr, P.Truth)
    assert [np.shape(x) for x in tr[:-1]] == [(3,), (3,), (4,), (4,), (4,), (4,)]
    pl.step(F)
    pl.step(F)
    assert pl.time == pytest.approx(2 / params.control.rate_hz)
    assert pl.encoders().shape == (4,)
    assert 0 < pl.truth().loop_gap < 1e-4


def test_forces_are_checked_and_clipped(params):
    pl = P.Plant(params)
    for bad, match in ((np.array([1.0, np.nan, 1, 1]), "NaN"), (np.ones(3), r"shape \(4,\)"),
                       (np.ones((4, 1)), "4 numbers"), ([1, 2, np.inf, 3], "NaN or infinity"), ("abcd", "numbers")):
        with pytest.raises(ValueError, match=match):
            pl.step(bad)
    assert pl.time == 0.0
    over = run(pl, 50, forces=np.array([250.0, -5.0, 20.0, 1e4]))[-1]
    at_limits = run(P.Plant(params), 50, forces=np.array([100.0, 0.0, 20.0, 100.0]))[-1]
    np.testing.assert_array_equal(over.alpha, at_limits.alpha)


def test_reset_pose_zero_elongation_and_bad_poses(params):
    pl = P.Plant(params)
    run(pl, 20)
    pl.reset(A0)
    tr = pl.truth()
    assert pl.time == 0.0
    np.testing.assert_allclose(tr.alpha, A0, atol=1e-14)
    np.testing.assert_allclose(tr.elongation, 0.0, atol=1e-12)
    np.testing.assert_allclose(tr.tension, 0.0, atol=1e-8)
    np.testing.assert_allclose(tr.theta, an.motor_angles_rigid(A0, params), atol=1e-12)
    for bad, match in ((np.zeros(2), "shape"), ([0, np.nan, 0], "NaN"), (np.radians([95, 0, 0]), "joint range")):
        with pytest.raises(ValueError, match=match):
            pl.reset(bad)


def test_elongation_follows_the_sign_convention(params):
    """Truth x_c = l_c(alpha) - l_c0 + (r_d/R) theta (analytic/cables.py), while moving, up to
    the soft loop closure (the cables run over the bars, which sit within a loop gap of the
    closed-form pose)."""
    pl = P.Plant(params)
    trs = run(pl, 1000)
    for tr in trs[::50]:
        x = an.elongation(tr.theta, tr.alpha, params)
        np.testing.assert_allclose(tr.elongation, x, rtol=0, atol=5 * tr.loop_gap + 1e-9)
    settled = trs[-1]                                  # x_dot ~ 0: tension = eq (54) of the elongation
    np.testing.assert_allclose(settled.tension, an.cable_tension(settled.elongation, np.zeros(4), params), atol=0.05)
    assert np.all(settled.tension > 5.0)
    # winding motor 1 alone (right cable of joint 1) bends joint 1 to the right (alpha_1 < 0)
    tr = run(pl, 100, forces=np.array([60.0, 5, 5, 5]), alpha0=np.zeros(3))[-1]
    assert tr.alpha[0] < np.radians(-5) and tr.theta[0] > 0


def test_encoders_are_quantised(params):
    pl = P.Plant(params)
    run(pl, 30)
    res = params.sensors.encoder_resolution
    enc, theta = pl.encoders(), pl.truth().theta
    np.testing.assert_allclose(enc / res, np.round(enc / res), atol=1e-9)
    assert np.all(np.abs(enc - theta) <= res / 2 + 1e-12)
    assert not np.allclose(enc, theta, atol=1e-9, rtol=0)


def test_camera_rate_noise_and_seed(params):
    pl = P.Plant(params, seed=3)
    pl.reset(A0)
    frames, truth_at = [], {}
    for _ in range(500):                               # 1 s
        pl.step(F)
        fr = pl.camera_frame()
        if fr is not None:
            frames.append(fr)
            truth_at[fr[0]] = pl.truth().alpha
    t = np.array([f[0] for f in frames])
    assert len(frames) == 30
    np.testing.assert_allclose(t, np.arange(1, 31) / 30.0, atol=pl.timestep)
    assert pl.camera_frame() is None or pl.camera_frame()[0] == t[-1]
    pl.reset(A0)
    again = []
    for _ in range(500):
        pl.step(F)
        if pl.camera_frame() is not None:
            again.append(pl.camera_frame()[1])
    np.testing.assert_array_equal(np.array(again), np.array([f[1] for f in frames]))   # reseeded


def test_camera_noise_level(params):
    pl = P.Plant(params, seed=11)
    pl.reset(np.zeros(3))
    errs = []
    for _ in range(3000):                              # 6 s, 180 frames
        pl.step(np.full(4, 15.0))
        fr = pl.camera_frame()
        if fr is not None:
            # frames are taken at the end of a sub-step inside the period: compare to the
            # nearly-static neck at the period's end
            errs.append(fr[1] - pl.truth().alpha)
    sd = np.std(np.array(errs))
    assert len(errs) == 180
    assert abs(sd - params.sensors.camera_noise) < 0.15 * params.sensors.camera_noise


def test_two_plants_do_not_see_each_others_parameters(params):
    soft = params.replace(**{"cables.k": (2000.0,) * 4, "friction.f_s": (5.0,) * 4})
    alone_a = [tr.alpha for tr in run(P.Plant(params), 100)]
    alone_b = [tr.alpha for tr in run(P.Plant(soft), 100)]
    a, b = P.Plant(params), P.Plant(soft)
    a.reset(A0)
    b.reset(A0)
    inter_a, inter_b = [], []
    for _ in range(100):
        a.step(F)
        b.step(F)
        inter_a.append(a.truth().alpha)
        inter_b.append(b.truth().alpha)
    np.testing.assert_array_equal(inter_a, alone_a)
    np.testing.assert_array_equal(inter_b, alone_b)
    assert np.abs(np.array(alone_a) - np.array(alone_b)).max() > 1e-3


PENDULUM = """<mujoco><option timestep="0.002"/><worldbody><body pos="0 0 1"><joint name="h" axis="0 1 0"/>
<geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02"/></body></worldbody>
<actuator><general joint="h" biastype="affine" biasprm="0 -3 -0.1"/></actuator></mujoco>"""


def _pendulum_run():
    m = mujoco.MjModel.from_xml_string(PENDULUM)
    d = mujoco.MjData(m)
    d.qpos[0] = 0.5
    mujoco.mj_step(m, d, 300)
    return d.qpos.copy(), m.actuator_biasprm[0, :3].copy()


@pytest.mark.parametrize("backend", ["native", "python"])
def test_a_plain_model_still_works_after_a_plant(params, backend):
    previous = P.get_backend() or "native"
    try:
        mujoco.set_mjcb_control(None)
        reference = _pendulum_run()
        P.set_backend(backend)
        pl = P.Plant(params)
        run(pl, 5)
        after = _pendulum_run()                      # compiled and stepped with the plant alive
        np.testing.assert_array_equal(after[0], reference[0])
        np.testing.assert_array_equal(after[1], [0, -3, -0.1])
        run(pl, 5)
    finally:
        P.set_backend(previous)


def test_native_and_python_backends_agree(params):
    if not P.native_available():
        pytest.skip("no C compiler: only the Python backend exists here")
    eff = E.Effects.of(E.ViscousFriction(0.2, cables=(0, 3)), E.StribeckFriction(df=3.0),
                       E.PulleyFriction(mu=0.1), E.Pretension(5e-4, cables=(1,)))
    previous = P.get_backend()
    out = {}
    try:
        for b in ("native", "python"):
            P.set_backend(b)
            out[b] = np.array([tr.alpha for tr in run(P.Plant(params, effects=eff), 60)])
    finally:
        P.set_backend(previous)
    np.testing.assert_allclose(out["native"], out["python"], rtol=0, atol=1e-10)


def test_native_force_laws_are_the_definitions(params, rng):
    if not P.native_available():
        pytest.skip("no C compiler")
    eff = E.Effects.of(E.ViscousFriction(0.3, cables=(1, 3)), E.StribeckFriction(df=4.0, speed=3.0, smoothing=0.7),
                       E.PulleyFriction(mu=(0.1, 0.2), cables=(0, 2)))
    pl = P.Plant(params, effects=eff, backend="native")
    lib = DISPATCH.lib
    out = (ctypes.c_double * 2)()
    for _ in range(400):
        j = int(rng.integers(4))
        x = rng.choice([rng.uniform(-1e-3, 0.02), rng.uniform(0, 0.3)])   # slack, taut, beyond t_cap
        xd = rng.normal(0, 0.3)
        lib.neck_tension(ctypes.byref(pl._c), j, x, xd, out)
        xa, xda = np.zeros(4), np.zeros(4)
        xa[j], xda[j] = x, xd
        assert out[0] == pytest.approx(an.cable_tension(xa, xda, params)[j], rel=1e-12, abs=1e-12)
        w, t = rng.normal(0, 20), rng.uniform(0, 100)
        lib.neck_friction(ctypes.byref(pl._c), j, w, t, out)
        wa, ta = np.zeros(4), np.zeros(4)
        wa[j], ta[j] = w, t
        expect = an.motor_friction(wa, params) + sum(e.motor_force(wa, ta) for e in eff.motor_effects())
        assert out[0] == pytest.approx(expect[j], rel=1e-12, abs=1e-12)
        h = 1e-6
        fd = (an.motor_friction(wa + h, params) - an.motor_friction(wa - h, params)
              + sum(e.motor_force(wa + h, ta) - e.motor_force(wa - h, ta) for e in eff.motor_effects())) / (2 * h)
        assert out[1] == pytest.approx(fd[j], rel=1e-6, abs=1e-6)


def test_ctypes_mirror_has_the_c_layout(tmp_path):
    """PlantStruct (generated from the C text) against the C compiler's own sizeof/offsetof."""
    if not P.native_available():
        pytest.skip("no C compiler")
    from neck_sim import native
    fields = [name for name, _ in native.PlantStruct._fields_]
    assert fields[:3] == ["ncable", "rigid", "njoint"] and "loop_gap" in fields and len(fields) > 30
    prog = tmp_path / "layout.c"
    prog.write_text(f'#include <stdio.h>\n#include <stddef.h>\n#include "{native.SOURCE_PATH}"\n'
                    'int main(void) {\n  printf("%zu\\n", sizeof(neck_plant));\n'
                    + "".join(f'  printf("%zu\\n", offsetof(neck_plant, {f}));\n' for f in fields) + "}\n")
    exe = tmp_path / "layout"
    subprocess.run([native.compiler(), "-I", native.mujoco_include_dir(), str(prog), "-o", str(exe),
                    *native.link_flags()],
                   check=True, capture_output=True)
    c_layout = [int(v) for v in subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout.split()]
    py_layout = [ctypes.sizeof(native.PlantStruct)] + [getattr(native.PlantStruct, f).offset for f in fields]
    assert py_layout == c_layout
    assert native.PlantStruct.tension.size == ctypes.sizeof(ctypes.c_double) * P.MAX_CABLES


def test_dead_plants_leave_the_registry(params):
    if not P.native_available():
        pytest.skip("no C compiler")
    previous = P.get_backend()
    try:
        P.set_backend("native")
        gc.collect()
        before = DISPATCH.lib.neck_registered()
        pl = P.Plant(params)
        assert DISPATCH.lib.neck_registered() == before + 1
        del pl
        gc.collect()
        assert DISPATCH.lib.neck_registered() == before
    finally:
        P.set_backend(previous)


def test_a_foreign_control_callback_is_reported(params):
    pl = P.Plant(params)
    saved = mujoco.get_mjcb_control()
    try:
        mujoco.set_mjcb_control(lambda m, d: None)
        with pytest.raises(RuntimeError, match="mjcb_control"):
            pl.step(F)
    finally:
        mujoco.set_mjcb_control(saved)
    pl.step(F)


def test_bad_construction_arguments(params):
    with pytest.raises(ValueError, match="timestep"):
        P.Plant(params, timestep=3e-4)
    with pytest.raises(ValueError, match="backend"):
        P.Plant(params, backend="gpu")
    with pytest.raises(ValueError, match="pretension.cables"):
        P.Plant(params, effects=E.Effects.of(E.Pretension(1e-3, cables=(7,))))
    with pytest.raises(ValueError, match="effects"):
        P.Plant(params, effects={"payload": 0.1})


# ------------------------------------------------------------------------- item 5: dynamics

def test_constant_antagonistic_forces_keep_the_loops_closed_for_10_s(params):
    pl = P.Plant(params)
    pl.reset(A0)
    gap, finite = 0.0, True
    for _ in range(5000):
        pl.step(F)
        tr = pl.truth()
        gap = max(gap, tr.loop_gap)
        finite &= bool(np.all(np.isfinite(tr.tension)))
    assert finite and gap < 1e-4
    assert np.all(np.abs(tr.alpha_dot) < 0.05)           # it settled


@pytest.fixture(scope="module")
def analytic_free_response():
    p = default_params(3)
    return an.simulate_elastic(A0, an.motor_angles_rigid(A0, p), lambda t: F, 0.05, p, sample_dt=0.002)


def test_free_response_matches_the_analytic_model(params, analytic_free_response):
    """Over the violent first 50 ms (bars snapping onto suddenly tensioned cables, where the
    whole first-second error is made) the plant is within 0.3 deg of eqs 29-30 and converges at
    first order in the timestep.  ``neck-sim crossval --dynamics`` runs the full second."""
    _, ref = analytic_free_response
    errs = []
    for dt in (5e-4, 2.5e-4):
        trs = run(P.Plant(params, timestep=dt), 25)
        alpha = np.array([A0] + [tr.alpha for tr in trs])
        theta = np.array([an.motor_angles_rigid(A0, params)] + [tr.theta for tr in trs])
        errs.append(np.abs(alpha - ref.alpha).max())
        assert np.abs(theta - ref.theta).max() < 0.05
    assert np.degrees(errs[0]) < 0.3
    assert errs[1] < 0.6 * errs[0]


def test_rigid_cables_match_the_rigid_model(params):
    t, alpha, _ = an.simulate_rigid(A0, lambda t: F, 0.1, params, sample_dt=0.002)
    trs = run(P.Plant(params, rigid_cables=True), 50)
    got = np.array([A0] + [tr.alpha for tr in trs])
    assert np.degrees(np.abs(got - alpha).max()) < 0.01
    assert max(np.abs(tr.elongation).max() for tr in trs) < 1e-5
    # tensions are the constraint forces: at rest they balance the commanded force minus friction
    assert np.all(np.abs(trs[-1].tension - F) <= np.asarray(params.friction.f_s) + 1.0)


# ------------------------------------------------------------------------------- effects

def test_pretension_is_invisible_to_the_encoders(params):
    eff = E.Effects.of(E.Pretension(1e-3, cables=(0, 3)))
    pl = P.Plant(params, effects=eff)
    pl.reset(np.zeros(3))
    tr = pl.truth()
    np.testing.assert_allclose(tr.elongation, [1e-3, 0, 0, 1e-3], atol=1e-12)
    np.testing.assert_allclose(tr.tension, an.cable_tension(tr.elongation, np.zeros(4), params))
    np.testing.assert_array_equal(pl.encoders(), 0.0)


def test_actuation_delay(params):
    """A delay of m control periods equals commanding the same forces m periods later."""
    f0, f1 = np.full(4, 15.0), np.array([40.0, 10, 10, 20])

    def history(plant, cmds):
        plant.reset(np.zeros(3))
        out = []
        for f in cmds:
            plant.step(f)
            out.append(plant.truth().alpha)
        return np.array(out)

    cmds = [f0] * 20 + [f1] * 40
    late = lambda m: [f0] * (20 + m) + [f1] * (40 - m)          # noqa: E731
    d3 = history(P.Plant(params, effects=E.Effects.of(E.ActuationDelay(delay=0.006))), cmds)   # 3 periods
    np.testing.assert_array_equal(d3, history(P.Plant(params), late(3)))
    # 2.5 periods: the force switches in the middle of a period, between the two
    half = history(P.Plant(params, effects=E.Effects.of(E.ActuationDelay(delay=0.005))), cmds)
    late2 = history(P.Plant(params), late(2))
    np.testing.assert_array_equal(half[:22], late2[:22])
    assert np.abs(half[22] - late2[22]).max() > 1e-9 and np.abs(half[23] - d3[23]).max() > 1e-9
    lo, hi = np.minimum(late2[30], d3[30]), np.maximum(late2[30], d3[30])
    assert np.all((half[30] >= lo - 1e-9) & (half[30] <= hi + 1e-9))


def test_parameter_effects_reach_the_true_plant(params):
    eff = E.Effects.of(E.Payload(0.05), E.SpringError(stiffness_scale=1.5, joints=(0,)))
    pl = P.Plant(params, effects=eff)
    assert pl.params.inertia.payload_mass == 0.0                 # the nominal constants stay nominal
    assert pl.true_params.inertia.payload_mass == pytest.approx(0.05)
    m = pl.model
    top = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "j3_top")
    assert m.body_mass[top] == pytest.approx(params.inertia.bar_mass + 0.05)
    spring = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_TENDON, "j1_spring_right")
    assert m.tendon_stiffness[spring] == pytest.approx(1.5 * params.springs.stiffness[0])
    plain = run(P.Plant(params), 100)[-1]
    loaded = run(pl, 100)[-1]
    assert np.abs(loaded.alpha - plain.alpha).max() > np.radians(0.1)


def test_dry_friction_override_equals_the_parameter_change(params):
    a = run(P.Plant(params, effects=E.Effects.of(E.DryFriction(f_s=2.0))), 60)[-1]
    b = run(P.Plant(params.replace(**{"friction.f_s": (2.0,) * 4})), 60)[-1]
    np.testing.assert_array_equal(a.alpha, b.alpha)


@pytest.mark.parametrize("effect", [E.ViscousFriction(0.3), E.StribeckFriction(df=8.0), E.PulleyFriction(0.3)])
def test_motor_friction_effects_change_the_motion(params, effect):
    base = run(P.Plant(params), 100)[-1]
    other = run(P.Plant(params, effects=E.Effects.of(effect)), 100)[-1]
    assert np.abs(other.theta - base.theta).max() > 1e-3


def test_rigid_cables_refuse_cable_effects(params):
    with pytest.raises(ValueError, match="pretension"):
        P.Plant(params, effects=E.Effects.of(E.Pretension(1e-3)), rigid_cables=True)


@pytest.mark.parametrize("n", [1, 5])
def test_other_neck_lengths_run(n):
    p = default_params(n)
    pl = P.Plant(p)
    pl.reset(np.radians(np.linspace(-10, 10, n)))
    for _ in range(200):
        pl.step(np.full(n + 1, 20.0))
    tr = pl.truth()
    assert tr.alpha.shape == (n,) and tr.tension.shape == (n + 1,)
    assert tr.loop_gap < 1e-4 and np.all(np.isfinite(tr.alpha)) and np.all(tr.tension > 0)


def test_divergence_is_an_error_not_a_silent_reset(tmp_path, monkeypatch):
    """Bang-bang forces drive the neck past its range: MuJoCo resets its state, the plant says so."""
    monkeypatch.chdir(tmp_path)
    plant = P.Plant()
    plant.reset()
    # ours, or one installed earlier by someone else (dm_control installs its own): never MuJoCo's default
    assert mujoco.get_mju_user_warning() is not None
    with pytest.raises(P.PlantDivergedError, match="diverged"):
        for _ in range(5000):
            plant.step([100.0, 2.0, 2.0, 2.0])
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
    with pytest.raises(P.PlantDivergedError):
        plant.step([10.0] * 4)                       # still broken until reset
    plant.reset()
    plant.step([10.0] * 4)


def test_mujoco_warnings_go_to_logging(caplog):
    with caplog.at_level("DEBUG", logger="neck_sim.mujoco"):
        log_warning("Nan, Inf or huge value in QACC at DOF 0.\n")
        log_warning("Pre-allocated constraint buffer is full.")
    levels = [(r.levelname, r.getMessage()) for r in caplog.records]
    # fatal ones become PlantDivergedError (quoting them), so they are only debug output here
    assert levels == [("DEBUG", "MuJoCo: Nan, Inf or huge value in QACC at DOF 0."),
                      ("WARNING", "MuJoCo: Pre-allocated constraint buffer is full.")]
