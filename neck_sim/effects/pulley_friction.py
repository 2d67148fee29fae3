"""``pulley_friction``: friction at the pulleys growing with the cable tension (capstan-like)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from neck_sim.effects.base import MotorEffect
from neck_sim.validation import finite, indices, per_item

__all__ = ["PulleyFriction"]


@dataclass(frozen=True)
class PulleyFriction(MotorEffect):
    """Friction at the pulleys that grows with the cable tension (capstan-like), per cable.

    f = mu t (2/pi) arctan(c theta_dot): a fraction ``mu`` (dimensionless; a capstan of friction
    coefficient mu_c over a total wrap beta gives mu = exp(mu_c beta) - 1) of the tension t (N)
    is lost while the cable slides, lumped at the motor; ``c`` (s/rad) smooths the sign.
    """

    name: ClassVar[str] = "pulley_friction"
    description: ClassVar[str] = "friction at the pulleys proportional to the cable tension"
    abbreviation: ClassVar[str] = "pulley"            # column heads of tables
    magnitude_field: ClassVar[str] = "mu"
    acts_on_cable_law: ClassVar[bool] = True
    mu: tuple | float = 0.1
    c: float = 0.5
    cables: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "mu", per_item("pulley_friction.mu", self.mu, non_negative=True))
        object.__setattr__(self, "c", finite("pulley_friction.c", self.c, positive=True))
        object.__setattr__(self, "cables", indices("pulley_friction.cables", self.cables))

    def regressor(self, theta_dot, tension):
        td = np.asarray(theta_dot, dtype=float)
        return np.asarray(tension, dtype=float) * (2 / np.pi) * np.arctan(self.c * td)

    def native_fields(self, n_cables):
        return {"pf_mu": self.per_cable(n_cables), "pf_c": np.full(n_cables, self.c)}
