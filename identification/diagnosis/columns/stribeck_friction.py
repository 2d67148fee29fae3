"""Columns of ``stribeck_friction``: the breakaway bump df per cable, its smoothing and speed on a grid."""

from __future__ import annotations

from typing import ClassVar

from neck_sim.effects import StribeckFriction

from identification.diagnosis.columns.base import Column, MotorColumns, Shape

__all__ = ["StribeckFrictionColumns"]


class StribeckFrictionColumns(MotorColumns):
    """df (N) per cable: the torque and cable blocks of df exp(-(theta_dot/speed)^2)
    tanh(theta_dot/smoothing); ``smoothing`` and ``speed`` (rad/s) tried on their grids."""

    effect: ClassVar[str] = StribeckFriction.name
    locates_cable: ClassVar[bool] = True
    columns: ClassVar[tuple] = (Column("df", "N"),)
    shapes: ClassVar[tuple] = (Shape("smoothing", "rad/s", default=0.5, grid=(0.15, 0.5, 1.5)),
                               Shape("speed", "rad/s", default=5.0, grid=(1.5, 3.0, 6.0, 12.0)))
