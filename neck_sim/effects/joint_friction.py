"""``joint_friction``: friction in the X-joints' revolute joints (the paper assumes them perfect)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from neck_sim.analytic import transmission_matrix
from neck_sim.effects.base import Column, Design, Effect, Hidden, Shape, indices, per_item
from neck_sim.mjcf import pose_qpos
from neck_sim.params import NeckParams

__all__ = ["JointFriction", "hinge_lever", "joint_speed_from_encoders"]


def hinge_lever(alpha, params: NeckParams) -> np.ndarray:
    """(..., N): |dq_A/dalpha| + |dq_B/dalpha| + |dq_D/dalpha|, the joint torque (N m) of 1 N m of
    Coulomb friction in each of the three hinges A, B, D of an X-joint moving (virtual work)."""
    pq = pose_qpos(alpha, params)
    return np.abs(pq.dq_A) + np.abs(pq.dq_B) + np.abs(pq.dq_D)


def joint_speed_from_encoders(theta_dot, alpha, params: NeckParams) -> np.ndarray:
    """alpha_dot (T, N) rad/s from the motor speeds theta_dot (T, C) rad/s and the poses alpha
    (T, N): the least-squares solution of Z^T alpha_dot = (r_d/R) theta_dot (eq 35, elongation
    rates neglected).  Sharper in time than the camera's 30 Hz derivative."""
    act = params.actuation
    Zt = np.swapaxes(transmission_matrix(alpha, params), -1, -2)              # (T, C, N)
    return np.einsum("tnc,tc->tn", np.linalg.pinv(Zt), (act.r_d / act.R) * theta_dot)


@dataclass(frozen=True)
class JointFriction(Effect):
    """Coulomb friction ``torque`` (N m) in each revolute hinge (A, B, D) of the affected X-joints.

    The plant sets MuJoCo's ``dof_frictionloss`` on those hinges (a constraint-based Coulomb
    friction) with a stiff ``dof_solref``.  The diagnosis fits, per joint, the joint torque it gives:
    torque x :func:`hinge_lever`(alpha) x tanh(alpha_dot / w), with alpha_dot from the encoders
    (:func:`joint_speed_from_encoders`) through the observations' filter chain, w a searched
    smoothing speed (rad/s).  tanh, not the arctan of eq 36: a hinge's friction saturates at its
    Coulomb level within about 0.1 rad/s, where arctan(v/w) 2/pi is still 0.7-0.9, so an arctan fit
    overstates the level by 4-16 % (on MuJoCo's applied hinge forces along the blind logs, the best
    arctan reads 1.04-1.08 of the set level, the best tanh 0.99-1.00 with half the residual).
    """

    name: ClassVar[str] = "joint_friction"
    description: ClassVar[str] = "friction in the X-joints' revolute joints, resisting joint motion"
    abbreviation: ClassVar[str] = "jfric"
    kind: ClassVar[str] = "mujoco"
    magnitude_field: ClassVar[str] = "torque"
    columns: ClassVar[tuple] = (Column("tau_j", "N m", per="joint"),)
    columns_exact: ClassVar[bool] = False       # MuJoCo's friction constraint vs a tanh sign
    shapes: ClassVar[tuple] = (Shape("width", "rad/s", default=0.05, grid=(0.01, 0.05, 0.2), refine="log", span=3.0),)
    blind_magnitude: ClassVar[float] = 0.02     # N m per hinge
    blind_unit: ClassVar[str] = "N m"
    torque: tuple | float = 0.02
    joints: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "torque", per_item("joint_friction.torque", self.torque, non_negative=True))
        object.__setattr__(self, "joints", indices("joint_friction.joints", self.joints))

    def check(self, params: NeckParams) -> None:
        if self.joints is not None and max(self.joints) >= params.n_joints:
            raise ValueError(f"joint_friction.joints: index {max(self.joints)} out of range for {params.n_joints} "
                             "joints (0-based)")
        want = params.n_joints if self.joints is None else len(self.joints)
        if isinstance(self.torque, tuple) and len(self.torque) != want:
            raise ValueError(f"joint_friction.torque: {len(self.torque)} values for {want} affected joints")

    def per_joint(self, n_joints: int) -> np.ndarray:
        """(N,) N m per hinge, zero on unaffected joints."""
        out = np.zeros(n_joints)
        out[np.arange(n_joints) if self.joints is None else np.asarray(self.joints)] = self.torque
        return out

    def setup_mujoco(self, model, data, index) -> None:
        tau = self.per_joint(index.n_joints)
        for dofs in (index.dof_A, index.dof_B, index.dof_D):
            model.dof_frictionloss[dofs] = tau
            # a stiff friction constraint (time constant 2 physics steps): with MuJoCo's default
            # 20 ms the soft constraint acts as a damper on the light top joint, not as Coulomb
            model.dof_solref[dofs] = (2 * model.opt.timestep, 1.0)

    @classmethod
    def design(cls, data, shape, context):
        """Torque block: per joint, the friction torque of 1 N m per hinge (sign of eq 30's g:
        it adds to the torque the cables must supply along the motion)."""
        def compute():
            alpha_fast = np.stack([np.interp(data.t_fast, data.t, data.alpha[:, i]) for i in range(data.n)], axis=1)
            speed = joint_speed_from_encoders(data.theta_dot_fast, alpha_fast, data.params)
            fast = hinge_lever(alpha_fast, data.params) * np.tanh(speed / shape["width"])
            return data.to_slow(fast)

        col = data.cached((cls.name, shape["width"]), compute)
        return Design(col[:, :, None] * np.eye(data.n), np.zeros((data.S, data.C, data.n)))

    @classmethod
    def to_plant(cls, params, values, shape):
        return params, cls(torque=tuple(np.clip(np.asarray(values["tau_j"], dtype=float), 0.0, None)))

    @classmethod
    def hide(cls, params, rng, magnitude, cable, joint):
        desc = f"hinge friction {magnitude:.3f} N m in joint {joint + 1}"
        return Hidden(params, (cls(torque=magnitude, joints=(joint,)),), (), (joint,), desc, cls.name)
