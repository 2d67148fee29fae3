"""Columns of ``payload``: one column, the joint torque of 1 kg more at the head."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from neck_sim.analytic import linkage_dynamics
from neck_sim.effects import Payload
from neck_sim.params import NeckParams

from identification.diagnosis.columns.base import Column, ColumnData, Design, EffectColumns, FitContext

__all__ = ["PayloadColumns", "payload_torque"]


def payload_torque(alpha, alpha_dot, alpha_ddot, params: NeckParams) -> np.ndarray:
    """Joint torque (S, N) N m of 1 kg more at the head on the motion (S, N) rad, rad/s, rad/s^2:
    the difference of the linkage dynamics (M alpha_ddot + c + g, eq 30) with and without it."""
    lk = linkage_dynamics(alpha, alpha_dot, params)
    lk1 = linkage_dynamics(alpha, alpha_dot, params.replace(**{"inertia.payload_mass": params.inertia.payload_mass + 1.0}))
    return np.einsum("sij,sj->si", lk1.M - lk.M, alpha_ddot) + (lk1.c - lk.c) + (lk1.g - lk.g)


class PayloadColumns(EffectColumns):
    """payload (kg), torque block only (eq 51's linkage side)."""

    effect: ClassVar[str] = Payload.name
    columns: ClassVar[tuple] = (Column("payload", "kg", per="one"),)
    # M(alpha) alpha_ddot of the head on the camera's angles, against the nominal neck's on the same
    # angles in the observation: errors in variables when C < N (the camera alone gives alpha)
    camera_noise_bias: ClassVar[bool] = True

    @classmethod
    def design(cls, data: ColumnData, shape: dict, context: FitContext) -> Design:
        """Torque block: the torque of 1 kg at the head (eq 51's linkage side)."""
        torque = data.cached(cls.effect, lambda: payload_torque(data.alpha, data.alpha_dot, data.alpha_ddot,
                                                                data.params))
        return Design(torque[:, :, None], np.zeros((data.S, data.C, 1)))

    @classmethod
    def to_plant(cls, params, values, shape):
        return Payload(mass=max(float(values["payload"][0]), 0.0)).apply(params), None
