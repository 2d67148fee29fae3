"""Serial re-simulation with unquantised motor angles: the fit's fallback engine.

Same contract as :func:`identification.output_error.rollouts.rollout` (an ``Experiment`` and K
parameter sets in; ``Rollouts`` out), but ``encoders`` holds the motor angles before
quantisation, which the fit's finite-difference Jacobian needs (a step of 1e-5 moves an angle by
far less than one encoder count), and the camera angles are interpolated from the control-period
states (2 ms apart; the error is below 1e-5 rad, against a camera noise of 1.7e-2 rad).
"""

from __future__ import annotations

import mujoco
import numpy as np

from identification.output_error.rollouts import Rollouts

__all__ = ["rollout"]


def rollout(experiment, params, effects=None, *, integrator: str) -> "Rollouts":
    """Run the K parameter sets one after the other; never raises for a diverging set."""
    from neck_sim.plant import Plant

    exp = experiment
    K, T = len(params), exp.n_periods
    effs = list(effects) if isinstance(effects, (list, tuple)) else [effects] * K
    n, m = params[0].n_joints, params[0].n_cables
    theta, alpha = np.full((K, T, m), np.nan), np.full((K, T + 1, n), np.nan)
    diverged, at, reasons = np.zeros(K, bool), np.full(K, np.nan), [""] * K
    t = np.arange(T + 1) * exp.period
    for k in range(K):
        i = 0
        try:
            plant = Plant(params[k], effs[k], seed=0, integrator=integrator)
            plant.reset(alpha0=exp.alpha0)
            bad_qacc = plant.data.warning[mujoco.mjtWarning.mjWARN_BADQACC]
            for i in range(T):
                tr = plant.truth()
                theta[k, i], alpha[k, i] = tr.theta, tr.alpha
                plant.step(exp.force[i])
                if bad_qacc.number > 0:
                    raise RuntimeError("diverged: MuJoCo reported bad qacc (NaN or huge)")
            alpha[k, T] = plant.truth().alpha
        except (RuntimeError, ValueError) as exc:         # PlantDivergedError is a RuntimeError
            diverged[k], at[k], reasons[k] = True, i * exp.period, str(exc).splitlines()[0]
            theta[k, i:], alpha[k, i:] = np.nan, np.nan
    cam = np.stack([np.stack([np.interp(exp.camera_t, t, alpha[k, :, j]) for j in range(n)], axis=1)
                    for k in range(K)])
    return Rollouts(theta, cam, diverged, at, tuple(reasons))
