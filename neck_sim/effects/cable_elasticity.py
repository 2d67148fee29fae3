"""``cable_elasticity``: linear cable stiffness and damping, eq (39) -- in the paper's model."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from neck_sim.effects.base import Column, Design, Effect, Hidden, per_item
from neck_sim.params import NeckParams

__all__ = ["CableElasticity"]


@dataclass(frozen=True)
class CableElasticity(Effect):
    """Linear cable stiffness k (N/m) and damping c_a (N s/m), eq (39) -- baseline (``params.cables``).

    ``None`` keeps the parameter; tuples have one value per cable (m, the routing's).  In a diagnosis model
    its presence makes the cables elastic (eq 54); without it they are rigid (eq 25).
    """

    name: ClassVar[str] = "cable_elasticity"
    description: ClassVar[str] = "elastic cables: stiffness k and damping c_a, eq (39)"
    abbreviation: ClassVar[str] = "elast"            # column heads of tables
    kind: ClassVar[str] = "params"
    baseline: ClassVar[bool] = True
    acts_on_cable_law: ClassVar[bool] = True
    elastic_cables: ClassVar[bool] = True
    columns: ClassVar[tuple] = (Column("k", "N/m"), Column("c_a", "N s/m", signed=False))
    blind_magnitude: ClassVar[float] = 1.0      # scale of the paper's stiffness (baseline with rigid cables)
    blind_unit: ClassVar[str] = "x Table 2 k"
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

    @classmethod
    def design(cls, data, shape, context):
        """Cable block of eq (39)/(54): k x_c + c_a x_c_dot (x_c with any rest elongation)."""
        eye = np.eye(data.C)
        cable = np.concatenate([context.x[:, :, None] * eye, data.x_dot[:, :, None] * eye], 2)
        return Design(np.zeros((data.S, data.n, 2 * data.C)), cable)

    @classmethod
    def to_plant(cls, params, values, shape):
        # the plant needs a positive stiffness and a non-negative damping
        k = np.maximum(values["k"], 1.0)
        return cls(k=tuple(k), c_a=tuple(np.clip(values["c_a"], 0.0, None))).apply(params), None

    @classmethod
    def hide(cls, params, rng, magnitude, cable, joint):
        k = tuple(np.asarray(params.cables.k) * magnitude)
        desc = f"elastic cables, k = {magnitude:.2f} x Table 2"
        return Hidden(params, (cls(k=k),), tuple(range(params.n_cables)), (), desc, cls.name)
