"""The effect vocabulary: one definition per physical effect (names of ``measured-data.md``).

The plant uses these definitions to *hide* an effect in simulated data; the diagnosis (issue 7)
uses the same definitions to *look* for it.  Every effect is a frozen dataclass whose docstring
states its physics and units, with

* ``name`` -- its vocabulary name, ``kind`` -- where it acts:

  ``"motor"``       an extra force along the cable, resisting the motor speed (N), added to the
                    friction of eq (29): ``I_a theta_ddot = (r_d/R)(f - t - f_friction - extra)``;
                    ``motor_force(theta_dot, tension)`` gives it and ``regressor(theta_dot,
                    tension)`` its derivative with respect to the effect's magnitude (the force
                    is linear in the magnitude), the column a least-squares diagnosis needs.
  ``"params"``      a change of the plant's constants: ``apply(params)`` returns the true ones.
  ``"command"``     acts on the commanded force (``delayed_index``).
  ``"elongation"``  an offset of the cable elongation x_c (``elongation_offset``).

* ``parameter_names()`` -- stable names of its parameters (``"<name>.<field>"``), the hook by
  which a diagnosis reports an identified value, and ``parameters(n_cables)`` their values.
* ``cables`` (0-based cable indices) or ``joints`` (0-based joint indices) it affects; ``None``
  means all.

``dry_friction``, ``cable_elasticity`` and ``tension_stiffening`` are the baseline plant's own
parameters (``NeckParams.friction.f_s/c_s``, ``cables.k/c_a``, ``cables.lam``): they are in the
paper's model and always present.  Their classes here map to those fields (``from_params``,
``apply``) so that a diagnosis can name them and a plant option can override them.

Indices of per-cable arrays: 0..N-1 the right cables c1..cN, N the long left cable.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, fields
from typing import Any, ClassVar, Mapping

import numpy as np

from neck_sim.params import NeckParams

__all__ = ["VOCABULARY", "Effect", "DryFriction", "ViscousFriction", "StribeckFriction", "PulleyFriction",
           "CableElasticity", "TensionStiffening", "Payload", "SpringError", "ActuationDelay", "Pretension",
           "Effects", "EFFECT_TYPES", "make_effect"]

VOCABULARY = ("dry_friction", "viscous_friction", "stribeck_friction", "pulley_friction", "cable_elasticity",
              "tension_stiffening", "payload", "spring_error", "actuation_delay", "pretension", "none")
"""Every name a diagnosis may report (``none``: the model explains the data)."""


def _finite(name: str, v: float, *, positive: bool = False, non_negative: bool = False) -> float:
    try:
        v = float(v)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: not a number ({v!r})") from None
    if not math.isfinite(v):
        raise ValueError(f"{name}: must be finite, got {v!r}")
    if positive and v <= 0:
        raise ValueError(f"{name}: must be > 0, got {v!r}")
    if non_negative and v < 0:
        raise ValueError(f"{name}: must be >= 0, got {v!r}")
    return v


def _indices(name: str, v) -> tuple[int, ...] | None:
    if v is None:
        return None
    try:
        out = tuple(int(i) for i in (v if hasattr(v, "__iter__") else [v]))
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a list of 0-based indices, got {v!r}") from None
    if any(i < 0 for i in out) or len(set(out)) != len(out) or not out:
        raise ValueError(f"{name}: expected distinct non-negative 0-based indices, got {v!r}")
    return out


def _per_item(name: str, v, *, positive=False, non_negative=False) -> tuple[float, ...] | float:
    """A scalar or a tuple of values (one per affected cable/joint)."""
    if np.ndim(v) == 0:
        return _finite(name, v, positive=positive, non_negative=non_negative)
    return tuple(_finite(f"{name}[{k}]", x, positive=positive, non_negative=non_negative) for k, x in enumerate(v))


@dataclass(frozen=True)
class Effect:
    """Base of every effect; see the module docstring for the protocol."""

    name: ClassVar[str] = ""
    kind: ClassVar[str] = ""
    baseline: ClassVar[bool] = False      # part of the paper's model (lives in NeckParams)
    magnitude_field: ClassVar[str] = ""   # the field a motor effect's force is linear in

    def parameter_names(self) -> tuple[str, ...]:
        """``"<name>.<field>"`` of every numeric parameter of the effect."""
        return tuple(f"{self.name}.{f.name}" for f in fields(self) if f.name not in ("cables", "joints"))

    def parameters(self, n_cables: int | None = None) -> dict[str, Any]:
        """Parameter name -> value (per-cable values expanded to (n_cables,) when given)."""
        out = {}
        for f in fields(self):
            if f.name in ("cables", "joints"):
                continue
            v = getattr(self, f.name)
            if n_cables is not None and f.name == self.magnitude_field and hasattr(self, "cables") and v is not None:
                v = self.per_cable(n_cables)
            out[f"{self.name}.{f.name}"] = v
        return out

    def check(self, params: NeckParams) -> None:
        """Raise ValueError naming the problem if the effect does not fit this neck."""
        n_c, n_j = params.n_cables, params.n_joints
        for attr, limit, what in (("cables", n_c, "cable"), ("joints", n_j, "joint")):
            idx = getattr(self, attr, None)
            if idx is not None and max(idx) >= limit:
                raise ValueError(f"{self.name}.{attr}: index {max(idx)} out of range for {limit} {what}s "
                                 f"(0-based; this neck has N = {n_j} joints)")
        mag = getattr(self, self.magnitude_field, None) if self.magnitude_field else None
        if isinstance(mag, tuple):
            want = len(self.cables) if getattr(self, "cables", None) is not None else n_c
            if len(mag) != want:
                raise ValueError(f"{self.name}.{self.magnitude_field}: {len(mag)} values for {want} affected cables")

    def per_cable(self, n_cables: int) -> np.ndarray:
        """The magnitude as an (n_cables,) array, zero on unaffected cables."""
        mag = getattr(self, self.magnitude_field)
        out = np.zeros(n_cables)
        idx = np.arange(n_cables) if self.cables is None else np.asarray(self.cables)
        out[idx] = mag
        return out

    def to_dict(self) -> dict[str, Any]:
        d = {"name": self.name}
        for f in fields(self):
            v = getattr(self, f.name)
            d[f.name] = list(v) if isinstance(v, tuple) else v
        return d


# ---------------------------------------------------------------------------------- motor side

@dataclass(frozen=True)
class DryFriction(Effect):
    """Arctan dry friction at the geared motors, eq (37) -- baseline (``params.friction``).

    f = (2/pi) arctan(c_s theta_dot) f_s, force along the cable (N) resisting the motor speed
    theta_dot (rad/s at the motor shaft).  ``f_s`` (N, per cable) and ``c_s`` (s/rad) override
    ``params.friction`` when the effect is given to a plant; ``None`` keeps the parameter.
    """

    name: ClassVar[str] = "dry_friction"
    kind: ClassVar[str] = "motor"
    baseline: ClassVar[bool] = True
    magnitude_field: ClassVar[str] = "f_s"
    f_s: tuple | float | None = None
    c_s: float | None = None
    cables: tuple | None = None

    def __post_init__(self):
        if self.f_s is not None:
            object.__setattr__(self, "f_s", _per_item("dry_friction.f_s", self.f_s, non_negative=True))
        if self.c_s is not None:
            object.__setattr__(self, "c_s", _finite("dry_friction.c_s", self.c_s, positive=True))
        object.__setattr__(self, "cables", _indices("dry_friction.cables", self.cables))

    @classmethod
    def from_params(cls, params: NeckParams) -> "DryFriction":
        return cls(f_s=params.friction.f_s, c_s=params.friction.c_s)

    def resolved(self, params: NeckParams) -> tuple[np.ndarray, float]:
        """(f_s (N+1,), c_s) after applying this override to ``params``."""
        fs = np.asarray(params.friction.f_s, dtype=float).copy()
        if self.f_s is not None:
            idx = np.arange(params.n_cables) if self.cables is None else np.asarray(self.cables)
            fs[idx] = self.f_s
        return fs, (params.friction.c_s if self.c_s is None else self.c_s)

    def apply(self, params: NeckParams) -> NeckParams:
        fs, cs = self.resolved(params)
        return params.replace(**{"friction.f_s": tuple(fs), "friction.c_s": cs})

    def motor_force(self, theta_dot, tension=None, params: NeckParams | None = None):
        if params is None and (self.f_s is None or self.c_s is None):
            raise ValueError("dry_friction.motor_force: needs params when f_s or c_s is not set")
        fs, cs = self.resolved(params) if params is not None else (np.asarray(self.f_s, float), self.c_s)
        return (2 / np.pi) * np.arctan(cs * np.asarray(theta_dot, dtype=float)) * fs

    def regressor(self, theta_dot, tension=None, params: NeckParams | None = None):
        """d force / d f_s = (2/pi) arctan(c_s theta_dot), (..., N+1)."""
        cs = self.c_s if self.c_s is not None else params.friction.c_s
        return (2 / np.pi) * np.arctan(cs * np.asarray(theta_dot, dtype=float))


@dataclass(frozen=True)
class ViscousFriction(Effect):
    """Friction proportional to motor speed: f = c_v theta_dot (N along the cable).

    ``c_v`` in N s/rad (per affected cable or one value for all): 0.2 N s/rad gives about 7 N
    at a cable speed of 3 cm/s (theta_dot = 37 rad/s).
    """

    name: ClassVar[str] = "viscous_friction"
    kind: ClassVar[str] = "motor"
    magnitude_field: ClassVar[str] = "c_v"
    c_v: tuple | float = 0.2
    cables: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "c_v", _per_item("viscous_friction.c_v", self.c_v, non_negative=True))
        object.__setattr__(self, "cables", _indices("viscous_friction.cables", self.cables))

    def regressor(self, theta_dot, tension=None):
        return np.asarray(theta_dot, dtype=float)

    def motor_force(self, theta_dot, tension=None):
        td = np.asarray(theta_dot, dtype=float)
        return self.per_cable(td.shape[-1]) * self.regressor(td)


@dataclass(frozen=True)
class StribeckFriction(Effect):
    """Breakaway friction higher at low speed than at speed (Stribeck effect).

    f = df exp(-(theta_dot / speed)^2) tanh(theta_dot / smoothing), N along the cable, added
    to the arctan friction of eq (37): at rest the friction reaches f_s + df, above ``speed``
    (rad/s at the motor shaft) it falls back to eq (37).  ``df`` in N; ``smoothing`` (rad/s)
    regularises the sign (a tanh, deliberately not the arctan of eq 37).
    """

    name: ClassVar[str] = "stribeck_friction"
    kind: ClassVar[str] = "motor"
    magnitude_field: ClassVar[str] = "df"
    df: tuple | float = 5.0
    speed: float = 5.0
    smoothing: float = 0.5
    cables: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "df", _per_item("stribeck_friction.df", self.df, non_negative=True))
        object.__setattr__(self, "speed", _finite("stribeck_friction.speed", self.speed, positive=True))
        object.__setattr__(self, "smoothing", _finite("stribeck_friction.smoothing", self.smoothing, positive=True))
        object.__setattr__(self, "cables", _indices("stribeck_friction.cables", self.cables))

    def regressor(self, theta_dot, tension=None):
        td = np.asarray(theta_dot, dtype=float)
        return np.exp(-(td / self.speed) ** 2) * np.tanh(td / self.smoothing)

    def motor_force(self, theta_dot, tension=None):
        td = np.asarray(theta_dot, dtype=float)
        return self.per_cable(td.shape[-1]) * self.regressor(td)


@dataclass(frozen=True)
class PulleyFriction(Effect):
    """Friction at the pulleys that grows with the cable tension (capstan-like), per cable.

    f = mu t (2/pi) arctan(c theta_dot): a fraction ``mu`` (dimensionless; a capstan of friction
    coefficient mu_c over a total wrap beta gives mu = exp(mu_c beta) - 1) of the tension t (N)
    is lost while the cable slides, lumped at the motor; ``c`` (s/rad) smooths the sign.
    """

    name: ClassVar[str] = "pulley_friction"
    kind: ClassVar[str] = "motor"
    magnitude_field: ClassVar[str] = "mu"
    mu: tuple | float = 0.1
    c: float = 0.5
    cables: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "mu", _per_item("pulley_friction.mu", self.mu, non_negative=True))
        object.__setattr__(self, "c", _finite("pulley_friction.c", self.c, positive=True))
        object.__setattr__(self, "cables", _indices("pulley_friction.cables", self.cables))

    def regressor(self, theta_dot, tension):
        td = np.asarray(theta_dot, dtype=float)
        return np.asarray(tension, dtype=float) * (2 / np.pi) * np.arctan(self.c * td)

    def motor_force(self, theta_dot, tension):
        td = np.asarray(theta_dot, dtype=float)
        return self.per_cable(td.shape[-1]) * self.regressor(td, tension)


# -------------------------------------------------------------------------------------- cables

@dataclass(frozen=True)
class CableElasticity(Effect):
    """Linear cable stiffness k (N/m) and damping c_a (N s/m), eq (39) -- baseline (``params.cables``).

    ``None`` keeps the parameter; tuples have one value per cable (N+1).
    """

    name: ClassVar[str] = "cable_elasticity"
    kind: ClassVar[str] = "params"
    baseline: ClassVar[bool] = True
    k: tuple | None = None
    c_a: tuple | None = None

    def __post_init__(self):
        for nm in ("k", "c_a"):
            v = getattr(self, nm)
            if v is not None:
                object.__setattr__(self, nm, tuple(np.atleast_1d(_per_item(f"cable_elasticity.{nm}", v,
                                                                           non_negative=True)).tolist()))

    @classmethod
    def from_params(cls, params: NeckParams) -> "CableElasticity":
        return cls(k=params.cables.k, c_a=params.cables.c_a)

    def apply(self, params: NeckParams) -> NeckParams:
        changes = {f"cables.{nm}": getattr(self, nm) for nm in ("k", "c_a") if getattr(self, nm) is not None}
        return params.replace(**changes) if changes else params


@dataclass(frozen=True)
class TensionStiffening(Effect):
    """Stiffness growing with tension, lambda (1/m) of eq (54): t = (k + lambda t) x + c_a x_dot.

    Baseline (``params.cables.lam``); ``lam`` has one value per cable (N+1), ``None`` keeps it.
    """

    name: ClassVar[str] = "tension_stiffening"
    kind: ClassVar[str] = "params"
    baseline: ClassVar[bool] = True
    lam: tuple | None = None

    def __post_init__(self):
        if self.lam is not None:
            object.__setattr__(self, "lam", tuple(np.atleast_1d(_per_item("tension_stiffening.lam", self.lam,
                                                                          non_negative=True)).tolist()))

    @classmethod
    def from_params(cls, params: NeckParams) -> "TensionStiffening":
        return cls(lam=params.cables.lam)

    def apply(self, params: NeckParams) -> NeckParams:
        return params if self.lam is None else params.replace(**{"cables.lam": self.lam})


@dataclass(frozen=True)
class Pretension(Effect):
    """Cables already stretched at the rest pose: x_c(0) = ``elongation`` (m) instead of 0.

    The encoders are zeroed at the straight pose with the cables stretched: the plant's
    elongation is x_c = l_c - l_c0 + (r_d/R) theta + elongation, invisible to the encoders.
    1 mm on cable 1 is about 5.5 N of tension at rest.
    """

    name: ClassVar[str] = "pretension"
    kind: ClassVar[str] = "elongation"
    magnitude_field: ClassVar[str] = "elongation"
    elongation: tuple | float = 1e-3
    cables: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "elongation", _per_item("pretension.elongation", self.elongation))
        object.__setattr__(self, "cables", _indices("pretension.cables", self.cables))

    def elongation_offset(self, n_cables: int) -> np.ndarray:
        """(n_cables,) m added to every elongation."""
        return self.per_cable(n_cables)


# ------------------------------------------------------------------------------------ linkage

@dataclass(frozen=True)
class Payload(Effect):
    """An unmodelled point mass ``mass`` (kg) at the head: the centre of the top bar of joint N.

    Maps to ``params.inertia.payload_mass`` (which the analytic model also understands).
    """

    name: ClassVar[str] = "payload"
    kind: ClassVar[str] = "params"
    mass: float = 0.05

    def __post_init__(self):
        object.__setattr__(self, "mass", _finite("payload.mass", self.mass, non_negative=True))

    def apply(self, params: NeckParams) -> NeckParams:
        return params.replace(**{"inertia.payload_mass": params.inertia.payload_mass + self.mass})


@dataclass(frozen=True)
class SpringError(Effect):
    """Side springs differ from nominal: stiffness times ``stiffness_scale`` on ``joints`` and
    rest length plus ``rest_length_offset`` (m, every spring: the parameter module has one rest
    length).  Maps to ``params.springs``.
    """

    name: ClassVar[str] = "spring_error"
    kind: ClassVar[str] = "params"
    stiffness_scale: float = 1.2
    rest_length_offset: float = 0.0
    joints: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "stiffness_scale", _finite("spring_error.stiffness_scale", self.stiffness_scale,
                                                            non_negative=True))
        object.__setattr__(self, "rest_length_offset", _finite("spring_error.rest_length_offset",
                                                               self.rest_length_offset))
        object.__setattr__(self, "joints", _indices("spring_error.joints", self.joints))

    def apply(self, params: NeckParams) -> NeckParams:
        k = np.asarray(params.springs.stiffness, dtype=float).copy()
        idx = np.arange(params.n_joints) if self.joints is None else np.asarray(self.joints)
        k[idx] *= self.stiffness_scale
        return params.replace(**{"springs.stiffness": tuple(k),
                                 "springs.rest_length": params.springs.rest_length + self.rest_length_offset})


# ------------------------------------------------------------------------------------- command

@dataclass(frozen=True)
class ActuationDelay(Effect):
    """The commanded force reaches the cable ``delay`` seconds after it is commanded.

    The delay line starts filled with the first command (no startup transient).
    """

    name: ClassVar[str] = "actuation_delay"
    kind: ClassVar[str] = "command"
    delay: float = 0.006

    def __post_init__(self):
        object.__setattr__(self, "delay", _finite("actuation_delay.delay", self.delay, non_negative=True))

    def delayed_index(self, t, command_times) -> np.ndarray:
        """Index of the command in force at times ``t``: the last issued at or before t - delay
        (0 before the first command takes effect).  ``command_times`` sorted, s."""
        k = np.searchsorted(np.asarray(command_times), np.asarray(t, dtype=float) - self.delay + 1e-12,
                            side="right") - 1
        return np.maximum(k, 0)


# -------------------------------------------------------------------------------------- options

EFFECT_TYPES: dict[str, type[Effect]] = {cls.name: cls for cls in (
    DryFriction, ViscousFriction, StribeckFriction, PulleyFriction, CableElasticity, TensionStiffening,
    Payload, SpringError, ActuationDelay, Pretension)}


def make_effect(name: str, **kwargs) -> Effect:
    """The effect called ``name`` (vocabulary) with its defaults overridden by ``kwargs``."""
    try:
        cls = EFFECT_TYPES[name]
    except KeyError:
        raise ValueError(f"unknown effect {name!r} (known: {', '.join(EFFECT_TYPES)})") from None
    try:
        return cls(**kwargs)
    except TypeError as exc:
        raise ValueError(f"{name}: {exc}") from None


@dataclass(frozen=True)
class Effects:
    """The plant's optional effects, one field per vocabulary name, all off (None) by default."""

    dry_friction: DryFriction | None = None
    viscous_friction: ViscousFriction | None = None
    stribeck_friction: StribeckFriction | None = None
    pulley_friction: PulleyFriction | None = None
    cable_elasticity: CableElasticity | None = None
    tension_stiffening: TensionStiffening | None = None
    payload: Payload | None = None
    spring_error: SpringError | None = None
    actuation_delay: ActuationDelay | None = None
    pretension: Pretension | None = None

    def __post_init__(self):
        for f in fields(self):
            v = getattr(self, f.name)
            if v is not None and not isinstance(v, EFFECT_TYPES[f.name]):
                raise ValueError(f"effects.{f.name}: expected {EFFECT_TYPES[f.name].__name__} or None, "
                                 f"got {type(v).__name__}")

    def active(self) -> tuple[Effect, ...]:
        return tuple(v for f in fields(self) if (v := getattr(self, f.name)) is not None)

    def names(self) -> tuple[str, ...]:
        """Names of the active effects, ``("none",)`` when there are none."""
        return tuple(e.name for e in self.active()) or ("none",)

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
            if hasattr(e, "apply"):
                out = e.apply(out)
        return out

    def elongation_offset(self, n_cables: int) -> np.ndarray:
        return np.zeros(n_cables) if self.pretension is None else self.pretension.elongation_offset(n_cables)

    def replace(self, **kw) -> "Effects":
        return dataclasses.replace(self, **kw)

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
