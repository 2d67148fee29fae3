"""``camera_delay``: the camera's joint angles lag the encoders by a fixed time."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from neck_sim.effects.base import Effect, Hidden, Shape, finite

__all__ = ["CameraDelay"]


@dataclass(frozen=True)
class CameraDelay(Effect):
    """A camera frame stamped t shows the neck at t - ``delay`` (s): video latency, or a clock
    offset between the camera's and the motors' recorders.

    The diagnosis fits it as a shape: every camera-side quantity (alpha, Z, the linkage torque,
    the elongations of eq 27) is read ``delay`` later
    (:meth:`identification.diagnosis.measured.MeasuredData.camera_shifted`); resolution from the profile
    of the training score, well below one 33 ms frame.
    """

    name: ClassVar[str] = "camera_delay"
    description: ClassVar[str] = "the camera's joint angles lag the encoders by a fixed time"
    abbreviation: ClassVar[str] = "camdelay"
    kind: ClassVar[str] = "camera"
    shapes: ClassVar[tuple] = (Shape("delay", "s", default=0.033, grid=(0.008, 0.017, 0.033, 0.05, 0.08),
                                     refine="linear", span=0.01, profile_step=1e-3),)
    blind_magnitude: ClassVar[float] = 0.033    # s, one camera frame at 30 Hz
    blind_unit: ClassVar[str] = "s"
    delay: float = 0.033

    def __post_init__(self):
        object.__setattr__(self, "delay", finite("camera_delay.delay", self.delay, non_negative=True))

    @property
    def camera_delay(self) -> float:
        return self.delay

    @classmethod
    def fit_camera_shift(cls, shape):
        return float(shape["delay"])

    @classmethod
    def to_plant(cls, params, values, shape):
        return params, cls(delay=max(cls.fit_camera_shift(shape), 0.0))

    @classmethod
    def hide(cls, params, rng, magnitude, cable, joint):
        return Hidden(params, (cls(delay=magnitude),), (), (), f"camera delay {1e3 * magnitude:.0f} ms", cls.name)
