"""Each effect's identification side, one module per effect, and the registry keyed by effect name.

The physics of an effect (parameters, force law, plant hooks) is its module of
:mod:`neck_sim.effects`; how the diagnosis fits it (regressor columns, shape parameters, the map
of a fit back to plant data) is its module here, over the typed data view :class:`ColumnData`
(protocol in :mod:`identification.diagnosis.columns.base`).  The diagnosis tries as candidates the
effects that have columns here, in the effect registry's (report) order.

Usage::

    from identification.diagnosis import columns

    cols = columns.get("viscous_friction")        # ViscousFrictionColumns
    [c.symbol for c in cols.columns]               # ['c_v']
    cols.default_shape()                           # ()

A new effect registers its physics with :func:`neck_sim.effects.register` first, then its columns
with :func:`register` (see ``docs/adding-an-effect.md``).
"""

from __future__ import annotations

from neck_sim import effects as effect_registry

from identification.diagnosis.columns.actuation_delay import ActuationDelayColumns
from identification.diagnosis.columns.backlash import BACKLASH_RANGE, BacklashColumns
from identification.diagnosis.columns.base import (Column, ColumnData, Design, EffectColumns, FitContext, MotorColumns,
                                                   Shape)
from identification.diagnosis.columns.cable_elasticity import CableElasticityColumns
from identification.diagnosis.columns.camera_delay import CameraDelayColumns
from identification.diagnosis.columns.dry_friction import DryFrictionColumns
from identification.diagnosis.columns.joint_friction import JointFrictionColumns
from identification.diagnosis.columns.payload import PayloadColumns
from identification.diagnosis.columns.pretension import PRETENSION_RANGE, PretensionColumns
from identification.diagnosis.columns.pulley_friction import PulleyFrictionColumns
from identification.diagnosis.columns.spring_error import SpringErrorColumns
from identification.diagnosis.columns.stribeck_friction import StribeckFrictionColumns
from identification.diagnosis.columns.tension_stiffening import TensionStiffeningColumns
from identification.diagnosis.columns.viscous_friction import ViscousFrictionColumns

__all__ = ["Column", "ColumnData", "Design", "EffectColumns", "FitContext", "MotorColumns", "Shape", "register",
           "unregister", "get", "registered", "names", "BACKLASH_RANGE", "PRETENSION_RANGE"]

_REGISTRY: dict[str, type[EffectColumns]] = {}


def register(cls: type[EffectColumns]) -> type[EffectColumns]:
    """Add an effect's columns (usable as a class decorator); returns the class.

    ``cls.effect`` must name a registered effect without columns yet; motor effects take
    :class:`MotorColumns`.
    """
    if not (isinstance(cls, type) and issubclass(cls, EffectColumns)):
        raise TypeError(f"columns.register: expected a subclass of EffectColumns, got {cls!r}")
    effect = effect_registry.get(cls.effect)        # ValueError naming the known effects
    if issubclass(effect, effect_registry.MotorEffect) != issubclass(cls, MotorColumns):
        raise TypeError(f"columns.register: {cls.__name__} must subclass MotorColumns exactly when "
                        f"{effect.__name__} is a MotorEffect")
    for col in cls.columns:
        if not isinstance(col, Column):
            raise TypeError(f"columns.register: {cls.__name__}.columns must hold Column objects, got {col!r}")
    for sh in cls.shapes:
        if not isinstance(sh, Shape):
            raise TypeError(f"columns.register: {cls.__name__}.shapes must hold Shape objects, got {sh!r}")
    if cls.effect in _REGISTRY and _REGISTRY[cls.effect] is not cls:
        raise ValueError(f"columns.register: {cls.effect} has columns already ({_REGISTRY[cls.effect].__name__})")
    _REGISTRY[cls.effect] = cls
    return cls


def unregister(effect: str) -> None:
    """Remove columns added by :func:`register` (tests); the built-in ones cannot be removed."""
    if effect in _BUILTIN:
        raise ValueError(f"columns.unregister: {effect} is part of the built-in vocabulary")
    _REGISTRY.pop(effect, None)


def names() -> tuple[str, ...]:
    """Names of the effects with columns, in the effect registry's (report) order."""
    return tuple(n for n in effect_registry.names() if n in _REGISTRY)


def registered() -> tuple[type[EffectColumns], ...]:
    """Every columns class, in the effect registry's (report) order."""
    return tuple(_REGISTRY[n] for n in names())


def get(effect: str) -> type[EffectColumns]:
    """The columns of effect ``effect``; ValueError listing the effects that have columns otherwise."""
    if effect not in names():
        raise ValueError(f"no columns for effect {effect!r} (effects with columns: {', '.join(names())})")
    return _REGISTRY[effect]


for _cls in (DryFrictionColumns, ViscousFrictionColumns, StribeckFrictionColumns, PulleyFrictionColumns,
             CableElasticityColumns, TensionStiffeningColumns, PayloadColumns, SpringErrorColumns,
             ActuationDelayColumns, PretensionColumns, JointFrictionColumns, CameraDelayColumns, BacklashColumns):
    register(_cls)
_BUILTIN = frozenset(_REGISTRY)
