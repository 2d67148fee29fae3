"""One contract over every registered effect (as dm_control's domains_test runs one over every domain).

For each effect of :mod:`neck_sim.effects`:

* a motor force is magnitude x regressor on random states;
* where the effect is in the native kernel, the C callback gives the Python reference;
* fitted values -> plant data (``to_plant``) -> the forces the plant's physics give (eqs 29, 30,
  37, 54 written here from :mod:`neck_sim.analytic`) equal the fit's regressor columns x values;
* names and units are non-empty and survive JSON; the default shape lies inside its grid;
* the sign check rejects a clearly wrong-signed fit of a signed column and accepts a right one.
"""

from __future__ import annotations

import ctypes
import json
import types

import numpy as np
import pytest

import neck_sim.analytic as an
from neck_sim import effects as E
from neck_sim import plant as P
from neck_sim.native import DISPATCH
from neck_sim.params import default_params, example_params

from identification.candidates import FitContext
from identification.measured import MeasuredData

EFFECTS = E.registered()
MOTOR = [c for c in EFFECTS if c.kind == "motor"]
NATIVE = [c for c in MOTOR if c.baseline or c().native_fields(4) is not None]
WITH_COLUMNS = [c for c in EFFECTS if c.columns and c.columns_exact]
SIGNED = [c for c in EFFECTS if any(col.signed for col in c.columns)]


def ids(classes):
    return [c.name for c in classes]


def _shape(cls, rng):
    """A shape other than the default: a grid point for searched shapes, an offset on cable 2."""
    out = {}
    for sh in cls.shapes:
        if sh.per_cable:
            out[f"{sh.name}_2"] = float(rng.uniform(*sh.bounds))
        else:
            out[sh.name] = float(rng.choice(sh.grid)) if sh.grid else sh.default
    return out


def _magnitudes(cls, rng, n, m):
    out = {}
    for col in cls.columns:
        count = len(col.names(n, m))
        lo = 0.05                     # inside what to_plant keeps (it clips unphysical values)
        scale = {"N/m": 3000.0, "N s/m": 50.0, "kg": 0.05, "N": 8.0}.get(col.unit, 0.2)
        out[col.symbol] = scale * rng.uniform(lo, 1.0, count)
    return out


@pytest.mark.parametrize("cls", MOTOR, ids=ids(MOTOR))
def test_motor_force_is_magnitude_times_regressor(cls, rng):
    td = rng.normal(0, 20, (40, 4))
    t = rng.uniform(0, 80, (40, 4))
    mag = rng.uniform(0.1, 3.0, 4)
    shape = _shape(cls, rng)
    eff = cls(**{cls.magnitude_field: tuple(mag)}, **shape)
    np.testing.assert_allclose(eff.motor_force(td, t), mag * cls.unit(shape).regressor(td, t), rtol=1e-13, atol=1e-13)
    one = cls(**{cls.magnitude_field: 2.0, "cables": (1,)}, **shape)
    np.testing.assert_array_equal(one.motor_force(td, t)[:, [0, 2, 3]], 0.0)


@pytest.mark.parametrize("cls", NATIVE, ids=ids(NATIVE))
def test_native_kernel_is_the_python_reference(cls, params, rng):
    if not P.native_available():
        pytest.skip("no C compiler")
    mag = rng.uniform(0.1, 3.0, 4)
    eff = cls(**{cls.magnitude_field: tuple(mag)}, **_shape(cls, rng))
    pl = P.Plant(params, effects=E.Effects.of(eff), backend="native")
    lib, out = DISPATCH.lib, (ctypes.c_double * 2)()
    for _ in range(100):
        j = int(rng.integers(4))
        w, t = rng.normal(0, 20), rng.uniform(0, 100)
        lib.neck_friction(ctypes.byref(pl._c), j, w, t, out)
        wa, ta = np.full(4, w), np.full(4, t)
        expect = an.motor_friction(wa, pl.true_params) + sum(e.motor_force(wa, ta) for e in pl.effects.motor_effects())
        assert out[0] == pytest.approx(expect[j], rel=1e-12, abs=1e-12)


def _fake_data(params, rng, S=60):
    """What an effect's ``design`` reads from MeasuredData, on random states (no filter: to_slow = identity)."""
    n, C = params.n_joints, params.n_cables
    alpha = rng.uniform(-0.4, 0.4, (S, n))
    d = types.SimpleNamespace(
        S=S, n=n, C=C, params=params, alpha=alpha,
        prep=types.SimpleNamespace(alpha_dot=rng.normal(0, 1, (S, n)), alpha_ddot=rng.normal(0, 5, (S, n))),
        Z=an.transmission_matrix(alpha, params), x=rng.uniform(1e-3, 3e-3, (S, C)), x_dot=rng.normal(0, 5e-4, (S, C)),
        theta_dot_fast=rng.normal(0, 20, (S, C)), to_slow=lambda v: v, _col_cache={})
    d.cached = types.MethodType(MeasuredData.cached, d)
    d.motor_basis = types.MethodType(MeasuredData.motor_basis, d)
    return d


def _observations(d, params, effects, elastic, nominal):
    """Cable block y_C = f_motor + t (N) and torque block Z f_motor + linkage change (N m) of the
    plant's physics: eq (37) + motor effects at the data's motor speed, eq (54) tension at the
    data's elongation (plus rest elongations), linkage eq (30) against the nominal one."""
    w = d.theta_dot_fast
    C = d.C
    x = d.x + effects.elongation_offset(C)
    t = an.cable_tension(x, d.x_dot, params) if elastic else np.zeros_like(x)
    f = an.motor_friction(w, params) + sum((e.motor_force(w, t) for e in effects.motor_effects()), np.zeros_like(w))
    lk, lk0 = (an.linkage_dynamics(d.alpha, d.prep.alpha_dot, p) for p in (params, nominal))
    dl = np.einsum("sij,sj->si", lk.M - lk0.M, d.prep.alpha_ddot) + (lk.c - lk0.c) + (lk.g - lk0.g)
    dl = dl + _mujoco_spring_torque(d.alpha, params, effects) - _mujoco_spring_torque(d.alpha, params, E.Effects())
    return f + t, np.einsum("sij,sj->si", d.Z, f) + dl, t


def _mujoco_spring_torque(alpha, params, effects):
    """(S, N) N m the cables must add against MuJoCo's passive tendon springs at the poses alpha
    (S, N), with the effects' MuJoCo edits (``setup_mujoco``): minus qfrc_spring projected on alpha
    by virtual work (hinge speeds per alpha_dot of the closed-form pose, helpers alpha/2)."""
    import mujoco

    from neck_sim.mjcf import pose_qpos

    pl = P.Plant(params, effects=effects)
    m, dd, ix = pl.model, pl.data, pl._ix
    out = np.zeros_like(alpha)
    for s, a in enumerate(alpha):
        pq = pose_qpos(a, params)
        dd.qpos[ix.qpos_A], dd.qpos[ix.qpos_B], dd.qpos[ix.qpos_D] = pq.q_A, pq.q_B, pq.q_D
        dd.qpos[ix.qpos_helper] = pq.q_helper
        mujoco.mj_forward(m, dd)
        q = dd.qfrc_spring
        tau = pq.dq_A * q[ix.dof_A] + pq.dq_B * q[ix.dof_B] + pq.dq_D * q[ix.dof_D]
        np.add.at(tau, ix.helper_joint, pq.dq_helper * q[ix.dof_helper])
        out[s] = -tau
    return out


@pytest.mark.parametrize("neck", ["paper", "neck10x4"])
@pytest.mark.parametrize("cls", WITH_COLUMNS, ids=ids(WITH_COLUMNS))
def test_fitted_values_to_plant_give_the_columns_forces(cls, neck, rng):
    """design(...) @ values == plant physics(to_plant(values)) - plant physics(without the effect),
    on the paper's neck and on the 10-joint, 4-cable one (columns sized by the routing)."""
    p = example_params(neck)
    n, m = p.n_joints, p.n_cables
    # linear cables in the nominal model, so that each cable effect alone is linear (eq 54, lambda = 0)
    nominal = p.replace(**{"cables.lam": (0.0,) * m, "cables.t_cap": 1e4})
    d = _fake_data(nominal, rng)
    shape, values = _shape(cls, rng), _magnitudes(cls, rng, n, m)
    base = nominal
    for other in E.registered():            # without: no friction, rigid cables unless this adds to them
        if other is not cls and other.baseline and other.name not in cls.requires:
            base = other.when_absent(base, True)
    base = cls.when_absent(base, True)
    params, extra = cls.to_plant(base, values, shape)
    with_eff = E.Effects.of(extra) if extra is not None else E.Effects()
    yC1, yT1, t1 = _observations(d, params, with_eff, True, nominal)
    # without the effect: the same plant, rigid cables when the effect is what makes them elastic
    yC0, yT0, _ = _observations(d, base, E.Effects(), not cls.elastic_cables, nominal)
    design = cls.design(d, shape, FitContext(d.x, t1, t1))
    v = np.concatenate([np.ravel(values[col.symbol]) for col in cls.columns])
    np.testing.assert_allclose(design.cable @ v, yC1 - yC0, rtol=1e-9, atol=1e-9 * np.abs(yC1).max())
    np.testing.assert_allclose(design.torque @ v, yT1 - yT0, rtol=1e-9, atol=1e-9 * np.abs(yT1).max())


def test_shifting_effects_reach_the_plant_as_fitted(rng):
    """Effects without columns: the rest elongations and the delay the fit uses are the plant's."""
    shifting = [c for c in EFFECTS if not c.columns]
    assert {c.kind for c in shifting} >= {"elongation", "command", "camera", "encoder"}
    for cls in shifting:
        shape = _shape(cls, rng)
        params, eff = cls.to_plant(default_params(3), {}, shape)
        assert eff is not None and params == default_params(3)
        np.testing.assert_array_equal(eff.elongation_offset(4), cls.fit_elongation_offset(shape, 4))
        assert eff.command_delay == cls.fit_delay(shape)
        assert eff.camera_delay == cls.fit_camera_shift(shape)
        band = eff.encoder_band(4)
        if cls.kind == "encoder":      # the fit's per-cable band is the plant's (shape key <name>_2)
            sh = next(s for s in cls.shapes if s.per_cable)
            assert band[1] == shape[f"{sh.name}_2"] and np.count_nonzero(band) == 1
        assert np.any(eff.elongation_offset(4) != 0) or eff.command_delay > 0 or eff.camera_delay > 0 or np.any(band > 0)


ENCODER = [c for c in EFFECTS if c.kind == "encoder"]


@pytest.mark.parametrize("cls", ENCODER, ids=ids(ENCODER))
def test_encoder_effects_offset_the_elongation_the_plant_has(cls, rng):
    """A dead band in the plant (from ``to_plant``) against the fit's offset of the elongation:
    the encoders the plant reports minus its true motor-slide (drum) positions, in m of cable, is
    the lead the fit computes from those encoders (``fit_cable_offset`` is minus it), to within the
    plant's finite swing across the band (the drum moves 1/SWING of the band meanwhile)."""
    from neck_sim.effects.backlash import SWING, motor_lead

    p = default_params(3)
    sh = next(s for s in cls.shapes if s.per_cable)
    band = 0.5e-3
    _, eff = cls.to_plant(p, {}, {f"{sh.name}_2": band})
    plant = P.Plant(p, effects=E.Effects.of(eff), seed=0)
    plant.reset()
    ratio = p.actuation.R / p.actuation.r_d
    f0 = plant.truth().tension.copy() + 5.0
    enc, drum = [], []
    for k in range(1500):          # 3 s: cable 2 wound, unwound, wound again by a force swing
        f = f0.copy()
        f[1] += 12.0 * np.sin(2 * np.pi * k / 500.0)
        plant.step(f)
        enc.append(plant.encoders())
        drum.append(plant._out_theta.copy())
    enc, drum = np.array(enc) / ratio, np.array(drum) / ratio                # m of cable
    lead = enc - drum
    quant = (2 * np.pi / p.sensors.encoder_counts_per_turn) / ratio          # one encoder count, m
    assert np.abs(lead[:, [0, 2, 3]]).max() <= 0.5 * quant                   # no band: quantisation only
    assert np.abs(lead[:, 1]).max() <= band / 2 + quant and np.ptp(lead[:, 1]) > 0.95 * band   # it swings across
    fitted = motor_lead(enc[:, 1:2], band)[:, 0]
    assert np.abs(fitted - lead[:, 1]).max() <= band / SWING + 2 * quant


@pytest.mark.parametrize("cls", EFFECTS, ids=ids(EFFECTS))
def test_names_units_and_json(cls):
    assert cls.name in E.names() and E.get(cls.name) is cls
    assert cls.description and "\n" not in cls.description and cls.__doc__ and len(cls.__doc__) > 60
    for col in cls.columns:
        assert col.symbol and col.unit and len(col.names(3, 4)) == {"cable": 4, "joint": 3, "spring": 6, "one": 1}[col.per]
        assert len(col.names(10, 4)) == {"cable": 4, "joint": 10, "spring": 20, "one": 1}[col.per]
    for sh in cls.shapes:
        assert sh.name and sh.unit
    eff = cls()
    text = json.dumps(E.Effects.of(eff).to_dict())
    assert E.Effects.from_dict(json.loads(text)) == E.Effects.of(eff)
    assert all(p.startswith(cls.name + ".") for p in eff.parameter_names())
    for need in cls.requires:
        assert need in E.names() and list(E.names()).index(need) < list(E.names()).index(cls.name)


@pytest.mark.parametrize("cls", [c for c in EFFECTS if c.shapes], ids=ids([c for c in EFFECTS if c.shapes]))
def test_default_shape_lies_inside_its_grid(cls):
    for sh in cls.shapes:
        if sh.per_cable:          # the search range holds "absent" (0)
            assert sh.default is None and sh.bounds[0] <= 0 < sh.bounds[1]
        else:
            assert sh.grid and min(sh.grid) <= sh.default <= max(sh.grid), sh
            assert list(sh.grid) == sorted(set(sh.grid))
    assert dict(cls.default_shape()).keys() == {sh.name for sh in cls.shapes if not sh.per_cable}


@pytest.mark.parametrize("cls", SIGNED, ids=ids(SIGNED))
def test_sign_constraint_rejects_a_wrong_signed_fit(cls, rng):
    col = next(c for c in cls.columns if c.signed)
    count = len(col.names(3, 4))
    good = {c.symbol: rng.uniform(1.0, 2.0, len(c.names(3, 4))) for c in cls.columns}
    sig = {c.symbol: np.full(len(c.names(3, 4)), 0.01) for c in cls.columns}
    assert cls.sign_violation(good, sig) == ""
    bad = dict(good)
    bad[col.symbol] = good[col.symbol].copy()
    bad[col.symbol][count - 1] = -1.5
    msg = cls.sign_violation(bad, sig)
    assert col.symbol in msg and cls.name in msg
    noisy = {k: v.copy() for k, v in bad.items()}
    assert cls.sign_violation(noisy, {k: np.full(v.size, 1.0) for k, v in noisy.items()}) == ""   # |z| < 4
