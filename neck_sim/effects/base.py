"""The protocol every effect of the vocabulary answers (one module per effect in this package).

An effect is a frozen dataclass: its instance fields are its parameters (SI units, validated in
``__post_init__`` with the parameter named), its class attributes and methods say everything else
about it.  Three audiences read an effect; this package serves the first:

**The plant** (:mod:`neck_sim.plant`) hides the effect in a simulation through whichever hooks the
effect overrides (the defaults do nothing):

* ``apply(params)`` -- the true constants (``"params"`` effects, baseline overrides);
* ``motor_force(theta_dot, tension)`` -- ``kind = "motor"``: an extra force (N) along the cable
  resisting the motor speed, added to eq (37): ``I_a theta_ddot = (r_d/R)(f - t - f_friction -
  extra)``.  ``native_fields(n_cables)`` hands the same law to the C callback (members of the
  ``neck_plant`` struct of ``neck_sim/native/plant_callback.c``); ``None`` = no native kernel (the
  plant then needs ``backend="python"``);
* ``elongation_offset(n_cables)`` -- m added to every cable elongation (pretension);
* ``encoder_band(n_cables)`` -- ``kind = "encoder"``: a dead band (m of cable) between each motor
  shaft, which carries the encoder, and its drum (backlash);
* ``command_delay`` (s) -- the commanded force acts that much later; ``camera_delay`` (s) -- a
  camera frame stamped t shows the neck at t - camera_delay;
* ``setup_mujoco(model, data, index)`` -- edit MuJoCo's compiled model or data directly
  (``dof_frictionloss``, ``qfrc_applied``, ...): MuJoCo-native mechanisms; called after every reset.

``requires`` names (strings) the effects this one is defined on top of (Stribeck friction on dry
friction, stiffening and pretension on elastic cables): they must be registered before it, and a
diagnosis model holding this effect holds them too.

The other audiences live elsewhere, keyed by the effect's name: how the diagnosis fits the effect
(regressor columns, shape parameters, the map back to the plant) in
:mod:`identification.diagnosis.columns`, how the blind tests hide it in
:mod:`identification.diagnosis.blind_forms`.

Indices of per-cable arrays follow the routing's cables (``params.routing.cables``, m of them; on
the paper's routing 0..N-1 the right cables c1..cN, N the long left cable); per-joint arrays have N.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np

from neck_sim.params import NeckParams

__all__ = ["Effect", "MotorEffect"]


# ------------------------------------------------------------------------------------- effects

@dataclass(frozen=True)
class Effect:
    """Base of every effect; see the module docstring for the protocol."""

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""       # one line, the vocabulary table
    abbreviation: ClassVar[str] = ""      # a few letters for table columns (default: the name)
    kind: ClassVar[str] = ""              # motor | params | command | elongation | camera | mujoco
    baseline: ClassVar[bool] = False      # part of the paper's model (lives in NeckParams)
    magnitude_field: ClassVar[str] = ""   # the field the effect's force is linear in
    # plant
    acts_on_cable_law: ClassVar[bool] = False   # moot with rigid cables (refused there)
    command_delay: ClassVar[float] = 0.0
    camera_delay: ClassVar[float] = 0.0
    requires: ClassVar[tuple[str, ...]] = ()    # names of the effects this one builds on

    # -- parameters
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
            cables = getattr(self, "cables", None)
            want = len(cables) if cables is not None else n_c
            if len(mag) != want:
                raise ValueError(f"{self.name}.{self.magnitude_field}: {len(mag)} values for {want} affected cables")

    def per_cable(self, n_cables: int) -> np.ndarray:
        """The magnitude as an (n_cables,) array, zero on unaffected cables."""
        mag, cables = getattr(self, self.magnitude_field), getattr(self, "cables")   # per-cable effects declare cables
        out = np.zeros(n_cables)
        idx = np.arange(n_cables) if cables is None else np.asarray(cables)
        out[idx] = mag
        return out

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"name": self.name}
        for f in fields(self):
            v = getattr(self, f.name)
            d[f.name] = list(v) if isinstance(v, tuple) else v
        return d

    # -- plant hooks (defaults: no action)
    def apply(self, params: NeckParams) -> NeckParams:
        """The plant's true constants with this effect."""
        return params

    def native_fields(self, n_cables: int) -> dict[str, np.ndarray] | None:
        """``neck_plant`` struct member -> (n_cables,) values of a motor effect; None: no native kernel."""
        return None

    def elongation_offset(self, n_cables: int) -> np.ndarray:
        """(n_cables,) m added to every elongation."""
        return np.zeros(n_cables)

    def encoder_band(self, n_cables: int) -> np.ndarray:
        """(n_cables,) m of cable: a dead band between each motor shaft (the encoder) and its drum
        (``kind = "encoder"``; the plant keeps the motor's lead, see :mod:`neck_sim.effects.backlash`)."""
        return np.zeros(n_cables)

    def setup_mujoco(self, model: Any, data: Any, index: Any) -> None:
        """Edit the compiled MuJoCo model/data (``index``: :func:`neck_sim.mjcf.model_index`);
        called after every reset, so it must set values, not accumulate them."""


@dataclass(frozen=True)
class MotorEffect(Effect):
    """An extra force along the cable, linear in ``magnitude_field`` (per cable): force =
    magnitude x ``regressor(theta_dot, tension)`` (its diagnosis columns follow from that:
    :class:`identification.diagnosis.columns.MotorColumns`)."""

    kind: ClassVar[str] = "motor"

    def regressor(self, theta_dot: np.ndarray, tension: np.ndarray | None = None) -> np.ndarray:
        """d force / d magnitude, (..., C)."""
        raise NotImplementedError

    def motor_force(self, theta_dot: np.ndarray, tension: np.ndarray | None = None) -> np.ndarray:
        """Force (N) along each cable resisting the motor speed ``theta_dot`` (..., C) rad/s."""
        td = np.asarray(theta_dot, dtype=float)
        return self.per_cable(td.shape[-1]) * self.regressor(td, tension)

    @classmethod
    def unit(cls, shape: dict) -> "MotorEffect":
        """The effect with magnitude 1 on every cable and the given shape."""
        return cls(**{cls.magnitude_field: 1.0}, **shape)
