"""The effect vocabulary: names, parameter hooks, validation, formulas and parameter mappings."""

import numpy as np
import pytest

import neck_sim.analytic as an
from neck_sim import effects as E

# measured-data.md, "Effect vocabulary" table
DOC_NAMES = ["dry_friction", "viscous_friction", "stribeck_friction", "pulley_friction", "cable_elasticity",
             "tension_stiffening", "payload", "spring_error", "actuation_delay", "pretension", "joint_friction",
             "camera_delay", "backlash", "insufficient_excitation", "none", "unexplained"]
VERDICT_ONLY = {"insufficient_excitation", "none", "unexplained"}     # verdicts, not effects


def test_vocabulary_is_the_documented_one():
    assert list(E.VOCABULARY) == DOC_NAMES
    assert set(E.EFFECT_TYPES) == set(DOC_NAMES) - VERDICT_ONLY
    assert list(E.Effects.slots()) == list(E.names()) == DOC_NAMES[:-3]
    for name, cls in E.EFFECT_TYPES.items():
        assert cls.name == name and cls.__doc__ and len(cls.__doc__) > 60


def test_baseline_effects_are_marked():
    baseline = {n for n, c in E.EFFECT_TYPES.items() if c.baseline}
    assert baseline == {"dry_friction", "cable_elasticity", "tension_stiffening"}


@pytest.mark.parametrize("name", sorted(E.EFFECT_TYPES))
def test_parameter_names_and_round_trip(name):
    eff = E.make_effect(name)
    names = eff.parameter_names()
    assert names and all(n.startswith(name + ".") for n in names)
    assert set(eff.parameters()) == set(names)
    back = E.Effects.from_dict(E.Effects.of(eff).to_dict())
    assert getattr(back, name) == eff


def test_effects_container():
    assert E.Effects().names() == ("none",)
    eff = E.Effects.of(E.ViscousFriction(0.1), E.Payload(0.02))
    assert eff.names() == ("viscous_friction", "payload")
    assert [e.name for e in eff.motor_effects()] == ["viscous_friction"]
    with pytest.raises(ValueError, match="twice"):
        E.Effects.of(E.Payload(0.1), E.Payload(0.2))
    with pytest.raises(ValueError, match="viscous_friction"):
        E.Effects(viscous_friction=E.Payload(0.1))
    with pytest.raises(ValueError, match="unknown effect"):
        E.make_effect("gear_creep")


@pytest.mark.parametrize("make, match", [
    (lambda: E.ViscousFriction(c_v=-1.0), "viscous_friction.c_v"),
    (lambda: E.ViscousFriction(c_v=float("nan")), "finite"),
    (lambda: E.StribeckFriction(speed=0.0), "stribeck_friction.speed"),
    (lambda: E.PulleyFriction(mu=(0.1, -0.2), cables=(0, 1)), r"pulley_friction.mu\[1\]"),
    (lambda: E.Payload(mass=-0.1), "payload.mass"),
    (lambda: E.ActuationDelay(delay=-0.001), "actuation_delay.delay"),
    (lambda: E.ViscousFriction(cables=(1, 1)), "distinct"),
    (lambda: E.ViscousFriction(cables="x"), "indices"),
    (lambda: E.make_effect("payload", weight=1.0), "payload"),
])
def test_bad_values_are_refused(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_indices_checked_against_the_neck(params):
    with pytest.raises(ValueError, match="pretension.cables: index 4 out of range for 4 cables"):
        E.Effects.of(E.Pretension(1e-3, cables=(4,))).check(params)
    with pytest.raises(ValueError, match="spring_error.joints"):
        E.SpringError(joints=(3,)).check(params)
    with pytest.raises(ValueError, match="2 values for 1 affected cables"):
        E.ViscousFriction(c_v=(0.1, 0.2), cables=(0,)).check(params)


def test_motor_forces_follow_their_formulas(rng):
    td = rng.normal(0, 20, (50, 4))
    t = rng.uniform(0, 80, (50, 4))
    v = E.ViscousFriction(c_v=(0.3, 0.1), cables=(1, 3))
    np.testing.assert_allclose(v.motor_force(td), td * np.array([0, 0.3, 0, 0.1]))
    s = E.StribeckFriction(df=4.0, speed=3.0, smoothing=0.7)
    np.testing.assert_allclose(s.motor_force(td), 4.0 * np.exp(-(td / 3.0) ** 2) * np.tanh(td / 0.7))
    p = E.PulleyFriction(mu=0.2, c=0.5, cables=(2,))
    expect = np.zeros_like(td)
    expect[:, 2] = 0.2 * t[:, 2] * 2 / np.pi * np.arctan(0.5 * td[:, 2])
    np.testing.assert_allclose(p.motor_force(td, t), expect)
    # forces are linear in the magnitude: force = magnitude * regressor on the affected cables
    for eff in (v, s, p):
        np.testing.assert_allclose(eff.motor_force(td, t), eff.per_cable(4) * eff.regressor(td, t))


def test_dry_friction_is_eq_37(params, rng):
    td = rng.normal(0, 20, (30, 4))
    np.testing.assert_allclose(E.DryFriction().motor_force(td, params=params), an.motor_friction(td, params))
    own = E.DryFriction(f_s=(1.0, 2.0, 3.0, 4.0), c_s=2.0)
    np.testing.assert_allclose(own.motor_force(td), 2 / np.pi * np.arctan(2.0 * td) * [1, 2, 3, 4])


def test_baseline_mappings(params):
    assert E.DryFriction.from_params(params).apply(params) == params
    assert E.CableElasticity.from_params(params).apply(params) == params
    assert E.TensionStiffening.from_params(params).apply(params) == params
    p = E.DryFriction(f_s=5.0, cables=(3,)).apply(params)
    assert p.friction.f_s == params.friction.f_s[:3] + (5.0,)
    p = E.CableElasticity(k=(1e4,) * 4).apply(params)
    assert p.cables.k == (1e4,) * 4 and p.cables.c_a == params.cables.c_a
    assert E.TensionStiffening(lam=(0.0,) * 4).apply(params).cables.lam == (0.0,) * 4


def test_parameter_effects(params):
    p = E.Payload(0.05).apply(params)
    assert p.inertia.payload_mass == pytest.approx(0.05)
    p = E.SpringError(stiffness_scale=1.5, rest_length_offset=0.002, joints=(0, 2)).apply(params)
    np.testing.assert_allclose(p.springs.stiffness, np.array(params.springs.stiffness) * [1.5, 1, 1.5])
    assert p.springs.rest_length == pytest.approx(params.springs.rest_length + 0.002)
    eff = E.Effects.of(E.Payload(0.05), E.SpringError(stiffness_scale=2.0))
    true = eff.true_params(params)
    assert true.inertia.payload_mass == pytest.approx(0.05)
    np.testing.assert_allclose(true.springs.stiffness, 2 * np.array(params.springs.stiffness))
    np.testing.assert_allclose(E.Effects.of(E.Pretension(1e-3, cables=(0, 3))).elongation_offset(4),
                               [1e-3, 0, 0, 1e-3])


def test_actuation_delay_index():
    d = E.ActuationDelay(delay=0.005)
    issued = np.arange(10) * 0.002
    # at 0.011 s the newest command issued at or before 0.006 s is the one of 0.006 s (index 3)
    np.testing.assert_array_equal(d.delayed_index([0.0, 0.004, 0.011, 0.0119], issued), [0, 0, 3, 3])


def test_parameters_expand_per_cable():
    eff = E.ViscousFriction(c_v=0.3, cables=(1,))
    np.testing.assert_allclose(eff.parameters(4)["viscous_friction.c_v"], [0, 0.3, 0, 0])
    assert eff.parameters()["viscous_friction.c_v"] == 0.3
    assert E.DryFriction().parameters(4)["dry_friction.f_s"] is None


@pytest.mark.parametrize("name", ["check", "names", "active", "replace", "dry_friction"])
def test_register_refuses_a_name_taken_by_effects_or_another_effect(name):
    """``effects.<name>`` must reach the effect: no name of an Effects attribute nor of another effect."""
    cls = type("Clash", (E.ViscousFriction,), {"name": name, "__doc__": "A clash."})
    with pytest.raises(ValueError, match=f"{name!r} (is an attribute of Effects|exists)"):
        E.register(cls)
    assert E.get("dry_friction") is E.DryFriction and "check" not in E.names()


def test_requires_are_names():
    cls = type("Needy", (E.ViscousFriction,), {"name": "needy_friction", "requires": (E.DryFriction,),
                                                "__doc__": "Requires a class, not a name."})
    with pytest.raises(TypeError, match="requires must hold effect names"):
        E.register(cls)
    assert all(isinstance(r, str) for c in E.registered() for r in c.requires)
