"""Columns of ``spring_error``: a stiffness change per side spring (2N columns), or of the two
side springs of one joint (a located term, shape ``joint``)."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from neck_sim.analytic import side_lengths
from neck_sim.effects import SpringError
from neck_sim.params import NeckParams

from identification.diagnosis.columns.base import Column, ColumnData, Design, EffectColumns, FitContext

__all__ = ["SpringErrorColumns", "spring_torque", "resolved_stiffness"]


def spring_torque(alpha, params: NeckParams) -> np.ndarray:
    """Joint torque (S, N, 2) N m per N/m more stiffness of each side spring (left: A_i C_i, right:
    B_i D_i, eqs 1-2) at the poses alpha (S, N): -d/dalpha of (1/2)(l - l0)^2, sign as g (eq 30).

    A rest-length change dl0 of one spring gives k dl0 dl/dalpha: over the workspace (springs
    stretched by l(0) - l0 = 41 mm at rest, |l - l(0)| < 15 mm) nearly proportional to this column,
    so the fit reads it as the stiffness change dk = -k dl0 / (l(0) - l0) (the report says so).
    """
    sd = side_lengths(alpha, params)
    l0 = params.springs.rest_length
    return np.stack([(sd.l_l - l0) * sd.dl_l, (sd.l_r - l0) * sd.dl_r], axis=-1)


def resolved_stiffness(alpha, params: NeckParams, joint: int) -> tuple[np.ndarray, float]:
    """(u (2,), ratio): the combination u . (dk_left, dk_right) of joint ``joint``'s (1-based) two
    side springs that its torque row resolves best at the poses alpha (S, N), and how much worse
    the other one is resolved.

    Both springs act on that row only (:func:`spring_torque`), so the fit's information on the
    pair is the Gram matrix G of their two columns: u is its leading unit eigenvector (signed so
    that its larger entry is positive), ``ratio`` = sqrt(lambda_min / lambda_max) the other
    combination's sensitivity relative to u's (1: both sides resolved alike; near 0: the two
    columns are nearly collinear and only u . dk is measured, the sides' split is not).  N/m of u
    . dk is the stiffness change that row sees."""
    col = spring_torque(alpha, params)[:, joint - 1, :]                        # (S, 2) N m per N/m
    w, v = np.linalg.eigh(col.T @ col)
    u = v[:, -1] * np.sign(v[np.argmax(np.abs(v[:, -1])), -1])
    return u, float(np.sqrt(max(w[0], 0.0) / w[-1]))


class SpringErrorColumns(EffectColumns):
    """dk (N/m) per side spring (joint 1 left, joint 1 right, ...), torque block only; with the
    shape ``joint`` = j (located: searched joint by joint) the two springs of joint j only, whose
    torque acts on joint j's row alone.  Mapped to the plant as ``SpringError(dk=...)`` (MuJoCo's
    tendon stiffness)."""

    effect: ClassVar[str] = SpringError.name
    columns: ClassVar[tuple] = (Column("dk", "N/m", per="spring", signed=False),)
    locates_joint: ClassVar[bool] = True

    @classmethod
    def design(cls, data: ColumnData, shape: dict, context: FitContext) -> Design:
        """Torque block: per spring, the torque of 1 N/m more stiffness."""
        torque = data.cached(cls.effect, lambda: spring_torque(data.alpha, data.params))       # (S, N, 2)
        S, n = data.S, data.n
        cols = np.zeros((S, n, 2 * n))
        for j in range(n):
            cols[:, j, 2 * j:2 * j + 2] = torque[:, j, :]
        cols = cols[:, :, cls.columns[0].select(cls.joint_of(shape))]
        return Design(cols, np.zeros((S, data.C, cols.shape[2])))

    @classmethod
    def to_plant(cls, params, values, shape):
        k = np.repeat(np.asarray(params.springs.stiffness, dtype=float), 2)
        dk = np.maximum(cls.columns[0].expand(values["dk"], params.n_joints, cls.joint_of(shape)), -k)
        return params, SpringError(dk=tuple(dk))
