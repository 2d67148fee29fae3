"""Columns of ``pulley_friction``: mu per cable on the tension estimate, its sign sharpness c searched."""

from __future__ import annotations

from typing import ClassVar

from neck_sim.effects import PulleyFriction

from identification.diagnosis.columns.base import Column, MotorColumns, Shape

__all__ = ["PulleyFrictionColumns"]


class PulleyFrictionColumns(MotorColumns):
    """mu (-) per cable: the torque and cable blocks of mu t (2/pi) arctan(c theta_dot), with t
    the previous pass's tension estimate (the fit iterates); c (s/rad) a log-refined shape."""

    effect: ClassVar[str] = PulleyFriction.name
    uses_tension: ClassVar[bool] = True
    columns: ClassVar[tuple] = (Column("mu", "-"),)
    shapes: ClassVar[tuple] = (Shape("c", "s/rad", default=0.5, grid=(0.5, 2.0, 8.0), refine="log", span=2.0),)

    # A pulley term may carry the shape key ``cable`` (1-based): its column on that cable only.  It
    # is not searched cable by cable (``locates_cable`` stays False: its places and its search are
    # the every-cable form's); the encompassing test of ``selection.one_cable_pair`` puts it on the
    # one cable a look-alike rests on, to compare the two laws on the same data.
    @classmethod
    def cable_of(cls, shape: dict) -> int | None:
        v = shape.get("cable")
        return None if v is None else int(v)

    @classmethod
    def without_location(cls, shape: dict) -> dict:
        return {k: v for k, v in shape.items() if k != "cable"}
