"""Columns of ``joint_friction``: the hinge friction torque per joint, with a tanh sign of searched width."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from neck_sim.analytic import transmission_matrix
from neck_sim.effects import JointFriction
from neck_sim.mjcf import pose_qpos
from neck_sim.params import NeckParams

from identification.diagnosis.columns.base import Column, ColumnData, Design, EffectColumns, FitContext, Shape
from identification.diagnosis.materiality import in_own_band

__all__ = ["JointFrictionColumns", "hinge_lever", "camera_hinge_column", "joint_speed_from_encoders"]


def hinge_lever(alpha, params: NeckParams) -> np.ndarray:
    """(..., N): |dq_A/dalpha| + |dq_B/dalpha| + |dq_D/dalpha|, the joint torque (N m) of 1 N m of
    Coulomb friction in each of the three hinges A, B, D of an X-joint moving (virtual work)."""
    pq = pose_qpos(alpha, params)
    return np.abs(pq.dq_A) + np.abs(pq.dq_B) + np.abs(pq.dq_D)


def camera_hinge_column(data: ColumnData, width: float) -> np.ndarray:
    """(S, N): :func:`hinge_lever` x tanh(alpha_dot / ``width``) on the slow grid, alpha_dot
    (rad/s) the camera's; ``width`` rad/s.  The hinge's column of a neck with fewer cables than
    joints before its projection on the own channel's band."""
    return hinge_lever(data.alpha, data.params) * np.tanh(data.alpha_dot / width)


def joint_speed_from_encoders(theta_dot, alpha, params: NeckParams) -> np.ndarray:
    """alpha_dot (T, N) rad/s from the motor speeds theta_dot (T, C) rad/s and the poses alpha
    (T, N): the least-squares solution of Z^T alpha_dot = (r_d/R) theta_dot (eq 35, elongation
    rates neglected).  Sharper in time than the camera's 30 Hz derivative."""
    act = params.actuation
    Zt = np.swapaxes(transmission_matrix(alpha, params), -1, -2)              # (T, C, N)
    return np.einsum("tnc,tc->tn", np.linalg.pinv(Zt), (act.r_d / act.R) * theta_dot)


class JointFrictionColumns(EffectColumns):
    """tau_j (N m per hinge) per joint (with the shape ``joint`` = j, located: joint j's only),
    torque block only: torque x :func:`hinge_lever`(alpha) x
    tanh(alpha_dot / w), alpha_dot from the encoders (:func:`joint_speed_from_encoders`) through
    the observations' filter chain (C < N: the camera's, the column projected on the own channel's
    band, ``materiality.in_own_band``), w a searched smoothing speed (rad/s).  tanh, not the arctan of
    eq 36: a hinge's friction saturates at its Coulomb level within about 0.1 rad/s, where
    arctan(v/w) 2/pi is still 0.7-0.9, so an arctan fit overstates the level by 4-16 % (on
    MuJoCo's applied hinge forces along the blind logs, the best arctan reads 1.04-1.08 of the set
    level, the best tanh 0.99-1.00 with half the residual).  Not exact: the plant's friction is
    MuJoCo's constraint (``dof_frictionloss``), which the tanh smooths."""

    effect: ClassVar[str] = JointFriction.name
    columns: ClassVar[tuple] = (Column("tau_j", "N m", per="joint"),)
    columns_exact: ClassVar[bool] = False       # MuJoCo's friction constraint vs a tanh sign
    shapes: ClassVar[tuple] = (Shape("width", "rad/s", default=0.05, grid=(0.01, 0.05, 0.2), refine="log", span=3.0),)
    locates_joint: ClassVar[bool] = True

    @classmethod
    def hinge_column(cls, data: ColumnData, width: float) -> np.ndarray:
        """(S, N): each joint's friction torque of 1 N m per hinge at the tanh ``width`` (rad/s),
        on the slow grid through the observations' chain (cached on ``data``): what the fit's
        columns hold, unit by unit."""
        def compute():
            if data.C < data.n:
                # C < N motor speeds do not determine N joint speeds (eq 35 has a null space: its
                # least-squares solution is the minimum-norm one, which halves a lone joint's
                # friction column on the 10-joint, 4-cable neck): the camera's speed instead, and
                # only in the band where it reads the joint's motion (below half the common
                # cutoff): above it a joint chatters at 1-3 Hz (47-53 % of its speed's power on
                # the blind 59.3 s logs of joints 4-5) under 1 deg of differentiated camera noise,
                # so the tanh of that speed follows neither the hinge's sign nor its size (joints
                # 5 and 4 read -41 % and +19 % with the full band, -12 % and +4 % with the plant's
                # own speed, -8.6 % and +26 % +- 23 % projected on the band)
                return in_own_band(camera_hinge_column(data, width), data.prep)
            alpha_fast = np.stack([np.interp(data.t_fast, data.t, data.alpha[:, i]) for i in range(data.n)], axis=1)
            speed = joint_speed_from_encoders(data.theta_dot_fast, alpha_fast, data.params)
            fast = hinge_lever(alpha_fast, data.params) * np.tanh(speed / width)
            return data.to_slow(fast)

        return data.cached((cls.effect, width), compute)

    @classmethod
    def design(cls, data: ColumnData, shape: dict, context: FitContext) -> Design:
        """Torque block: per joint, the friction torque of 1 N m per hinge (sign of eq 30's g:
        it adds to the torque the cables must supply along the motion; :meth:`hinge_column`)."""
        col = cls.hinge_column(data, shape["width"])
        cols = (col[:, :, None] * np.eye(data.n))[:, :, cls.columns[0].select(cls.joint_of(shape))]
        return Design(cols, np.zeros((data.S, data.C, cols.shape[2])))

    @classmethod
    def to_plant(cls, params, values, shape):
        tau = cls.columns[0].expand(values["tau_j"], params.n_joints, cls.joint_of(shape))
        return params, JointFriction(torque=tuple(np.clip(tau, 0.0, None)))
