"""Re-simulation of logged forces through the plant for a batch of parameter sets (serial stand-in).

This is the output-error fit's minimal serial engine; the parallel engine replaces this module
with the same :func:`rollout` contract.

Example::

    out = rollout([params_a, params_b], force, alpha0=np.zeros(3), integrator="implicitfast")
    out.theta.shape      # (2, T, m) motor angles, rad (not quantised)
    out.alpha.shape      # (2, T, N) joint angles at the motor sample times, rad
    out.diverged         # (2,) bool; out.reason[k] says why
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

__all__ = ["Rollouts", "rollout"]

_INTEGRATORS = {"euler": mujoco.mjtIntegrator.mjINT_EULER, "rk4": mujoco.mjtIntegrator.mjINT_RK4,
                "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
                "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST}


@dataclass(frozen=True, eq=False)
class Rollouts:
    """K open-loop runs: ``theta`` (K, T, m) rad and ``alpha`` (K, T, N) rad at the T motor sample
    times (the state before each logged force is applied), NaN from a divergence on;
    ``diverged`` (K,) bool and ``reason`` (K,) str or None."""

    theta: np.ndarray
    alpha: np.ndarray
    diverged: np.ndarray
    reason: tuple


def _plant(params, effects, integrator: str):
    from neck_sim.plant import Plant

    try:
        return Plant(params, effects, seed=0, integrator=integrator)
    except TypeError:                       # a Plant without the integrator argument
        plant = Plant(params, effects, seed=0)
        discrete = getattr(mujoco.mjtIntegrator, "mjINT_DISCRETE", None)
        plant.model.opt.integrator = discrete if integrator == "discrete" else _INTEGRATORS[integrator]
        return plant


def rollout(params, force, *, alpha0, integrator: str, effects=None) -> Rollouts:
    """Drive one plant per parameter set in ``params`` (K NeckParams) open loop with ``force``
    (T, m) N, one row per control period, from rest at ``alpha0`` (N,) rad; ``effects`` is one
    :class:`neck_sim.effects.Effects` or a list of K.  Never raises for a diverging run."""
    force = np.asarray(force, dtype=float)
    K, T = len(params), force.shape[0]
    effs = effects if isinstance(effects, (list, tuple)) else [effects] * K
    n, m = params[0].n_joints, params[0].n_cables
    theta, alpha = np.full((K, T, m), np.nan), np.full((K, T, n), np.nan)
    diverged, reason = np.zeros(K, bool), [None] * K
    for k in range(K):
        i = 0
        try:
            plant = _plant(params[k], effs[k], integrator)
            plant.reset(alpha0=alpha0)
            bad_qacc = plant.data.warning[mujoco.mjtWarning.mjWARN_BADQACC]
            for i in range(T):
                tr = plant.truth()
                theta[k, i], alpha[k, i] = tr.theta, tr.alpha
                plant.step(force[i])
                if bad_qacc.number > 0:
                    raise RuntimeError("MuJoCo reported a bad acceleration (mjWARN_BADQACC)")
        except (RuntimeError, ValueError) as exc:         # PlantDivergedError is a RuntimeError
            diverged[k], reason[k] = True, f"diverged at sample {i}: {str(exc).splitlines()[0]}"
            theta[k, i:], alpha[k, i:] = np.nan, np.nan
    return Rollouts(theta, alpha, diverged, tuple(reason))
