"""``tension_stiffening``: cable stiffness growing with tension, lambda of eq (54) -- in the paper's model."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from neck_sim.effects.base import Effect
from neck_sim.params import NeckParams
from neck_sim.validation import per_item

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
    requires: ClassVar[tuple] = ("cable_elasticity",)
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
