"""``spring_error``: side springs stiffer or softer than nominal."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from neck_sim.analytic import side_lengths
from neck_sim.effects.base import Column, Design, Effect, Hidden, finite, indices
from neck_sim.params import NeckParams

__all__ = ["SpringError", "spring_torque"]


def spring_torque(alpha, params: NeckParams) -> np.ndarray:
    """Joint torque (S, N) N m per N/m of each joint's side-spring stiffness at the poses alpha (S, N).

    A rest-length error is not a separate regressor: over the workspace -k (dl_l + dl_r) is nearly
    proportional to this column (both odd in alpha).
    """
    sd = side_lengths(alpha, params)
    l0 = params.springs.rest_length
    return (sd.l_l - l0) * sd.dl_l + (sd.l_r - l0) * sd.dl_r


@dataclass(frozen=True)
class SpringError(Effect):
    """Side springs differ from nominal: stiffness times ``stiffness_scale`` on ``joints`` and
    rest length plus ``rest_length_offset`` (m, every spring: the parameter module has one rest
    length).  Maps to ``params.springs``.
    """

    name: ClassVar[str] = "spring_error"
    description: ClassVar[str] = "side springs stiffer or softer than nominal"
    abbreviation: ClassVar[str] = "spring"            # column heads of tables
    kind: ClassVar[str] = "params"
    columns: ClassVar[tuple] = (Column("dk", "N/m", per="joint", signed=False),)
    blind_magnitude: ClassVar[float] = 0.5      # relative stiffness error on one joint
    blind_unit: ClassVar[str] = "relative"
    stiffness_scale: float = 1.2
    rest_length_offset: float = 0.0
    joints: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "stiffness_scale", finite("spring_error.stiffness_scale", self.stiffness_scale,
                                                           non_negative=True))
        object.__setattr__(self, "rest_length_offset", finite("spring_error.rest_length_offset",
                                                              self.rest_length_offset))
        object.__setattr__(self, "joints", indices("spring_error.joints", self.joints))

    def apply(self, params: NeckParams) -> NeckParams:
        k = np.asarray(params.springs.stiffness, dtype=float).copy()
        idx = np.arange(params.n_joints) if self.joints is None else np.asarray(self.joints)
        k[idx] *= self.stiffness_scale
        return params.replace(**{"springs.stiffness": tuple(k),
                                 "springs.rest_length": params.springs.rest_length + self.rest_length_offset})

    @classmethod
    def design(cls, data, shape, context):
        """Torque block: per joint, the torque of 1 N/m more side-spring stiffness."""
        torque = data.cached(cls.name, lambda: spring_torque(data.alpha, data.params))
        return Design(torque[:, :, None] * np.eye(data.n), np.zeros((data.S, data.C, data.n)))

    @classmethod
    def to_plant(cls, params, values, shape):
        k = np.asarray(params.springs.stiffness) + values["dk"]
        return params.replace(**{"springs.stiffness": tuple(np.clip(k, 0.0, None))}), None

    @classmethod
    def hide(cls, params, rng, magnitude, cable, joint):
        scale = 1.0 + magnitude * (1 if rng.random() < 0.5 else -1)
        desc = f"side springs of joint {joint + 1} x {scale:.2f}"
        return Hidden(params, (cls(stiffness_scale=scale, joints=(joint,)),), (), (joint,), desc, cls.name)
