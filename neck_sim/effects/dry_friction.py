"""``dry_friction``: arctan dry friction at the geared motors, eq (37) -- in the paper's model."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from neck_sim.effects.base import MotorEffect
from neck_sim.params import NeckParams
from neck_sim.validation import finite, indices, per_item

__all__ = ["DryFriction"]

# eq (37) is neck_sim.analytic.dynamics.arctan_friction, imported where it is used: the analytic
# model loads numba (0.3-0.9 s), which importing the vocabulary (its classes, their validation and
# apply) does not need.


@dataclass(frozen=True)
class DryFriction(MotorEffect):
    """Arctan dry friction at the geared motors, eq (37) -- baseline (``params.friction``).

    f = (2/pi) arctan(c_s theta_dot) f_s, force along the cable (N) resisting the motor speed
    theta_dot (rad/s at the motor shaft).  ``f_s`` (N, per cable) and ``c_s`` (s/rad) override
    ``params.friction`` when the effect is given to a plant; ``None`` keeps the parameter.
    """

    name: ClassVar[str] = "dry_friction"
    description: ClassVar[str] = "arctan dry friction at the motors, eq (37)"
    abbreviation: ClassVar[str] = "dry"            # column heads of tables
    baseline: ClassVar[bool] = True
    magnitude_field: ClassVar[str] = "f_s"
    f_s: tuple | float | None = None
    c_s: float | None = None
    cables: tuple | None = None

    def __post_init__(self):
        if self.f_s is not None:
            object.__setattr__(self, "f_s", per_item("dry_friction.f_s", self.f_s, non_negative=True))
        if self.c_s is not None:
            object.__setattr__(self, "c_s", finite("dry_friction.c_s", self.c_s, positive=True))
        object.__setattr__(self, "cables", indices("dry_friction.cables", self.cables))

    @classmethod
    def from_params(cls, params: NeckParams) -> "DryFriction":
        return cls(f_s=params.friction.f_s, c_s=params.friction.c_s)

    def resolved(self, params: NeckParams) -> tuple[np.ndarray, float]:
        """(f_s (m,), c_s) after applying this override to ``params``."""
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
        td = np.asarray(theta_dot, dtype=float)
        fs, cs = self.resolved(params) if params is not None else (self.per_cable(td.shape[-1]), self.c_s)
        from neck_sim.analytic.dynamics import arctan_friction

        return arctan_friction(td, cs, fs)

    def regressor(self, theta_dot, tension=None, params: NeckParams | None = None):
        """d force / d f_s = (2/pi) arctan(c_s theta_dot), (..., m)."""
        from neck_sim.analytic.dynamics import arctan_friction

        cs = self.c_s if self.c_s is not None else params.friction.c_s
        return arctan_friction(np.asarray(theta_dot, dtype=float), cs, 1.0)

    # the plant applies eq (37) from params.friction (apply); no extra native force
