"""Columns of ``camera_delay``: none; the delay is a shape by which the camera is read later."""

from __future__ import annotations

from typing import ClassVar

from neck_sim.effects import CameraDelay

from identification.diagnosis.columns.base import EffectColumns, Shape

__all__ = ["CameraDelayColumns"]


class CameraDelayColumns(EffectColumns):
    """Every camera-side quantity (alpha, Z, the linkage torque, the elongations of eq 27) is read
    ``delay`` (s) later (:meth:`identification.diagnosis.measured.MeasuredData.camera_shifted`);
    resolution from the profile of the training score, well below one 33 ms frame."""

    effect: ClassVar[str] = CameraDelay.name
    shapes: ClassVar[tuple] = (Shape("delay", "s", default=0.033, grid=(0.008, 0.017, 0.033, 0.05, 0.08),
                                     refine="linear", span=0.01, profile_step=1e-3),)

    @classmethod
    def fit_camera_shift(cls, shape: dict) -> float:
        return float(shape["delay"])

    @classmethod
    def to_plant(cls, params, values, shape):
        return params, CameraDelay(delay=max(cls.fit_camera_shift(shape), 0.0))
