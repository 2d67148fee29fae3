"""The effect vocabulary: one module per physical effect, and the registry that lists them.

Each module of this package defines one effect class (the protocol is in
:mod:`neck_sim.effects.base`): its name and description, parameters with units and signs, its
force law for the plant and its prerequisites (``requires``, by name).  The effect's other two
audiences are keyed by its name: its regressor columns, shape parameters and the map of a fitted
result back to plant data in :mod:`identification.diagnosis.columns`, how the blind tests hide it
in :mod:`identification.diagnosis.blind_forms`.  The plant, the diagnosis, the blind-log
generator, the reports and the command line iterate over :func:`registered`; nothing else lists
effect names.

A new effect is a new class registered with :func:`register` (see ``docs/adding-an-effect.md``);
the registry order is the report order.  ``dry_friction``, ``cable_elasticity`` and
``tension_stiffening`` are the paper's own model (``baseline``): the plant always has them (from
``NeckParams``); their classes map to those fields so that a diagnosis can name them and a plant
option can override them.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from neck_sim.effects.actuation_delay import ActuationDelay
from neck_sim.effects.backlash import Backlash
from neck_sim.effects.base import Effect, MotorEffect
from neck_sim.effects.cable_elasticity import CableElasticity
from neck_sim.effects.camera_delay import CameraDelay
from neck_sim.effects.dry_friction import DryFriction
from neck_sim.effects.joint_friction import JointFriction
from neck_sim.effects.payload import Payload
from neck_sim.effects.pretension import Pretension
from neck_sim.effects.pulley_friction import PulleyFriction
from neck_sim.effects.spring_error import SpringError
from neck_sim.effects.stribeck_friction import StribeckFriction
from neck_sim.effects.tension_stiffening import TensionStiffening
from neck_sim.effects.viscous_friction import ViscousFriction
from neck_sim.params import NeckParams

__all__ = ["Effect", "MotorEffect", "register", "unregister", "registered", "get", "names", "paper_model", "NONE",
           "UNEXPLAINED", "INSUFFICIENT_EXCITATION", "VOCABULARY", "EFFECT_TYPES", "make_effect", "Effects",
           "DryFriction", "ViscousFriction", "StribeckFriction", "PulleyFriction", "CableElasticity",
           "TensionStiffening", "Payload", "SpringError", "ActuationDelay", "Pretension", "JointFriction",
           "CameraDelay", "Backlash"]

NONE = "none"
"""The verdict when the model explains the data."""

UNEXPLAINED = "unexplained"
"""Part of the verdict when the residuals keep structure beyond noise that no effect removes."""

INSUFFICIENT_EXCITATION = "insufficient_excitation"
"""The verdict when the log cannot support one (too short, too still): its reasons say what to record."""

_REGISTRY: dict[str, type[Effect]] = {}


def register(cls: type[Effect]) -> type[Effect]:
    """Add an effect class to the vocabulary (usable as a class decorator); returns it.

    Its ``name`` must be a new identifier that is no attribute of :class:`Effects` (``check``,
    ``names``, ...: ``effects.<name>`` must reach the effect) and its ``requires`` names of
    registered effects.
    """
    if not (isinstance(cls, type) and issubclass(cls, Effect)):
        raise TypeError(f"register: expected a subclass of neck_sim.effects.Effect, got {cls!r}")
    name = cls.name
    if not name or not name.isidentifier() or name in (NONE, UNEXPLAINED, INSUFFICIENT_EXCITATION):
        raise ValueError(f"register: {cls.__name__}.name must be an identifier other than 'none', "
                         f"'unexplained' and 'insufficient_excitation', got {name!r}")
    if name in _REGISTRY and _REGISTRY[name] is not cls:
        raise ValueError(f"register: an effect called {name!r} exists ({_REGISTRY[name].__name__})")
    if name in dir(Effects):
        raise ValueError(f"register: {cls.__name__}.name {name!r} is an attribute of Effects; choose another name")
    if not all(isinstance(r, str) for r in cls.requires):
        raise TypeError(f"register: {name}.requires must hold effect names (str), got {cls.requires!r}")
    missing = [r for r in cls.requires if r not in _REGISTRY]
    if missing:
        raise ValueError(f"register: {name} requires unregistered {missing}")
    _REGISTRY[name] = cls
    return cls


def unregister(name: str) -> None:
    """Remove an effect added by :func:`register` (tests); built-in effects cannot be removed."""
    if name in _BUILTIN:
        raise ValueError(f"unregister: {name} is part of the built-in vocabulary")
    _REGISTRY.pop(name, None)


def registered() -> tuple[type[Effect], ...]:
    """Every effect class, in report order."""
    return tuple(_REGISTRY.values())


def names() -> tuple[str, ...]:
    """Every effect name, in report order (without ``none``)."""
    return tuple(_REGISTRY)


def get(name: str) -> type[Effect]:
    """The effect class called ``name``; ValueError listing the known ones otherwise."""
    try:
        return _REGISTRY[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown effect {name!r} (known: {', '.join(_REGISTRY)})") from None


def paper_model() -> tuple[str, ...]:
    """The paper's model: arctan friction + variable-stiffness cables (the baseline effects)."""
    return tuple(c.name for c in _REGISTRY.values() if c.baseline)


def make_effect(name: str, **kwargs: Any) -> Effect:
    """The effect called ``name`` (vocabulary) with its defaults overridden by ``kwargs``."""
    cls = get(name)
    try:
        return cls(**kwargs)
    except TypeError as exc:
        raise ValueError(f"{name}: {exc}") from None


class Effects:
    """The plant's optional effects, at most one per registered name, all off by default.

    ``Effects(viscous_friction=ViscousFriction(...))`` or ``Effects.of(ViscousFriction(...))``;
    ``effects.viscous_friction`` is the effect or None.  Immutable; iteration order is the
    registry's.
    """

    __slots__ = ("_by_name",)

    def __init__(self, **by_name: Effect | None) -> None:
        items = {}
        for name, v in by_name.items():
            cls = get(name)
            if v is None:
                continue
            if not isinstance(v, cls):
                raise ValueError(f"effects.{name}: expected {cls.__name__} or None, got {type(v).__name__}")
            items[name] = v
        order = list(_REGISTRY)
        object.__setattr__(self, "_by_name", dict(sorted(items.items(), key=lambda kv: order.index(kv[0]))))

    def __getattr__(self, name: str):
        if name.startswith("_"):
            raise AttributeError(name)
        if name in _REGISTRY:
            return self._by_name.get(name)
        raise AttributeError(f"Effects has no effect {name!r} (known: {', '.join(_REGISTRY)})")

    def __setattr__(self, name, value):
        raise AttributeError("Effects is immutable: use replace()")

    def __eq__(self, other) -> bool:
        return isinstance(other, Effects) and self._by_name == other._by_name

    def __reduce__(self):
        return (Effects.of, self.active())

    def __hash__(self) -> int:
        return hash(tuple(self._by_name.items()))

    def __repr__(self) -> str:
        return "Effects(" + ", ".join(f"{k}={v!r}" for k, v in self._by_name.items()) + ")"

    def active(self) -> tuple[Effect, ...]:
        return tuple(self._by_name.values())

    def names(self) -> tuple[str, ...]:
        """Names of the active effects, ``("none",)`` when there are none."""
        return tuple(self._by_name) or (NONE,)

    def motor_effects(self) -> tuple[Effect, ...]:
        """Active extra motor forces (the baseline dry friction is not one of them)."""
        return tuple(e for e in self.active() if e.kind == "motor" and not e.baseline)

    def check(self, params: NeckParams) -> None:
        for e in self.active():
            e.check(params)

    def true_params(self, params: NeckParams) -> NeckParams:
        """``params`` with every parameter-changing effect (and baseline override) applied."""
        self.check(params)
        out = params
        for e in self.active():
            out = e.apply(out)
        return out

    def elongation_offset(self, n_cables: int) -> np.ndarray:
        """(n_cables,) m added to the cable elongations (pretension)."""
        out = np.zeros(n_cables)
        for e in self.active():
            out = out + e.elongation_offset(n_cables)
        return out

    def encoder_band(self, n_cables: int) -> np.ndarray:
        """(n_cables,) m of cable: the dead band between each motor and its drum (backlash)."""
        out = np.zeros(n_cables)
        for e in self.active():
            out = out + e.encoder_band(n_cables)
        return out

    def command_delay(self) -> float:
        """s between commanding a force and its acting on the cables."""
        return float(sum(e.command_delay for e in self.active()))

    def camera_lag(self) -> float:
        """s by which a camera frame lags its time stamp (``effects.camera_delay`` is the effect)."""
        return float(sum(e.camera_delay for e in self.active()))

    def replace(self, **kw: Effect | None) -> "Effects":
        return Effects(**{**self._by_name, **kw})

    def to_dict(self) -> dict[str, dict]:
        """Plain dict of the active effects (for run metadata)."""
        return {e.name: e.to_dict() for e in self.active()}

    @classmethod
    def from_dict(cls, data: Mapping[str, Mapping[str, Any]]) -> "Effects":
        """Inverse of :meth:`to_dict`; unknown names raise ValueError."""
        kw = {}
        for name, vals in data.items():
            vals = {k: v for k, v in dict(vals).items() if k != "name"}
            kw[name] = make_effect(name, **vals)
        return cls(**kw)

    @classmethod
    def of(cls, *effects: Effect) -> "Effects":
        """Effects(viscous_friction=ViscousFriction(...), ...) from a list of effects."""
        kw = {}
        for e in effects:
            if e.name in kw:
                raise ValueError(f"effects: {e.name} given twice")
            kw[e.name] = e
        return cls(**kw)

    @classmethod
    def slots(cls) -> tuple[str, ...]:
        """Every name an Effects can hold (the registry)."""
        return names()


for _cls in (DryFriction, ViscousFriction, StribeckFriction, PulleyFriction, CableElasticity, TensionStiffening,
             Payload, SpringError, ActuationDelay, Pretension, JointFriction, CameraDelay, Backlash):
    register(_cls)
_BUILTIN = frozenset(_REGISTRY)

VOCABULARY = names() + (INSUFFICIENT_EXCITATION, NONE, UNEXPLAINED)
"""The built-in names a diagnosis may report (``none``: the model explains the data;
``unexplained``: structure is left that no effect removes)."""

EFFECT_TYPES = _REGISTRY
"""Name -> effect class (a live view of the registry)."""
