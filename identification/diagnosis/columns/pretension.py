"""Columns of ``pretension``: none; the rest elongation of each cable is a bounded shape."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from neck_sim.effects import Pretension

from identification.diagnosis.columns.base import EffectColumns, Shape

__all__ = ["PretensionColumns", "PRETENSION_RANGE"]


#: Search range of the rest elongation of each cable (m): 1.5 mm (the blind magnitude) x 1.25 plus
#: margin above, and a slack cable (negative offset) below.
PRETENSION_RANGE = (-1e-3, 5e-3)


class PretensionColumns(EffectColumns):
    """The rest elongation x_0 (m) per cable, added to the measured elongation of eq (27): nearly
    collinear with k and lambda as a linear column (a linear offset lets the fit run to negative
    stiffness), so a shape searched on :data:`PRETENSION_RANGE` cable by cable."""

    effect: ClassVar[str] = Pretension.name
    shapes: ClassVar[tuple] = (Shape("x0", "m", per_cable=True, bounds=PRETENSION_RANGE, profile_step=1e-4),)

    @classmethod
    def fit_elongation_offset(cls, shape: dict, n_cables: int) -> np.ndarray:
        """x_0 (n_cables,) m from the shape keys ``x0_<i>`` (1-based)."""
        return cls.shapes[0].per_cable_values(shape, n_cables)

    @classmethod
    def shape_violation(cls, shape: dict) -> str:
        """A rest elongation on a bound of :data:`PRETENSION_RANGE` (within 1 % of its width):
        the best offset lies outside what a rest elongation can be, so the gain comes from another
        form (a cable's own hysteresis or creep pin x_0 at -1 mm on the generator's logs; its
        encoder offsets, 2.4-3.8 mm, stay inside)."""
        lo, hi = PRETENSION_RANGE
        tol = 0.01 * (hi - lo)
        for key, v in sorted(shape.items()):
            if key.startswith("x0_") and not lo + tol < v < hi - tol:
                return f"fitted x0({key[3:]}) = {1e3 * v:.2f} mm on a bound of its range: not a {cls.effect}"
        return ""

    @classmethod
    def to_plant(cls, params, values, shape):
        return params, Pretension(elongation=tuple(cls.fit_elongation_offset(shape, params.n_cables)))
