"""``payload``: an unmodelled point mass at the head."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from neck_sim.effects.base import Effect
from neck_sim.params import NeckParams
from neck_sim.validation import finite

__all__ = ["Payload"]


@dataclass(frozen=True)
class Payload(Effect):
    """An unmodelled point mass ``mass`` (kg) at the head: the centre of the top bar of joint N.

    Maps to ``params.inertia.payload_mass`` (which the analytic model also understands).
    """

    name: ClassVar[str] = "payload"
    description: ClassVar[str] = "an unmodelled mass at the head"
    abbreviation: ClassVar[str] = "payload"            # column heads of tables
    kind: ClassVar[str] = "params"
    mass: float = 0.05

    def __post_init__(self):
        object.__setattr__(self, "mass", finite("payload.mass", self.mass, non_negative=True))

    def apply(self, params: NeckParams) -> NeckParams:
        return params.replace(**{"inertia.payload_mass": params.inertia.payload_mass + self.mass})
