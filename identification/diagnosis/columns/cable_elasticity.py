"""Columns of ``cable_elasticity`` (eq 39/54, in the paper's model): k and c_a per cable."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from neck_sim.effects import CableElasticity

from identification.diagnosis.columns.base import Column, ColumnData, Design, EffectColumns, FitContext

__all__ = ["CableElasticityColumns"]


class CableElasticityColumns(EffectColumns):
    """k (N/m) and c_a (N s/m) per cable, cable block only.  Its presence makes a model's cables
    elastic (eq 54); without it they are rigid (eq 25)."""

    effect: ClassVar[str] = CableElasticity.name
    elastic_cables: ClassVar[bool] = True
    columns: ClassVar[tuple] = (Column("k", "N/m"), Column("c_a", "N s/m", signed=False))

    @classmethod
    def design(cls, data: ColumnData, shape: dict, context: FitContext) -> Design:
        """Cable block of eq (39)/(54): k x_c + c_a x_c_dot (x_c with any rest elongation)."""
        eye = np.eye(data.C)
        cable = np.concatenate([context.x[:, :, None] * eye, data.x_dot[:, :, None] * eye], 2)
        return Design(np.zeros((data.S, data.n, 2 * data.C)), cable)

    @classmethod
    def to_plant(cls, params, values, shape):
        # the plant needs a positive stiffness and a non-negative damping
        k = np.maximum(values["k"], 1.0)
        return CableElasticity(k=tuple(k), c_a=tuple(np.clip(values["c_a"], 0.0, None))).apply(params), None
