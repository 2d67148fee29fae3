"""Columns of ``viscous_friction``: c_v per cable (the regressor is the motor speed)."""

from __future__ import annotations

from typing import ClassVar

from neck_sim.effects import ViscousFriction

from identification.diagnosis.columns.base import Column, MotorColumns

__all__ = ["ViscousFrictionColumns"]


class ViscousFrictionColumns(MotorColumns):
    """c_v (N s/rad) per cable: the torque and cable blocks of f = c_v theta_dot."""

    effect: ClassVar[str] = ViscousFriction.name
    columns: ClassVar[tuple] = (Column("c_v", "N s/rad"),)
