"""Columns of ``tension_stiffening`` (lambda of eq 54, in the paper's model): lambda per cable."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from neck_sim.effects import TensionStiffening
from neck_sim.params import NeckParams

from identification.diagnosis.columns.base import Column, ColumnData, Design, EffectColumns, FitContext

__all__ = ["TensionStiffeningColumns"]


class TensionStiffeningColumns(EffectColumns):
    """lambda (1/m) per cable, cable block only, on the previous pass's tension estimate."""

    effect: ClassVar[str] = TensionStiffening.name
    uses_tension: ClassVar[bool] = True
    columns: ClassVar[tuple] = (Column("lambda", "1/m"),)

    @classmethod
    def design(cls, data: ColumnData, shape: dict, context: FitContext) -> Design:
        """Cable block of eq (54): lambda x_c t, with the previous pass's tension estimate."""
        cable = (context.x * context.tension)[:, :, None] * np.eye(data.C)
        return Design(np.zeros((data.S, data.n, data.C)), cable)

    @classmethod
    def to_plant(cls, params, values, shape):
        return TensionStiffening(lam=tuple(np.clip(values["lambda"], 0.0, None))).apply(params), None

    @classmethod
    def when_absent(cls, params: NeckParams, elastic: bool) -> NeckParams:
        return TensionStiffening(lam=(0.0,) * params.n_cables).apply(params) if elastic else params
