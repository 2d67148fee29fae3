"""Columns of ``actuation_delay``: none; the delay is a shape that shifts the commanded force."""

from __future__ import annotations

from typing import ClassVar

from neck_sim.effects import ActuationDelay

from identification.diagnosis.columns.base import EffectColumns, Shape

__all__ = ["ActuationDelayColumns"]


class ActuationDelayColumns(EffectColumns):
    """The observations use the force commanded ``delay`` (s) earlier; delay grid-searched, then
    refined linearly."""

    effect: ClassVar[str] = ActuationDelay.name
    shapes: ClassVar[tuple] = (Shape("delay", "s", default=0.005, grid=(0.002, 0.005, 0.010, 0.020, 0.040),
                                     refine="linear", span=0.005, profile_step=5e-4),)

    @classmethod
    def fit_delay(cls, shape: dict) -> float:
        return float(shape["delay"])

    @classmethod
    def to_plant(cls, params, values, shape):
        return params, ActuationDelay(delay=max(cls.fit_delay(shape), 0.0))
