"""``actuation_delay``: the commanded force reaches the cables late."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from neck_sim.effects.base import Effect, Hidden, Shape, finite

__all__ = ["ActuationDelay"]


@dataclass(frozen=True)
class ActuationDelay(Effect):
    """The commanded force reaches the cable ``delay`` seconds after it is commanded.

    The delay line starts filled with the first command (no startup transient).  A diagnosis
    fits it as a shape: the observations use the force commanded ``delay`` earlier.
    """

    name: ClassVar[str] = "actuation_delay"
    description: ClassVar[str] = "the commanded force acts late"
    abbreviation: ClassVar[str] = "delay"            # column heads of tables
    kind: ClassVar[str] = "command"
    shapes: ClassVar[tuple] = (Shape("delay", "s", default=0.005, grid=(0.002, 0.005, 0.010, 0.020, 0.040),
                                     refine="linear", span=0.005, profile_step=5e-4),)
    blind_magnitude: ClassVar[float] = 0.010    # s
    blind_unit: ClassVar[str] = "s"
    delay: float = 0.006

    def __post_init__(self):
        object.__setattr__(self, "delay", finite("actuation_delay.delay", self.delay, non_negative=True))

    @property
    def command_delay(self) -> float:
        return self.delay

    def delayed_index(self, t, command_times) -> np.ndarray:
        """Index of the command in force at times ``t``: the last issued at or before t - delay
        (0 before the first command takes effect).  ``command_times`` sorted, s."""
        k = np.searchsorted(np.asarray(command_times), np.asarray(t, dtype=float) - self.delay + 1e-12,
                            side="right") - 1
        return np.maximum(k, 0)

    @classmethod
    def fit_delay(cls, shape):
        return float(shape["delay"])

    @classmethod
    def to_plant(cls, params, values, shape):
        return params, cls(delay=max(cls.fit_delay(shape), 0.0))

    @classmethod
    def hide(cls, params, rng, magnitude, cable, joint):
        return Hidden(params, (cls(delay=magnitude),), (), (), f"actuation delay {1e3 * magnitude:.1f} ms", cls.name)
