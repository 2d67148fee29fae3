"""``viscous_friction``: friction proportional to the motor speed."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from neck_sim.effects.base import MotorEffect
from neck_sim.validation import indices, per_item

__all__ = ["ViscousFriction"]


@dataclass(frozen=True)
class ViscousFriction(MotorEffect):
    """Friction proportional to motor speed: f = c_v theta_dot (N along the cable).

    ``c_v`` in N s/rad (per affected cable or one value for all): 0.2 N s/rad gives about 7 N
    at a cable speed of 3 cm/s (theta_dot = 37 rad/s).
    """

    name: ClassVar[str] = "viscous_friction"
    description: ClassVar[str] = "friction proportional to the motor speed"
    abbreviation: ClassVar[str] = "visc"            # column heads of tables
    magnitude_field: ClassVar[str] = "c_v"
    c_v: tuple | float = 0.2
    cables: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "c_v", per_item("viscous_friction.c_v", self.c_v, non_negative=True))
        object.__setattr__(self, "cables", indices("viscous_friction.cables", self.cables))

    def regressor(self, theta_dot, tension=None):
        return np.asarray(theta_dot, dtype=float)

    def native_fields(self, n_cables):
        return {"c_v": self.per_cable(n_cables)}
