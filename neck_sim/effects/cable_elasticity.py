"""``cable_elasticity``: linear cable stiffness and damping, eq (39) -- in the paper's model."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from neck_sim.effects.base import Effect
from neck_sim.params import NeckParams
from neck_sim.validation import per_item

__all__ = ["CableElasticity"]


@dataclass(frozen=True)
class CableElasticity(Effect):
    """Linear cable stiffness k (N/m) and damping c_a (N s/m), eq (39) -- baseline (``params.cables``).

    ``None`` keeps the parameter; tuples have one value per cable (m, the routing's).
    """

    name: ClassVar[str] = "cable_elasticity"
    description: ClassVar[str] = "elastic cables: stiffness k and damping c_a, eq (39)"
    abbreviation: ClassVar[str] = "elast"            # column heads of tables
    kind: ClassVar[str] = "params"
    baseline: ClassVar[bool] = True
    acts_on_cable_law: ClassVar[bool] = True
    k: tuple | None = None
    c_a: tuple | None = None

    def __post_init__(self):
        for nm in ("k", "c_a"):
            v = getattr(self, nm)
            if v is not None:
                object.__setattr__(self, nm, tuple(np.atleast_1d(per_item(f"cable_elasticity.{nm}", v,
                                                                          non_negative=True)).tolist()))

    @classmethod
    def from_params(cls, params: NeckParams) -> "CableElasticity":
        return cls(k=params.cables.k, c_a=params.cables.c_a)

    def apply(self, params: NeckParams) -> NeckParams:
        changes = {f"cables.{nm}": getattr(self, nm) for nm in ("k", "c_a") if getattr(self, nm) is not None}
        return params.replace(**changes) if changes else params
