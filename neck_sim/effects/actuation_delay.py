"""``actuation_delay``: the commanded force reaches the cables late."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from neck_sim.effects.base import Effect
from neck_sim.validation import finite

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
