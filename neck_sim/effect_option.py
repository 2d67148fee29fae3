"""``NAME=VALUE[@INDEX]``: an effect of the vocabulary given on the command line (``simulate --effect``).

``NAME`` is a registered effect (``neck-sim effects``); ``VALUE`` (SI units) sets its main
parameter (:func:`value_field`): the ``magnitude_field`` of a per-cable or per-joint effect (dry
friction f_s N, viscous c_v N s/rad, Stribeck df N, pulley mu, pretension elongation m, joint
friction torque N m per hinge), otherwise its first parameter (payload mass kg, actuation or camera
delay s, spring_error stiffness_scale (1 = nominal), cable_elasticity k N/m, tension_stiffening
lam 1/m).  ``@INDEX`` (1-based) restricts an effect with cables to that cable, one with joints to
that joint; without it the effect acts on every cable or joint.

Examples: ``payload=0.05``, ``dry_friction=25@2`` (cable 2's dry friction is 25 N),
``actuation_delay=0.01``, ``spring_error=0.5@3`` (both side springs of joint 3 at half stiffness).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Iterable

from neck_sim import effects as E
from neck_sim.params import NeckParams

__all__ = ["value_field", "parse_effect", "parse_effects"]


def value_field(cls: type[E.Effect]) -> str:
    """The parameter ``VALUE`` sets for effect class ``cls``."""
    if cls.magnitude_field:
        return cls.magnitude_field
    return next(f.name for f in dataclasses.fields(cls) if f.name not in ("cables", "joints"))


def parse_effect(text: str, params: NeckParams) -> E.Effect:
    """One ``NAME=VALUE[@INDEX]`` for the neck ``params``; ValueError (one line, naming the option)."""
    where = f"--effect {text}"
    name, eq, rest = text.partition("=")
    name = name.strip()
    if not eq or not name:
        raise ValueError(f"{where}: expected NAME=VALUE[@INDEX], e.g. payload=0.05 or dry_friction=25@2")
    if name not in E.names():
        raise ValueError(f"{where}: unknown effect {name!r} (known: {', '.join(E.names())})")
    cls = E.get(name)
    value_text, at, index_text = rest.partition("@")
    try:
        value = float(value_text)
    except ValueError:
        raise ValueError(f"{where}: VALUE {value_text!r} is not a number") from None
    if not math.isfinite(value):
        raise ValueError(f"{where}: VALUE must be finite, got {value_text}")
    kwargs: dict[str, object] = {value_field(cls): value}
    if at:
        have = {f.name for f in dataclasses.fields(cls)}
        kind = "cables" if "cables" in have else "joints" if "joints" in have else None
        if kind is None:
            raise ValueError(f"{where}: {name} acts on the whole neck; it takes no @INDEX")
        count = params.n_cables if kind == "cables" else params.n_joints
        try:
            index = int(index_text)
        except ValueError:
            raise ValueError(f"{where}: @{index_text} is not a {kind[:-1]} number") from None
        if not 1 <= index <= count:
            raise ValueError(f"{where}: {kind[:-1]} {index} does not exist (this neck has {count} {kind}, "
                             f"numbered 1..{count})")
        kwargs[kind] = (index - 1,)
    try:
        effect = cls(**kwargs)
        effect.check(params)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{where}: {exc}") from None
    return effect


def parse_effects(texts: Iterable[str], params: NeckParams) -> E.Effects:
    """Every ``--effect`` as the plant's :class:`neck_sim.effects.Effects`; an effect given twice is
    refused, and so is a combination the neck's constants cannot take."""
    effects = [parse_effect(t, params) for t in texts or ()]
    seen = set()
    for t, e in zip(texts or (), effects):
        if e.name in seen:
            raise ValueError(f"--effect {t}: {e.name} given twice (one --effect per effect; use its @INDEX once)")
        seen.add(e.name)
    out = E.Effects.of(*effects)
    try:
        out.true_params(params)
    except ValueError as exc:
        raise ValueError(f"--effect: {exc}") from None
    return out
