"""Static-feasible workspace of a neck with any cable count.

In the sense of CASPR's wrench-feasible workspace: the poses the neck can *hold* with cable
tensions in [f_min, f_max].  With m < N + 1 cables those poses form an m-dimensional set, so they
are found from the force side: tensions are sampled uniformly in the box, the equilibrium of each
is solved from the straight pose (:func:`~neck_sim.analytic.statics.equilibrium_for_forces`), and
a sample belongs to the workspace when the equilibrium lies inside the joint range and is stable
with the motors held (elastic cables, ``K_theta`` positive definite: how a position-controlled
neck holds it).  Whether it is also stable under pure force control (``K_f``) is recorded too.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from neck_sim.analytic.geometry import forward_kinematics
from neck_sim.analytic.statics import (equilibrium_for_forces, head_jacobian, motor_angles_for, motor_stiffness,
                                       with_payload)
from neck_sim.params import NeckParams

__all__ = ["Workspace", "sample_workspace", "head_stiffness"]


class Workspace(NamedTuple):
    """S force samples and their equilibria.

    forces (S, m) N; alpha (S, N) rad (NaN where no equilibrium in range); head (S, 3) head bar
    centre x, y (m) and angle (rad); feasible (S,) in range and stable with held motors;
    force_stable (S,) also stable under force control; min_eig_force, min_eig_motor (S,) N m/rad
    the smallest eigenvalues of K_f and K_theta; lateral_stiffness (S,) N/m the head's stiffness
    along x with held motors.
    """

    forces: np.ndarray
    alpha: np.ndarray
    head: np.ndarray
    feasible: np.ndarray
    force_stable: np.ndarray
    min_eig_force: np.ndarray
    min_eig_motor: np.ndarray
    lateral_stiffness: np.ndarray


def head_stiffness(alpha: npt.ArrayLike, stiffness: np.ndarray, params: NeckParams) -> np.ndarray:
    """Stiffness of the head bar's centre along x and y, (..., 2) N/m: 1 / diag(J K^-1 J^T),
    J the head Jacobian, K (..., N, N) N m/rad a stiffness matrix at ``alpha``."""
    J = head_jacobian(alpha, params)[..., :2, :]
    compliance = np.einsum("...ai,...ia->...a", J, np.linalg.solve(stiffness, np.swapaxes(J, -1, -2)))
    with np.errstate(divide="ignore"):
        return 1.0 / compliance


def sample_workspace(params: NeckParams, samples: int = 1000, *, seed: int = 0, f_min: float | None = None,
                     f_max: float | None = None, payload_mass: float | None = None, progress: bool = False,
                     chunk: int = 250) -> Workspace:
    """Sample ``samples`` tension vectors uniformly in [f_min, f_max]^m and solve their equilibria."""
    p = with_payload(params, payload_mass)
    if samples < 1:
        raise ValueError(f"samples: need at least 1, got {samples}")
    lo = p.actuation.f_min if f_min is None else float(f_min)
    hi = p.actuation.f_max if f_max is None else float(f_max)
    if not 0 <= lo < hi:
        raise ValueError(f"force box: need 0 <= f_min < f_max, got [{lo}, {hi}] N")
    forces = np.random.default_rng(seed).uniform(lo, hi, (samples, p.n_cables))
    parts = []
    starts = range(0, samples, chunk)
    if progress:
        from tqdm.auto import tqdm
        starts = tqdm(starts, desc=f"workspace N={p.n_joints} m={p.n_cables}", unit="chunk", mininterval=0.5)
    for s in starts:
        parts.append(equilibrium_for_forces(forces[s:s + chunk], p))
    alpha = np.concatenate([e.alpha for e in parts])
    ok = np.concatenate([e.converged for e in parts])
    eig_f = np.concatenate([e.eigenvalues[:, 0] for e in parts])
    safe = np.where(ok[:, None], alpha, 0.0)
    K_m = motor_stiffness(safe, motor_angles_for(safe, forces, p), p)
    eig_m = np.linalg.eigvalsh(K_m)[:, 0]
    feasible = ok & (eig_m > 0)
    kin = forward_kinematics(safe, p)
    head = np.concatenate([kin.head_position, kin.head_angle[:, None]], -1)
    lateral = np.where(feasible, head_stiffness(safe, K_m, p)[:, 0], np.nan)
    nan = np.where(ok, 0.0, np.nan)
    return Workspace(forces, alpha + nan[:, None], head + nan[:, None], feasible, feasible & (eig_f > 0), eig_f + nan,
                     eig_m + nan, lateral)
