"""``camera_delay``: the camera's joint angles lag the encoders by a fixed time."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from neck_sim.effects.base import Effect
from neck_sim.validation import finite

__all__ = ["CameraDelay"]


@dataclass(frozen=True)
class CameraDelay(Effect):
    """A camera frame stamped t shows the neck at t - ``delay`` (s): video latency, or a clock
    offset between the camera's and the motors' recorders.

    The diagnosis fits it as a shape (:mod:`identification.diagnosis.columns.camera_delay`).
    """

    name: ClassVar[str] = "camera_delay"
    description: ClassVar[str] = "the camera's joint angles lag the encoders by a fixed time"
    abbreviation: ClassVar[str] = "camdelay"
    kind: ClassVar[str] = "camera"
    delay: float = 0.033

    def __post_init__(self):
        object.__setattr__(self, "delay", finite("camera_delay.delay", self.delay, non_negative=True))

    @property
    def camera_delay(self) -> float:
        return self.delay
