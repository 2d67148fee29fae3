"""``stribeck_friction``: breakaway friction above the dry friction at low speed."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from neck_sim.effects.base import MotorEffect
from neck_sim.validation import finite, indices, per_item

__all__ = ["StribeckFriction"]


@dataclass(frozen=True)
class StribeckFriction(MotorEffect):
    """Breakaway friction higher at low speed than at speed (Stribeck effect).

    f = df exp(-(theta_dot / speed)^2) tanh(theta_dot / smoothing), N along the cable, added
    to the arctan friction of eq (37): at rest the friction reaches f_s + df, above ``speed``
    (rad/s at the motor shaft) it falls back to eq (37).  ``df`` in N; ``smoothing`` (rad/s)
    regularises the sign (a tanh, deliberately not the arctan of eq 37).
    """

    name: ClassVar[str] = "stribeck_friction"
    description: ClassVar[str] = "breakaway friction above the dry friction at low speed"
    abbreviation: ClassVar[str] = "strib"            # column heads of tables
    magnitude_field: ClassVar[str] = "df"
    requires: ClassVar[tuple] = ("dry_friction",)      # a breakaway bump on top of dry friction
    df: tuple | float = 5.0
    speed: float = 5.0
    smoothing: float = 0.5
    cables: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "df", per_item("stribeck_friction.df", self.df, non_negative=True))
        object.__setattr__(self, "speed", finite("stribeck_friction.speed", self.speed, positive=True))
        object.__setattr__(self, "smoothing", finite("stribeck_friction.smoothing", self.smoothing, positive=True))
        object.__setattr__(self, "cables", indices("stribeck_friction.cables", self.cables))

    def regressor(self, theta_dot, tension=None):
        td = np.asarray(theta_dot, dtype=float)
        return np.exp(-(td / self.speed) ** 2) * np.tanh(td / self.smoothing)

    def native_fields(self, n_cables):
        return {"st_df": self.per_cable(n_cables), "st_speed": np.full(n_cables, self.speed),
                "st_smooth": np.full(n_cables, self.smoothing)}
