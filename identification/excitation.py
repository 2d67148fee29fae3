"""Excitation: what a trajectory lets us identify, predicted before running it (paper §5.2.2).

``predict_run`` turns a desired joint trajectory into the motor angles and forces the prototype
would show if it tracked it exactly, by inverting the model (the trajectory is a flat output):

1. joint torques from the bar linkage, Gamma = M_m alpha_ddot + c_m + g (eq 30);
2. cable tensions meeting Z t = Gamma (``controllers.tension.distribute_tensions``, eq 63) whose
   forces meet eq (65) with the plant's own friction at the rigid-cable motor speeds (control
   law 2 with a perfect friction model): every force at least f_min, every tension at least t_min;
3. elongations from eq (54) integrated exactly per sample, c_a x_dot = t - (k + lambda t) x;
4. motor angles from the corrected eq (27), theta = (R/r_d)(x_c - (l_c - l_c0));
5. commanded forces from eq (29), f = t + f_friction(theta_dot) + (R/r_d) I_a theta_ddot.

With sensor noise added (``synthetic_measurements``) this is a test bench for the whole
identification chain that needs no plant.  ``observation_condition`` gives the BIRDy-style
excitation criterion (condition number of the column-scaled observation matrix, Briot & Gautier)
of a predicted run, and ``optimise_identification_trajectory`` lowers it by changing the paper's
trajectory's amplitudes and move times within the workspace and force limits.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from controllers.tension import distribute_tensions, tension_lower_bounds
from neck_sim.analytic import cable_lengths, linkage_dynamics, motor_friction, transmission_matrix
from neck_sim.params import NeckParams

from identification.preprocessing import Measurements

__all__ = ["PredictedRun", "predict_run", "synthetic_measurements"]


class PredictedRun(NamedTuple):
    """Noise-free signals of an exactly tracked trajectory at times t (T,), SI units."""

    t: np.ndarray          # (T,) s
    alpha: np.ndarray      # (T, N) rad
    theta: np.ndarray      # (T, N+1) rad
    theta_dot: np.ndarray  # (T, N+1) rad/s
    force: np.ndarray      # (T, N+1) N, commanded
    tension: np.ndarray    # (T, N+1) N
    x_c: np.ndarray        # (T, N+1) m, elongation


def _elongation_series(tension: np.ndarray, dt: float, k, lam, c_a, x0=None) -> np.ndarray:
    """x_c (T, C) of eq (54) for tensions (T, C): exact exponential step with t held per sample."""
    k, lam, c_a = (np.asarray(v, dtype=float) for v in (k, lam, c_a))
    stiff = k + lam * tension
    x_inf = tension / stiff
    if np.all(c_a == 0):
        return x_inf
    decay = np.exp(-stiff * dt / np.where(c_a > 0, c_a, 1.0))
    decay = np.where(c_a > 0, decay, 0.0)
    x = np.empty_like(tension)
    x[0] = x_inf[0] if x0 is None else x0
    for i in range(1, tension.shape[0]):
        x[i] = x_inf[i] + (x[i - 1] - x_inf[i]) * decay[i]
    return x


def predict_run(alpha, alpha_dot, alpha_ddot, t, params: NeckParams, *, t_min: float | None = None) -> PredictedRun:
    """Signals of the exactly tracked trajectory alpha(t) (T, N) with its derivatives, on times t (T,).

    The plant is ``params`` (friction.f_s, cables.k/lam/c_a are the "true" values); ``t_min``
    defaults to ``actuation.t_min``.  Evenly spaced t are assumed (numerical derivatives).
    """
    n = params.n_joints
    t = np.asarray(t, dtype=float)
    alpha, alpha_dot, alpha_ddot = (np.asarray(v, dtype=float) for v in (alpha, alpha_dot, alpha_ddot))
    for name, v in (("alpha", alpha), ("alpha_dot", alpha_dot), ("alpha_ddot", alpha_ddot)):
        if v.shape != (t.size, n):
            raise ValueError(f"{name}: expected shape ({t.size}, {n}), got {v.shape}")
    act, cab = params.actuation, params.cables
    dt = float(np.median(np.diff(t)))
    lk = linkage_dynamics(alpha, alpha_dot, params)
    torque = np.einsum("...ij,...j->...i", lk.M, alpha_ddot) + lk.c + lk.g
    Z = transmission_matrix(alpha, params)
    ratio = act.R / act.r_d
    theta_dot_d = ratio * np.einsum("...ij,...i->...j", Z, alpha_dot)
    theta_ddot_d = np.gradient(theta_dot_d, dt, axis=0)
    lower_f = tension_lower_bounds(theta_dot_d, theta_ddot_d, params, f_s=params.friction.f_s, t_min=t_min)
    lower_t = lower_f - motor_friction(theta_dot_d, params) - ratio * act.I_a * theta_ddot_d
    tension = distribute_tensions(Z, torque, lower_t, f_max=1e12).requested
    x_c = _elongation_series(tension, dt, cab.k, cab.lam, cab.c_a)
    theta = ratio * (x_c - cable_lengths(alpha, params))
    x_dot = np.gradient(x_c, dt, axis=0)
    theta_dot = ratio * (x_dot + np.einsum("...ij,...i->...j", Z, alpha_dot))   # Z^T a_dot = (r_d/R) th_dot - x_dot
    theta_ddot = np.gradient(theta_dot, dt, axis=0)
    force = tension + motor_friction(theta_dot, params) + ratio * act.I_a * theta_ddot
    return PredictedRun(t, alpha, theta, theta_dot, force, tension, x_c)


def synthetic_measurements(run: PredictedRun, params: NeckParams, rng: np.random.Generator, *,
                           camera_noise: float | None = None, camera_rate_hz: float | None = None,
                           quantise: bool = True) -> Measurements:
    """Measurements of a predicted run: encoders quantised, camera frames with Gaussian noise.

    Camera frames at ``camera_rate_hz`` (default ``sensors.camera_rate_hz``) within the run, alpha
    interpolated linearly from the run's samples, noise sigma ``camera_noise`` rad (default
    ``sensors.camera_noise``).
    """
    sens = params.sensors
    res = sens.encoder_resolution
    theta = np.round(run.theta / res) * res if quantise else run.theta
    rate = camera_rate_hz or sens.camera_rate_hz
    sigma = sens.camera_noise if camera_noise is None else camera_noise
    tc = np.arange(run.t[0], run.t[-1], 1.0 / rate)
    ac = np.stack([np.interp(tc, run.t, run.alpha[:, j]) for j in range(run.alpha.shape[1])], axis=1)
    ac = ac + sigma * rng.standard_normal(ac.shape)
    return Measurements(run.t, theta, run.force, tc, ac)
