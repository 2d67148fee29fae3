"""Columns of ``viscous_friction``: c_v per cable (the regressor is the motor speed)."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from neck_sim.effects import ViscousFriction

from identification.diagnosis.columns.base import Column, MotorColumns
from identification.diagnosis.statistics import clearly_nonzero

__all__ = ["ViscousFrictionColumns", "CROSSTALK"]

#: The largest |c_v| < 0 on one cable, as a fraction of the largest c_v > 0 on another, read as
#: cross-talk and not as an unphysical sign: the torque block sees every cable through Z (eq 51)
#: and antagonist motors turn against each other, so their c_v columns are nearly collinear; a
#: damping on the soft left cable alone (open-world generator, 0.12-0.15 N s/rad, seeds 1 and 3)
#: leaves -0.033 (0.26 of it) to +0.025 N s/rad on the right cable that ends at the same joint.
CROSSTALK = 1.0 / 3.0


class ViscousFrictionColumns(MotorColumns):
    """c_v (N s/rad) per cable: the torque and cable blocks of f = c_v theta_dot."""

    effect: ClassVar[str] = ViscousFriction.name
    locates_cable: ClassVar[bool] = True
    columns: ClassVar[tuple] = (Column("c_v", "N s/rad"),)

    @classmethod
    def sign_violation(cls, values: dict, sigmas: dict) -> str:
        """'' when every clearly negative c_v is cross-talk (|c_v| <= :data:`CROSSTALK` x the
        largest clearly positive one), else why not."""
        sym = cls.columns[0].symbol
        if sym not in values:
            return ""
        v = np.asarray(values[sym], dtype=float)
        ok = clearly_nonzero(v, sigmas[sym])
        top = float(np.max(v[ok & (v > 0)], initial=0.0))
        bad = ok & (v < 0) & (-v > CROSSTALK * top)
        if bad.any():
            idx = ", ".join(str(i + 1) for i in np.nonzero(bad)[0])
            return f"fitted {sym} < 0 on cable {idx}: not a {cls.effect}"
        return ""
