"""One contract over every registered effect (as dm_control's domains_test runs one over every domain).

For each effect of :mod:`neck_sim.effects`:

* its three audiences are there: the physics (:mod:`neck_sim.effects`), the columns
  (:mod:`identification.diagnosis.columns`) and at least one hiding form of the blind-test
  generator (:mod:`identification.diagnosis.blind_forms`), all under its name;
* the columns read of the measured data only what :class:`ColumnData` states, and
  :class:`MeasuredData` answers it;
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
from typing import ClassVar

import numpy as np
import pytest

import neck_sim.analytic as an
from neck_sim import effects as E
from neck_sim import plant as P
from neck_sim.native import DISPATCH
from neck_sim.params import default_params, example_params

from identification.diagnosis import blind_forms
from identification.diagnosis import columns as IC
from identification.diagnosis.columns import ColumnData, FitContext

EFFECTS = E.registered()
MOTOR = [c for c in EFFECTS if c.kind == "motor"]
NATIVE = [c for c in MOTOR if c.baseline or c().native_fields(4) is not None]
WITH_COLUMNS = [c for c in EFFECTS if IC.get(c.name).columns and IC.get(c.name).columns_exact]
SIGNED = [c for c in EFFECTS if any(col.signed for col in IC.get(c.name).columns)]
#: every member of the data protocol: its fields and its methods
PROTOCOL = set(ColumnData.__annotations__) | {k for k, v in vars(ColumnData).items() if callable(v) and k[0] != "_"}


def ids(classes):
    return [c.name for c in classes]


@pytest.mark.parametrize("cls", EFFECTS, ids=ids(EFFECTS))
def test_every_effect_has_its_three_audiences(cls, rng):
    """Physics, columns and a blind form under the effect's name; each form hides this effect."""
    assert issubclass(cls, E.Effect) and E.get(cls.name) is cls and isinstance(cls(), cls)
    cols = IC.get(cls.name)
    assert cols.effect == cls.name and cols.effect_class() is cls
    assert issubclass(cols, IC.MotorColumns) == issubclass(cls, E.MotorEffect)
    forms = blind_forms.of_effect(cls.name)
    assert forms
    p = default_params(3)
    for form in forms:
        h = form.hide(p, rng, form.magnitude, 0, 1)
        assert h.expect == cls.name and h.description and form.unit is not None
        hidden = E.Effects.of(*h.effects)
        hidden.check(h.params)
        assert (cls.name in hidden.names()) or cls.baseline       # a baseline effect may be hidden by another law


def test_registries_refuse_what_does_not_fit():
    with pytest.raises(ValueError, match="no columns for effect 'gear_creep'"):
        IC.get("gear_creep")
    with pytest.raises(ValueError, match="unknown effect 'gear_creep'"):
        IC.register(type("GearCreep", (IC.EffectColumns,), {"effect": "gear_creep"}))
    with pytest.raises(ValueError, match="has columns already"):
        IC.register(type("Again", (IC.MotorColumns,), {"effect": "viscous_friction"}))
    with pytest.raises(TypeError, match="MotorColumns exactly when"):
        IC.register(type("Wrong", (IC.EffectColumns,), {"effect": "viscous_friction"}))
    with pytest.raises(ValueError, match="built-in"):
        IC.unregister("payload")
    with pytest.raises(ValueError, match="exists"):
        blind_forms.register("payload", "payload", 1.0, "kg")
    with pytest.raises(ValueError, match="must be 'payload' or 'payload:<variant>'"):
        blind_forms.register("heavy_head", "payload", 1.0, "kg")
    with pytest.raises(ValueError, match="unknown blind case 'gear_creep'"):
        blind_forms.get("gear_creep")


class _Only:
    """``data`` seen through the members of :class:`ColumnData` alone: any other read fails."""

    allowed: ClassVar[frozenset] = frozenset(PROTOCOL)

    def __init__(self, data):
        self._data = data

    def __getattr__(self, name):
        if name not in self.allowed:
            raise AttributeError(f"the columns read {name!r}, which ColumnData does not state")
        return getattr(self._data, name)


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    """A short simulated log (one sequence of the identification trajectory) as MeasuredData."""
    from identification.diagnosis.blind import excitation_trajectory, run_log
    from identification.diagnosis.measured import MeasuredData
    from neck_sim.logs import read_log

    p = default_params(3)
    path = tmp_path_factory.mktemp("protocol") / "short.mcap"
    run_log(path, p, E.Effects(), trajectory=excitation_trajectory(p, sequences=1), seed=3, write_truth=False)
    return MeasuredData.from_log(read_log(path))


@pytest.mark.parametrize("cls", EFFECTS, ids=ids(EFFECTS))
def test_columns_read_only_the_data_protocol(cls, measured, rng):
    """Every hook that takes data runs on MeasuredData seen through ColumnData alone, with the
    shapes the search tries, and gives arrays of the documented shapes."""
    from identification.diagnosis.candidates import initial_state

    assert isinstance(measured, ColumnData)
    cols, d = IC.get(cls.name), _Only(measured)
    S, n, C = measured.S, measured.n, measured.C
    state = initial_state(measured)
    shape = _shape(cls, rng)
    design = cols.design(d, shape, FitContext(measured.x, state.tension_fast, state.tension))
    p = sum(len(col.names(n, C)) for col in cols.columns)
    assert design.torque.shape == (S, n, p) and design.cable.shape == (S, C, p)
    assert np.all(np.isfinite(design.torque)) and np.all(np.isfinite(design.cable))
    series = cols.fit_elongation_series(d, shape)
    assert series is None or series.shape == (S, C)
    offset = cols.fit_force_offset(d, shape)
    assert offset is None or (offset[0].shape == measured.force_fast.shape and offset[1].shape == (S, C))
    for sh in cols.shapes:
        if sh.per_cable:
            assert np.shape(cols.fit_cable_offset(d, 1, sh.bounds[1] / 2)) in ((), (S,))


def _shape(cls, rng):
    """A shape other than the default: a grid point for searched shapes, an offset on cable 2."""
    out = {}
    for sh in IC.get(cls.name).shapes:
        if sh.per_cable:
            out[f"{sh.name}_2"] = float(rng.uniform(*sh.bounds))
        else:
            out[sh.name] = float(rng.choice(sh.grid)) if sh.grid else sh.default
    return out


def _magnitudes(cls, rng, n, m):
    out = {}
    for col in IC.get(cls.name).columns:
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
    """The data protocol's members, exactly, on random states (no filter: to_slow and
    motor_lowpass = identity, the control rate is the slow grid), and the elongations x (S, C) m
    of those states."""
    n, C = params.n_joints, params.n_cables
    alpha = rng.uniform(-0.4, 0.4, (S, n))
    t = np.arange(S) * 0.01
    cache = {}

    def cached(key, compute):
        if key not in cache:
            cache[key] = compute()
        return cache[key]

    d = types.SimpleNamespace(
        S=S, n=n, C=C, params=params, t=t, t_fast=t, dt=0.01, ratio=params.actuation.R / params.actuation.r_d,
        alpha=alpha, alpha_dot=rng.normal(0, 1, (S, n)), alpha_ddot=rng.normal(0, 5, (S, n)),
        Z=an.transmission_matrix(alpha, params), x_dot=rng.normal(0, 5e-4, (S, C)),
        theta_fast=rng.normal(0, 2, (S, C)), theta_dot_fast=rng.normal(0, 20, (S, C)), to_slow=lambda v: v,
        motor_lowpass=lambda v: v,
        prep=types.SimpleNamespace(rate_hz=100.0, cutoffs={"common": types.SimpleNamespace(hz=5.0)}),
        cached=cached)
    assert set(vars(d)) == PROTOCOL
    return d, rng.uniform(1e-3, 3e-3, (S, C))


def _observations(d, x, params, effects, elastic, nominal):
    """Cable block y_C = f_motor + t (N) and torque block Z f_motor + linkage change (N m) of the
    plant's physics: eq (37) + motor effects at the data's motor speed, eq (54) tension at the
    data's elongation (plus rest elongations), linkage eq (30) against the nominal one."""
    w = d.theta_dot_fast
    C = d.C
    x = x + effects.elongation_offset(C)
    t = an.cable_tension(x, d.x_dot, params) if elastic else np.zeros_like(x)
    f = an.motor_friction(w, params) + sum((e.motor_force(w, t) for e in effects.motor_effects()), np.zeros_like(w))
    lk, lk0 = (an.linkage_dynamics(d.alpha, d.alpha_dot, p) for p in (params, nominal))
    dl = np.einsum("sij,sj->si", lk.M - lk0.M, d.alpha_ddot) + (lk.c - lk0.c) + (lk.g - lk0.g)
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
    d, x = _fake_data(nominal, rng)
    cols = IC.get(cls.name)
    shape, values = _shape(cls, rng), _magnitudes(cls, rng, n, m)
    base = nominal
    for other in IC.registered():           # without: no friction, rigid cables unless this adds to them
        if other is not cols and other.effect_class().baseline and other.effect not in cls.requires:
            base = other.when_absent(base, True)
    base = cols.when_absent(base, True)
    params, extra = cols.to_plant(base, values, shape)
    with_eff = E.Effects.of(extra) if extra is not None else E.Effects()
    yC1, yT1, t1 = _observations(d, x, params, with_eff, True, nominal)
    # without the effect: the same plant, rigid cables when the effect is what makes them elastic
    yC0, yT0, _ = _observations(d, x, base, E.Effects(), not cols.elastic_cables, nominal)
    design = cols.design(d, shape, FitContext(x, t1, t1))
    v = np.concatenate([np.ravel(values[col.symbol]) for col in cols.columns])
    np.testing.assert_allclose(design.cable @ v, yC1 - yC0, rtol=1e-9, atol=1e-9 * np.abs(yC1).max())
    np.testing.assert_allclose(design.torque @ v, yT1 - yT0, rtol=1e-9, atol=1e-9 * np.abs(yT1).max())


def test_shifting_effects_reach_the_plant_as_fitted(rng):
    """Effects without columns: the rest elongations and the delay the fit uses are the plant's."""
    shifting = [c for c in EFFECTS if not IC.get(c.name).columns]
    assert {c.kind for c in shifting} >= {"elongation", "command", "camera", "encoder"}
    for cls in shifting:
        cols = IC.get(cls.name)
        shape = _shape(cls, rng)
        params, eff = cols.to_plant(default_params(3), {}, shape)
        assert eff is not None and params == default_params(3)
        np.testing.assert_array_equal(eff.elongation_offset(4), cols.fit_elongation_offset(shape, 4))
        assert eff.command_delay == cols.fit_delay(shape)
        assert eff.camera_delay == cols.fit_camera_shift(shape)
        band = eff.encoder_band(4)
        if cls.kind == "encoder":      # the fit's per-cable band is the plant's (shape key <name>_2)
            sh = next(s for s in cols.shapes if s.per_cable)
            assert band[1] == shape[f"{sh.name}_2"] and np.count_nonzero(band) == 1
        assert np.any(eff.elongation_offset(4) != 0) or eff.command_delay > 0 or eff.camera_delay > 0 or np.any(band > 0)


ENCODER = [c for c in EFFECTS if c.kind == "encoder"]


@pytest.mark.parametrize("cls", ENCODER, ids=ids(ENCODER))
def test_encoder_effects_offset_the_elongation_the_plant_has(cls, rng):
    """A dead band in the plant (from ``to_plant``) against the fit's offset of the elongation:
    the encoders the plant reports minus its true motor-slide (drum) positions, in m of cable, is
    the lead the fit computes from those encoders (``fit_cable_offset`` is minus it), to within the
    plant's finite swing across the band (the drum moves 1/SWING of the band meanwhile)."""
    from identification.diagnosis.columns.backlash import motor_lead
    from neck_sim.effects.backlash import SWING

    p = default_params(3)
    cols = IC.get(cls.name)
    sh = next(s for s in cols.shapes if s.per_cable)
    band = 0.5e-3
    _, eff = cols.to_plant(p, {}, {f"{sh.name}_2": band})
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
    cols = IC.get(cls.name)
    for col in cols.columns:
        assert col.symbol and col.unit and len(col.names(3, 4)) == {"cable": 4, "joint": 3, "spring": 6, "one": 1}[col.per]
        assert len(col.names(10, 4)) == {"cable": 4, "joint": 10, "spring": 20, "one": 1}[col.per]
    for sh in cols.shapes:
        assert sh.name and sh.unit
    eff = cls()
    text = json.dumps(E.Effects.of(eff).to_dict())
    assert E.Effects.from_dict(json.loads(text)) == E.Effects.of(eff)
    assert all(p.startswith(cls.name + ".") for p in eff.parameter_names())
    for need in cls.requires:
        assert need in E.names() and list(E.names()).index(need) < list(E.names()).index(cls.name)


SHAPED = [c for c in EFFECTS if IC.get(c.name).shapes]


@pytest.mark.parametrize("cls", SHAPED, ids=ids(SHAPED))
def test_default_shape_lies_inside_its_grid(cls):
    cols = IC.get(cls.name)
    for sh in cols.shapes:
        if sh.per_cable:          # the search range holds "absent" (0)
            assert sh.default is None and sh.bounds[0] <= 0 < sh.bounds[1]
        else:
            assert sh.grid and min(sh.grid) <= sh.default <= max(sh.grid), sh
            assert list(sh.grid) == sorted(set(sh.grid))
    assert dict(cols.default_shape()).keys() == {sh.name for sh in cols.shapes if not sh.per_cable}


@pytest.mark.parametrize("cls", SIGNED, ids=ids(SIGNED))
def test_sign_constraint_rejects_a_wrong_signed_fit(cls, rng):
    cols = IC.get(cls.name)
    col = next(c for c in cols.columns if c.signed)
    count = len(col.names(3, 4))
    good = {c.symbol: rng.uniform(1.0, 2.0, len(c.names(3, 4))) for c in cols.columns}
    sig = {c.symbol: np.full(len(c.names(3, 4)), 0.01) for c in cols.columns}
    assert cols.sign_violation(good, sig) == ""
    bad = dict(good)
    bad[col.symbol] = good[col.symbol].copy()
    bad[col.symbol][count - 1] = -1.5
    msg = cols.sign_violation(bad, sig)
    assert col.symbol in msg and cls.name in msg
    noisy = {k: v.copy() for k, v in bad.items()}
    assert cols.sign_violation(noisy, {k: np.full(v.size, 1.0) for k, v in noisy.items()}) == ""   # |z| < 4
