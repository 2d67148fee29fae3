"""How the blind-test generator hides each effect: one form per effect, registered by case name.

A form is written here, in the test generator, not in the effect's physics or its columns: the
hidden effect should differ from the candidate the diagnosis fits (another Stribeck speed and
smoothing, a sharper dry-friction sign, friction on one cable only, a pulley-friction smoothing
other than the candidate's), so that a blind test shows the diagnosis finds the effect, not its
own formula.  :func:`identification.diagnosis.blind.hidden_effect` draws the magnitude factor,
the cable and the joint from a seed and calls the form.

Usage::

    from identification.diagnosis import blind_forms

    form = blind_forms.get("viscous_friction")      # BlindForm(case, effect, magnitude 0.15, "N s/rad", hide)
    hidden = form.hide(params, rng, 0.15, 0, 1)      # Hidden(params, effects, cables, joints, description, expect)

A new form: ``@register("case", "effect", magnitude, unit)`` on a function ``hide(params, rng,
magnitude, cable, joint) -> Hidden``; ``case`` is the effect's name for its main form,
``effect:variant`` for others (e.g. ``dry_friction:tanh``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np

from neck_sim import effects as effect_registry
from neck_sim.effects import (ActuationDelay, Backlash, CableElasticity, CameraDelay, DryFriction, JointFriction,
                              Payload, Pretension, PulleyFriction, SpringError, StribeckFriction, TensionStiffening,
                              ViscousFriction)
from neck_sim.effects.spring_error import SIDES
from neck_sim.params import NeckParams

__all__ = ["Hidden", "BlindForm", "register", "unregister", "get", "forms", "of_effect"]


class Hidden(NamedTuple):
    """A blind test's hidden effect: plant constants and effects, where it was hidden (0-based),
    a description, the effect a correct diagnosis names."""

    params: NeckParams
    effects: tuple
    cables: tuple
    joints: tuple
    description: str
    expect: str


Hide = Callable[[NeckParams, np.random.Generator, float, int, int], Hidden]


@dataclass(frozen=True)
class BlindForm:
    """One way to hide ``effect``: blind case name ``case``, test magnitude ``magnitude`` (the
    "medium" level, in ``unit``), ``hide(params, rng, magnitude, cable, joint) -> Hidden`` with a
    cable and a joint drawn by the generator (0-based; a form may draw its own)."""

    case: str
    effect: str
    magnitude: float
    unit: str
    hide: Hide


_REGISTRY: dict[str, BlindForm] = {}


def register(case: str, effect: str, magnitude: float, unit: str) -> Callable[[Hide], Hide]:
    """Decorator: register ``hide`` as the blind form ``case`` of the registered ``effect``."""
    effect_registry.get(effect)                       # ValueError naming the known effects
    if case != effect and not case.startswith(effect + ":"):
        raise ValueError(f"blind_forms.register: case {case!r} must be {effect!r} or {effect + ':<variant>'!r}")
    if case in _REGISTRY:
        raise ValueError(f"blind_forms.register: a blind form {case!r} exists")

    def add(hide: Hide) -> Hide:
        _REGISTRY[case] = BlindForm(case, effect, float(magnitude), unit, hide)
        return hide
    return add


def unregister(case: str) -> None:
    """Remove a form added by :func:`register` (tests); the built-in forms cannot be removed."""
    if case in _BUILTIN:
        raise ValueError(f"blind_forms.unregister: {case} is a built-in blind form")
    _REGISTRY.pop(case, None)


def forms() -> dict[str, BlindForm]:
    """Blind case name -> form, in the effect registry's (report) order, an effect's forms in the
    order they were registered."""
    order = {name: i for i, name in enumerate(effect_registry.names())}
    live = [f for f in _REGISTRY.values() if f.effect in order]
    return {f.case: f for f in sorted(live, key=lambda f: order[f.effect])}


def get(case: str) -> BlindForm:
    """The form called ``case``; ValueError listing the known ones otherwise."""
    known = forms()
    if case not in known:
        raise ValueError(f"unknown blind case {case!r} (known: {', '.join(known)})")
    return known[case]


def of_effect(effect: str) -> tuple[BlindForm, ...]:
    """Every form that hides ``effect``."""
    return tuple(f for f in forms().values() if f.effect == effect)


def _no_friction(params: NeckParams) -> NeckParams:
    """The generator's friction-free plant (a baseline without the paper's eq 37)."""
    return params.replace(**{"friction.f_s": (0.0,) * params.n_cables})


# ---------------------------------------------------------------------------- the built-in forms

@register(DryFriction.name, DryFriction.name, 12.0, "N")      # f_s on one cable (baseline without friction)
def _dry_friction(params, rng, magnitude, cable, joint):
    """A sharper sign than eq (37)'s c_s = 0.5, on one cable only, against a friction-free model."""
    cs = float(rng.uniform(2.0, 6.0))
    desc = f"dry friction {magnitude:.2f} N, c_s = {cs:.2f} s/rad, on cable {cable + 1} only"
    return Hidden(_no_friction(params), (DryFriction(f_s=magnitude, c_s=cs, cables=(cable,)),), (cable,), (), desc,
                  DryFriction.name)


@register(DryFriction.name + ":tanh", DryFriction.name, 12.0, "N")
def _dry_friction_tanh(params, rng, magnitude, cable, joint):
    """A tanh-smoothed sign (the plant's Stribeck term with an infinite Stribeck speed), one cable."""
    smooth = float(rng.uniform(0.2, 1.0))
    eff = StribeckFriction(df=magnitude, speed=1e6, smoothing=smooth, cables=(cable,))
    desc = f"dry friction {magnitude:.2f} N with a tanh sign (smoothing {smooth:.2f} rad/s) on cable {cable + 1} only"
    return Hidden(_no_friction(params), (eff,), (cable,), (), desc, DryFriction.name)


@register(ViscousFriction.name, ViscousFriction.name, 0.15, "N s/rad")     # at the motor shaft
def _viscous_friction(params, rng, magnitude, cable, joint):
    desc = f"viscous friction {magnitude:.3f} N s/rad on cable {cable + 1}"
    return Hidden(params, (ViscousFriction(c_v=magnitude, cables=(cable,)),), (cable,), (), desc,
                  ViscousFriction.name)


@register(StribeckFriction.name, StribeckFriction.name, 8.0, "N")          # of extra breakaway friction
def _stribeck_friction(params, rng, magnitude, cable, joint):
    speed = float(rng.uniform(2.5, 7.0))
    smooth = float(rng.uniform(0.2, 0.8))
    desc = (f"Stribeck friction +{magnitude:.2f} N, speed {speed:.2f} rad/s, smoothing {smooth:.2f} rad/s, "
            f"cable {cable + 1}")
    return Hidden(params, (StribeckFriction(df=magnitude, speed=speed, smoothing=smooth, cables=(cable,)),), (cable,),
                  (), desc, StribeckFriction.name)


@register(PulleyFriction.name, PulleyFriction.name, 0.15, "")              # fraction of the tension
def _pulley_friction(params, rng, magnitude, cable, joint):
    c = float(rng.uniform(1.0, 3.0))
    desc = f"pulley friction mu = {magnitude:.3f}, c = {c:.2f} s/rad, cable {cable + 1}"
    return Hidden(params, (PulleyFriction(mu=magnitude, c=c, cables=(cable,)),), (cable,), (), desc,
                  PulleyFriction.name)


@register(CableElasticity.name, CableElasticity.name, 1.0, "x Table 2 k")   # baseline with rigid cables
def _cable_elasticity(params, rng, magnitude, cable, joint):
    k = tuple(np.asarray(params.cables.k) * magnitude)
    desc = f"elastic cables, k = {magnitude:.2f} x Table 2"
    return Hidden(params, (CableElasticity(k=k),), tuple(range(params.n_cables)), (), desc, CableElasticity.name)


@register(TensionStiffening.name, TensionStiffening.name, 1.0, "x Table 2 lambda")   # baseline with linear cables
def _tension_stiffening(params, rng, magnitude, cable, joint):
    lam = tuple(np.asarray(params.cables.lam) * magnitude)
    desc = f"tension stiffening, lambda = {magnitude:.2f} x Table 2"
    return Hidden(params, (TensionStiffening(lam=lam),), tuple(range(params.n_cables)), (), desc,
                  TensionStiffening.name)


@register(Payload.name, Payload.name, 0.08, "kg")                          # at the head
def _payload(params, rng, magnitude, cable, joint):
    return Hidden(params, (Payload(mass=magnitude),), (), (), f"payload {1e3 * magnitude:.0f} g at the head",
                  Payload.name)


@register(SpringError.name, SpringError.name, 0.5, "relative")             # stiffness error of one spring
def _spring_error(params, rng, magnitude, cable, joint):
    side = int(rng.integers(2))
    k = params.springs.stiffness[joint] * magnitude * (1 if rng.random() < 0.5 else -1)
    dk = np.zeros(2 * params.n_joints)
    dk[2 * joint + side] = k
    desc = f"{SIDES[side]} side spring of joint {joint + 1} {k:+.0f} N/m"
    return Hidden(params, (SpringError(dk=tuple(dk)),), (), (joint,), desc, SpringError.name)


@register(ActuationDelay.name, ActuationDelay.name, 0.010, "s")
def _actuation_delay(params, rng, magnitude, cable, joint):
    return Hidden(params, (ActuationDelay(delay=magnitude),), (), (), f"actuation delay {1e3 * magnitude:.1f} ms",
                  ActuationDelay.name)


@register(Pretension.name, Pretension.name, 1.5e-3, "m")                   # on one cable
def _pretension(params, rng, magnitude, cable, joint):
    # not on the softest cables (the paper's long left cable): they stiffen strongly (lambda x_0 ~
    # 0.2), so their k and lambda absorb an offset of a few mm within the noise (see the detection
    # benchmark)
    k = np.asarray(params.cables.k, dtype=float)
    stiff = np.nonzero(k > k.min())[0] if np.ptp(k) > 0 else np.arange(k.size)
    cable = int(stiff[rng.integers(stiff.size)])
    desc = f"pretension {1e3 * magnitude:.2f} mm on cable {cable + 1}"
    return Hidden(params, (Pretension(elongation=magnitude, cables=(cable,)),), (cable,), (), desc, Pretension.name)


@register(JointFriction.name, JointFriction.name, 0.02, "N m")             # per hinge
def _joint_friction(params, rng, magnitude, cable, joint):
    desc = f"hinge friction {magnitude:.3f} N m in joint {joint + 1}"
    return Hidden(params, (JointFriction(torque=magnitude, joints=(joint,)),), (), (joint,), desc, JointFriction.name)


@register(CameraDelay.name, CameraDelay.name, 0.033, "s")                  # one camera frame at 30 Hz
def _camera_delay(params, rng, magnitude, cable, joint):
    return Hidden(params, (CameraDelay(delay=magnitude),), (), (), f"camera delay {1e3 * magnitude:.0f} ms",
                  CameraDelay.name)


@register(Backlash.name, Backlash.name, 0.3e-3, "m")                       # of cable on one right cable
def _backlash(params, rng, magnitude, cable, joint):
    cable = int(rng.integers(params.n_cables - 1))        # a right cable (see ``pretension``)
    desc = f"backlash {1e3 * magnitude:.2f} mm of cable on motor {cable + 1}"
    return Hidden(params, (Backlash(band=magnitude, cables=(cable,)),), (cable,), (), desc, Backlash.name)


_BUILTIN = frozenset(_REGISTRY)
