"""``tension_stiffening``: cable stiffness growing with tension, lambda of eq (54) -- in the paper's model."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from neck_sim.effects.base import Column, Design, Effect, Hidden, per_item
from neck_sim.effects.cable_elasticity import CableElasticity
from neck_sim.params import NeckParams

__all__ = ["TensionStiffening"]


@dataclass(frozen=True)
class TensionStiffening(Effect):
    """Stiffness growing with tension, lambda (1/m) of eq (54): t = (k + lambda t) x + c_a x_dot.

    Baseline (``params.cables.lam``); ``lam`` has one value per cable (m, the routing's), ``None`` keeps it.
    """

    name: ClassVar[str] = "tension_stiffening"
    description: ClassVar[str] = "cable stiffness growing with tension, lambda of eq (54)"
    abbreviation: ClassVar[str] = "stiff"            # column heads of tables
    kind: ClassVar[str] = "params"
    baseline: ClassVar[bool] = True
    acts_on_cable_law: ClassVar[bool] = True
    uses_tension: ClassVar[bool] = True
    requires: ClassVar[tuple] = (CableElasticity.name,)
    columns: ClassVar[tuple] = (Column("lambda", "1/m"),)
    blind_magnitude: ClassVar[float] = 1.0      # scale of the paper's lambda (baseline with linear cables)
    blind_unit: ClassVar[str] = "x Table 2 lambda"
    lam: tuple | None = None

    def __post_init__(self):
        if self.lam is not None:
            object.__setattr__(self, "lam", tuple(np.atleast_1d(per_item("tension_stiffening.lam", self.lam,
                                                                         non_negative=True)).tolist()))

    @classmethod
    def from_params(cls, params: NeckParams) -> "TensionStiffening":
        return cls(lam=params.cables.lam)

    def apply(self, params: NeckParams) -> NeckParams:
        return params if self.lam is None else params.replace(**{"cables.lam": self.lam})

    @classmethod
    def design(cls, data, shape, context):
        """Cable block of eq (54): lambda x_c t, with the previous pass's tension estimate."""
        cable = (context.x * context.tension)[:, :, None] * np.eye(data.C)
        return Design(np.zeros((data.S, data.n, data.C)), cable)

    @classmethod
    def to_plant(cls, params, values, shape):
        return cls(lam=tuple(np.clip(values["lambda"], 0.0, None))).apply(params), None

    @classmethod
    def when_absent(cls, params, elastic):
        return cls(lam=(0.0,) * params.n_cables).apply(params) if elastic else params

    @classmethod
    def hide(cls, params, rng, magnitude, cable, joint):
        lam = tuple(np.asarray(params.cables.lam) * magnitude)
        desc = f"tension stiffening, lambda = {magnitude:.2f} x Table 2"
        return Hidden(params, (cls(lam=lam),), tuple(range(params.n_cables)), (), desc, cls.name)
