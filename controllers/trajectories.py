"""Joint-space reference trajectories (re-exported from :mod:`neck_sim.trajectory`), fitted to the
neck's force limits.

The cycloidal segments and the paper's two trajectories are defined once, in the model core,
so that the dm_control environment (:mod:`neck_sim.env`) can use them without importing
``controllers`` (layer rule).  Import them from here or from ``neck_sim.trajectory``.

A long neck cannot follow the paper's angles: with N + 1 cables each held above t_min plus its
friction, the long left cable balances all the right ones, and gravity acts on a longer lever.
:func:`make_trajectory` here therefore scales the joint angles down (never up) until the
computed-torque forces along the reference stay within a fraction of f_max
(:func:`workspace_amplitude`); the paper's N = 3 neck keeps amplitude 1.
"""

from __future__ import annotations

import numpy as np

from controllers.computed_torque import ComputedTorqueController, ControlLaw, MotorReference
from controllers.tension import TensionInfeasibleError, distribute_tensions
from neck_sim.analytic import gravity_spring_torque, mass_matrix, transmission_matrix
from neck_sim.params import NeckParams
from neck_sim.trajectory import (HOLD_TIME, MOVE_TIME, TRAJECTORIES, Trajectory, TrajectorySample,
                                 control_test_trajectory, cycloidal_path, identification_trajectory,
                                 scaled_trajectory)

__all__ = ["MOVE_TIME", "HOLD_TIME", "TrajectorySample", "Trajectory", "cycloidal_path", "reference_feedforward",
           "control_test_trajectory", "identification_trajectory", "TRAJECTORIES", "make_trajectory",
           "feedforward_forces", "workspace_amplitude", "FORCE_MARGIN"]

FORCE_MARGIN = 0.9
"""Share of f_max the feed-forward forces may use; the rest is left to the feedback (eq 59)."""


def feedforward_forces(trajectory: Trajectory, params: NeckParams, sample_dt: float = 0.02) -> np.ndarray:
    """Cable forces (K, N+1) N that law 2 requests along ``trajectory`` when it tracks perfectly.

    Computed torque of eq (66) at the reference (w = alpha_d_ddot, no feedback), with the friction
    and the eq (65) bounds of :class:`ComputedTorqueController`, distributed by eqs (63)-(64)
    without clipping, every ``sample_dt`` s.  Raises TensionInfeasibleError where no positive
    forces exist.
    """
    ctrl = ComputedTorqueController(params, ControlLaw.FRICTION)
    t = np.arange(0.0, trajectory.duration + 0.5 * sample_dt, sample_dt)
    return reference_feedforward(ctrl.motor_reference(trajectory.sample(t)), params)[1]


def reference_feedforward(ref: MotorReference, params: NeckParams) -> tuple[np.ndarray, np.ndarray]:
    """Law 2's feed-forward at a :class:`~controllers.computed_torque.MotorReference` (no feedback):
    gamma (..., N) N m of eq (66) with w = alpha_d'' and the eq (63)-(65) forces (..., N+1) N that
    produce it, unclipped."""
    a = ref.alpha
    Z = transmission_matrix(a, params)
    gamma = (np.einsum("...ij,...j->...i", mass_matrix(a, params), ref.alpha_ddot)
             + gravity_spring_torque(a, params) + np.einsum("...ij,...j->...i", Z, ref.friction))
    return gamma, distribute_tensions(Z, gamma, ref.lower, 1e12).requested     # 1e12 N: no clipping


def workspace_amplitude(name: str, params: NeckParams, duration_scale: float = 1.0, *,
                        margin: float = FORCE_MARGIN, resolution: float = 0.01) -> float:
    """Largest amplitude in (0, 1] (to ``resolution``) of trajectory ``name`` whose
    :func:`feedforward_forces` stay within ``margin`` f_max; 1 when the full trajectory does.

    Raises ValueError when even holding the straight pose needs more (the neck's f_max or t_min
    cannot carry its N + 1 cables).
    """
    limit = margin * params.actuation.f_max

    def fits(s: float) -> bool:
        # s = 0 stands for the straight pose held, which every trajectory starts from
        traj = scaled_trajectory(name, params, duration_scale, amplitude=max(s, 1e-9))
        try:
            return float(feedforward_forces(traj, params).max()) <= limit
        except TensionInfeasibleError:
            return False

    if fits(1.0):
        return 1.0
    if not fits(0.0):
        raise ValueError(f"{name}: even the straight pose of this {params.n_joints}-joint neck needs cable "
                         f"forces above {margin:g} f_max = {limit:g} N (raise actuation.f_max or lower t_min)")
    lo, hi = 0.0, 1.0                                   # fits(lo) and not fits(hi)
    while hi - lo > resolution:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if fits(mid) else (lo, mid)
    return lo


def make_trajectory(name: str, params: NeckParams, duration_scale: float = 1.0,
                    amplitude: float | None = None) -> Trajectory:
    """One of :data:`TRAJECTORIES` by name, move and hold times times ``duration_scale``, joint
    angles times ``amplitude`` (default :func:`workspace_amplitude`: 1 for the paper's neck,
    smaller for a neck too long to follow the paper's angles within f_max).

    A scaled trajectory is named ``"<name> x<amplitude>"`` (:func:`neck_sim.trajectory.scaled_trajectory`)
    so that logs and tables say so.
    """
    s = workspace_amplitude(name, params, duration_scale) if amplitude is None else amplitude
    return scaled_trajectory(name, params, duration_scale, amplitude=s)
