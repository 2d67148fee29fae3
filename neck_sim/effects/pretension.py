"""``pretension``: cables already stretched at the pose where the encoders were zeroed."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from neck_sim.effects.base import Effect
from neck_sim.validation import indices, per_item

__all__ = ["Pretension"]


@dataclass(frozen=True)
class Pretension(Effect):
    """Cables already stretched at the rest pose: x_c(0) = ``elongation`` (m) instead of 0.

    The encoders are zeroed at the straight pose with the cables stretched: the plant's
    elongation is x_c = l_c - l_c0 + (r_d/R) theta + elongation, invisible to the encoders.
    1 mm on cable 1 is about 5.5 N of tension at rest.  A diagnosis fits it as a shape, the rest
    elongation x_0 per cable (:mod:`identification.diagnosis.columns.pretension`).
    """

    name: ClassVar[str] = "pretension"
    description: ClassVar[str] = "cables already stretched when the encoders were zeroed"
    abbreviation: ClassVar[str] = "pret"            # column heads of tables
    kind: ClassVar[str] = "elongation"
    magnitude_field: ClassVar[str] = "elongation"
    acts_on_cable_law: ClassVar[bool] = True
    requires: ClassVar[tuple] = ("cable_elasticity",)
    elongation: tuple | float = 1e-3
    cables: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "elongation", per_item("pretension.elongation", self.elongation))
        object.__setattr__(self, "cables", indices("pretension.cables", self.cables))

    def elongation_offset(self, n_cables: int) -> np.ndarray:
        """(n_cables,) m added to every elongation."""
        return self.per_cable(n_cables)
