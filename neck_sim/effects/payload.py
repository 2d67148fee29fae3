"""``payload``: an unmodelled point mass at the head."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from neck_sim.analytic import linkage_dynamics
from neck_sim.effects.base import Column, Design, Effect, Hidden, finite
from neck_sim.params import NeckParams

__all__ = ["Payload", "payload_torque"]


def payload_torque(alpha, alpha_dot, alpha_ddot, params: NeckParams) -> np.ndarray:
    """Joint torque (S, N) N m of 1 kg more at the head on the motion (S, N) rad, rad/s, rad/s^2:
    the difference of the linkage dynamics (M alpha_ddot + c + g, eq 30) with and without it."""
    lk = linkage_dynamics(alpha, alpha_dot, params)
    lk1 = linkage_dynamics(alpha, alpha_dot, params.replace(**{"inertia.payload_mass": params.inertia.payload_mass + 1.0}))
    return np.einsum("sij,sj->si", lk1.M - lk.M, alpha_ddot) + (lk1.c - lk.c) + (lk1.g - lk.g)


@dataclass(frozen=True)
class Payload(Effect):
    """An unmodelled point mass ``mass`` (kg) at the head: the centre of the top bar of joint N.

    Maps to ``params.inertia.payload_mass`` (which the analytic model also understands).
    """

    name: ClassVar[str] = "payload"
    description: ClassVar[str] = "an unmodelled mass at the head"
    abbreviation: ClassVar[str] = "payload"            # column heads of tables
    kind: ClassVar[str] = "params"
    columns: ClassVar[tuple] = (Column("payload", "kg", per="one"),)
    blind_magnitude: ClassVar[float] = 0.08     # kg at the head
    blind_unit: ClassVar[str] = "kg"
    mass: float = 0.05

    def __post_init__(self):
        object.__setattr__(self, "mass", finite("payload.mass", self.mass, non_negative=True))

    def apply(self, params: NeckParams) -> NeckParams:
        return params.replace(**{"inertia.payload_mass": params.inertia.payload_mass + self.mass})

    @classmethod
    def design(cls, data, shape, context):
        """Torque block: the torque of 1 kg at the head (eq 51's linkage side)."""
        torque = data.cached(cls.name, lambda: payload_torque(data.alpha, data.prep.alpha_dot, data.prep.alpha_ddot,
                                                              data.params))
        return Design(torque[:, :, None], np.zeros((data.S, data.C, 1)))

    @classmethod
    def to_plant(cls, params, values, shape):
        return cls(mass=max(float(values["payload"][0]), 0.0)).apply(params), None

    @classmethod
    def hide(cls, params, rng, magnitude, cable, joint):
        return Hidden(params, (cls(mass=magnitude),), (), (), f"payload {1e3 * magnitude:.0f} g at the head", cls.name)
