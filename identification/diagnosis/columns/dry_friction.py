"""Columns of ``dry_friction`` (eq 37, in the paper's model): f_s per cable, the sign sharpness c_s searched."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from neck_sim.effects import DryFriction
from neck_sim.params import NeckParams

from identification.diagnosis.columns.base import Column, MotorColumns, Shape

__all__ = ["DryFrictionColumns"]


class DryFrictionColumns(MotorColumns):
    """f_s (N) per cable: the torque and cable blocks of (2/pi) arctan(c_s theta_dot), c_s (s/rad)
    a log-refined shape.  A model without it has no friction at all (``when_absent``)."""

    effect: ClassVar[str] = DryFriction.name
    locates_cable: ClassVar[bool] = True
    columns: ClassVar[tuple] = (Column("f_s", "N"),)
    shapes: ClassVar[tuple] = (Shape("c_s", "s/rad", default=0.5, grid=(0.5, 1.0, 2.0, 5.0, 10.0, 20.0),
                                     refine="log", span=2.0),)

    # the plant applies eq (37) from params.friction (apply); no extra native force
    @classmethod
    def to_plant(cls, params, values, shape):
        return DryFriction(f_s=tuple(np.clip(values["f_s"], 0.0, None)), c_s=shape["c_s"]).apply(params), None

    @classmethod
    def when_absent(cls, params: NeckParams, elastic: bool) -> NeckParams:
        return params.replace(**{"friction.f_s": (0.0,) * params.n_cables})
