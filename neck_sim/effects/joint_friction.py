"""``joint_friction``: friction in the X-joints' revolute joints (the paper assumes them perfect)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from neck_sim.effects.base import Effect
from neck_sim.params import NeckParams
from neck_sim.validation import indices, per_item

__all__ = ["JointFriction"]


@dataclass(frozen=True)
class JointFriction(Effect):
    """Coulomb friction ``torque`` (N m) in each revolute hinge (A, B, D) of the affected X-joints.

    The plant sets MuJoCo's ``dof_frictionloss`` on those hinges (a constraint-based Coulomb
    friction) with a stiff ``dof_solref`` (the diagnosis fits the joint torque it gives with a
    tanh sign: :mod:`identification.diagnosis.columns.joint_friction`).
    """

    name: ClassVar[str] = "joint_friction"
    description: ClassVar[str] = "friction in the X-joints' revolute joints, resisting joint motion"
    abbreviation: ClassVar[str] = "jfric"
    kind: ClassVar[str] = "mujoco"
    magnitude_field: ClassVar[str] = "torque"
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
