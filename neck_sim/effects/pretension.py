"""``pretension``: cables already stretched at the pose where the encoders were zeroed."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from neck_sim.effects.base import Effect, Hidden, Shape, indices, per_item
from neck_sim.effects.cable_elasticity import CableElasticity

__all__ = ["Pretension", "PRETENSION_RANGE"]

#: Search range of the rest elongation of each cable (m): 1.5 mm (the blind magnitude) x 1.25 plus
#: margin above, and a slack cable (negative offset) below.
PRETENSION_RANGE = (-1e-3, 5e-3)


@dataclass(frozen=True)
class Pretension(Effect):
    """Cables already stretched at the rest pose: x_c(0) = ``elongation`` (m) instead of 0.

    The encoders are zeroed at the straight pose with the cables stretched: the plant's
    elongation is x_c = l_c - l_c0 + (r_d/R) theta + elongation, invisible to the encoders.
    1 mm on cable 1 is about 5.5 N of tension at rest.  A diagnosis fits it as a shape: the rest
    elongation x_0 per cable (nearly collinear with k, lambda as a linear column), searched on
    :data:`PRETENSION_RANGE` cable by cable.
    """

    name: ClassVar[str] = "pretension"
    description: ClassVar[str] = "cables already stretched when the encoders were zeroed"
    abbreviation: ClassVar[str] = "pret"            # column heads of tables
    kind: ClassVar[str] = "elongation"
    magnitude_field: ClassVar[str] = "elongation"
    acts_on_cable_law: ClassVar[bool] = True
    requires: ClassVar[tuple] = (CableElasticity.name,)
    shapes: ClassVar[tuple] = (Shape("x0", "m", per_cable=True, bounds=PRETENSION_RANGE, profile_step=1e-4),)
    blind_magnitude: ClassVar[float] = 1.5e-3   # m on one cable
    blind_unit: ClassVar[str] = "m"
    elongation: tuple | float = 1e-3
    cables: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "elongation", per_item("pretension.elongation", self.elongation))
        object.__setattr__(self, "cables", indices("pretension.cables", self.cables))

    def elongation_offset(self, n_cables: int) -> np.ndarray:
        """(n_cables,) m added to every elongation."""
        return self.per_cable(n_cables)

    @classmethod
    def fit_elongation_offset(cls, shape, n_cables):
        """x_0 (n_cables,) m from the shape keys ``x0_<i>`` (1-based)."""
        out = np.zeros(n_cables)
        for key, v in shape.items():
            if key.startswith("x0_"):
                out[int(key[3:]) - 1] = v
        return out

    @classmethod
    def to_plant(cls, params, values, shape):
        return params, cls(elongation=tuple(cls.fit_elongation_offset(shape, params.n_cables)))

    @classmethod
    def hide(cls, params, rng, magnitude, cable, joint):
        # not on the softest cables (the paper's long left cable): they stiffen strongly (lambda x_0 ~
        # 0.2), so their k and lambda absorb an offset of a few mm within the noise (see the detection
        # benchmark)
        k = np.asarray(params.cables.k, dtype=float)
        stiff = np.nonzero(k > k.min())[0] if np.ptp(k) > 0 else np.arange(k.size)
        cable = int(stiff[rng.integers(stiff.size)])
        desc = f"pretension {1e3 * magnitude:.2f} mm on cable {cable + 1}"
        return Hidden(params, (cls(elongation=magnitude, cables=(cable,)),), (cable,), (), desc, cls.name)
