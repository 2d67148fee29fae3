"""Columns of ``actuation_delay``: none; the delay is a shape that shifts the commanded force, on
every motor (``delay``) or on one (``motor_delay_<i>``)."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from neck_sim.effects import ActuationDelay

from identification.diagnosis.columns.base import EffectColumns, Shape

__all__ = ["ActuationDelayColumns"]

_GRID = (0.002, 0.005, 0.010, 0.020, 0.040)


class ActuationDelayColumns(EffectColumns):
    """The observations use the force commanded ``delay`` (s) earlier on every motor, or
    ``motor_delay_<i>`` (s) earlier on motor i only; each grid-searched, then refined linearly
    (the search keeps whichever of the two fits the training folds better)."""

    effect: ClassVar[str] = ActuationDelay.name
    shapes: ClassVar[tuple] = (Shape("delay", "s", default=0.005, grid=_GRID, refine="linear", span=0.005,
                                     profile_step=5e-4),
                               Shape("motor_delay", "s", grid=_GRID, per_cable=True, bounds=(0.0, 2 * _GRID[-1]),
                                     profile_step=5e-4, search="fit"))

    @classmethod
    def fit_delay(cls, shape: dict) -> float:
        return float(shape.get("delay", 0.0))

    @classmethod
    def motor_delays(cls, shape: dict, n_cables: int) -> np.ndarray:
        """(n_cables,) s from the shape keys ``motor_delay_<i>`` (1-based)."""
        return cls.shapes[1].per_cable_values(shape, n_cables)

    @classmethod
    def fit_motor_delays(cls, shape: dict, n_cables: int) -> np.ndarray:
        return cls.motor_delays(shape, n_cables)

    @classmethod
    def to_plant(cls, params, values, shape):
        """The all-motor delay as the plant's; the plant has one delay line for every motor, so a
        delay on some motors only is not carried into a re-simulation."""
        return params, ActuationDelay(delay=max(cls.fit_delay(shape), 0.0))
