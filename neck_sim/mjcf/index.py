"""Reading a compiled neck model: the addresses of its joints, tendons, actuators and bodies by
name (:func:`model_index`), and the hinge angles that put its bars on a closed-form pose
(:func:`pose_qpos`)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from neck_sim.analytic.geometry import _joint_local, check_alpha
from neck_sim.mjcf.paths import helper_joints, helper_name
from neck_sim.params import NeckParams

__all__ = ["ModelIndex", "model_index", "PoseQpos", "pose_qpos"]


class ModelIndex(NamedTuple):
    """Addresses in a compiled neck model (0-based arrays over joints i or cables j)."""

    n_joints: int
    qpos_A: np.ndarray        # (N,) qpos address of hinge j{i}_A
    qpos_B: np.ndarray
    qpos_D: np.ndarray
    qpos_helper: np.ndarray   # (H,) helpers in the order of helper_joints (N-1 for the paper's routing)
    qpos_motor: np.ndarray    # (m,)
    dof_A: np.ndarray
    dof_B: np.ndarray
    dof_D: np.ndarray
    dof_helper: np.ndarray
    dof_motor: np.ndarray
    cable_tendon: np.ndarray  # (m,) tendon ids of c1..c{m}
    drive_actuator: np.ndarray    # (m,)
    tension_actuator: np.ndarray  # (m,)
    loop_sites: np.ndarray    # (N, 2) site ids of j{i}_C_top, j{i}_C_bc
    bar_bodies: np.ndarray    # (3N,) body ids of the bars
    other_bodies: np.ndarray  # helpers (first H) and motors
    rigid_equality: np.ndarray    # (m,) equality ids of c{j}_rigid, or empty
    helper_joint: np.ndarray  # (H,) 0-based X-joint of each helper
    helper_tendon: np.ndarray     # (H,) tendon ids of the helpers' fixed-tendon locks
    spring_tendon: np.ndarray     # (N, 2) tendon ids of j{i}_spring_left, j{i}_spring_right
    spring_stiffness: np.ndarray  # (N, 2) their stiffness as compiled (N/m), before any effect edits it
    spring_length: np.ndarray     # (N, 2) their rest length as compiled (m)

    @property
    def n_cables(self) -> int:
        return len(self.cable_tendon)


def model_index(model) -> ModelIndex:
    """Look up every address the plant and the cross-validation need, by name."""
    import mujoco

    def ids(kind, names):
        out = []
        for nm in names:
            i = mujoco.mj_name2id(model, kind, nm)
            if i < 0:
                raise ValueError(f"model: no {kind.name.removeprefix('mjOBJ_').lower()} named {nm!r} "
                                 "(not a neck_sim model?)")
            out.append(i)
        return np.array(out, dtype=int)

    J = mujoco.mjtObj.mjOBJ_JOINT
    n = 0
    while mujoco.mj_name2id(model, J, f"j{n + 1}_A") >= 0:
        n += 1
    if n == 0:
        raise ValueError("model: no joint named 'j1_A' (not a neck_sim model?)")
    m = 0
    while mujoco.mj_name2id(model, J, f"motor{m + 1}") >= 0:
        m += 1
    jn = range(1, n + 1)
    cn = range(1, m + 1)
    helpers = [(i, side) for i in jn for side in ("left", "right")
               if mujoco.mj_name2id(model, J, helper_name(i, side)) >= 0]
    hnames = [helper_name(i, side) for i, side in helpers]
    jA, jB, jD = (ids(J, [f"j{i}_{h}" for i in jn]) for h in "ABD")
    jH = ids(J, hnames)
    jM = ids(J, [f"motor{j}" for j in cn])
    q = model.jnt_qposadr
    v = model.jnt_dofadr
    B = mujoco.mjtObj.mjOBJ_BODY
    T = mujoco.mjtObj.mjOBJ_TENDON
    bars = ids(B, [f"j{i}_{p}" for i in jn for p in ("ad", "bc", "top")])
    others = np.concatenate([ids(B, hnames), ids(B, [f"motor{j}" for j in cn])])
    rigid = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, f"c{j}_rigid") for j in cn], dtype=int)
    rigid = rigid if np.all(rigid >= 0) else np.zeros(0, dtype=int)
    S = mujoco.mjtObj.mjOBJ_SITE
    loops = np.stack([ids(S, [f"j{i}_C_top" for i in jn]), ids(S, [f"j{i}_C_bc" for i in jn])], axis=1)
    springs = ids(T, [f"j{i}_spring_{side}" for i in jn for side in ("left", "right")]).reshape(n, 2)
    return ModelIndex(n, q[jA], q[jB], q[jD], q[jH], q[jM], v[jA], v[jB], v[jD], v[jH], v[jM],
                      ids(T, [f"c{j}" for j in cn]),
                      ids(mujoco.mjtObj.mjOBJ_ACTUATOR, [f"drive{j}" for j in cn]),
                      ids(mujoco.mjtObj.mjOBJ_ACTUATOR, [f"tension{j}" for j in cn]),
                      loops, bars, others, rigid, np.array([i - 1 for i, _ in helpers], dtype=int),
                      ids(T, [f"{h}_lock" for h in hnames]), springs,
                      model.tendon_stiffness[springs].copy(), model.tendon_lengthspring[springs, 0].copy())


class PoseQpos(NamedTuple):
    """Hinge angles of the closed-form pose and their derivatives d q / d alpha_i (per joint)."""

    q_A: np.ndarray
    q_B: np.ndarray
    q_D: np.ndarray
    q_helper: np.ndarray
    dq_A: np.ndarray
    dq_B: np.ndarray
    dq_D: np.ndarray
    dq_helper: np.ndarray


def pose_qpos(alpha, params: NeckParams) -> PoseQpos:
    """Hinge angles (relative to the straight pose) that put the bars on the closed-form pose.

    q_A = angle(D - A) - its straight value, q_B = psi - psi(0), q_D = alpha - q_A, helpers
    alpha/2; shapes (..., N) (helpers (..., H), in the order of :func:`helper_joints`).  The derivatives are those of the closed form
    (eqs 1, 2, 7 differentiated), i.e. the analytic model's own kinematics.
    """
    g = params.geometry
    n = g.n_joints
    a = check_alpha(alpha, n)
    A = np.array([-g.b / 2, 0.0])
    B = np.array([g.b / 2, 0.0])
    jl = _joint_local(a, g.b, g.L)
    j0 = _joint_local(np.zeros(n), g.b, g.L)

    def ang(v):
        return np.arctan2(v[..., 1], v[..., 0])

    def cross(u, w):
        return u[..., 0] * w[..., 1] - u[..., 1] * w[..., 0]

    q_A = ang(jl.D - A) - ang(j0.D - A)
    q_B = ang(jl.C - B) - ang(j0.C - B)
    dq_A = cross(jl.D - A, jl.dD) / g.L ** 2
    dq_B = cross(jl.C - B, jl.dC) / g.L ** 2
    at = np.array([i - 1 for i, _ in helper_joints(params)], dtype=int)
    return PoseQpos(q_A, q_B, a - q_A, a[..., at] / 2, dq_A, dq_B, 1.0 - dq_A, np.full(a[..., at].shape, 0.5))
