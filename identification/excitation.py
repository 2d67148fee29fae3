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
identification chain that needs no plant.  ``cable_excitation`` measures, per cable, what a run
(predicted or logged) exercises: the tension range and the motor's speed range and reversals;
``joint_excitation`` the same per joint (angle range, peak speed, reversals), which is all a
per-joint effect (a side spring, a hinge's friction) is seen through.

A neck the paper's laws cannot move (m < N + 1 cables, or another routing) cannot follow the
paper's joint-space trajectory; its identification experiment is planned in tension space through
reachable, stable poses instead (:func:`controllers.reachable_paths.excitation_path`: §5.2.2's
six-move pattern along the C and S directions at two pretension levels, joined by co-contraction
moves), and ``neck-sim simulate --trajectory identification`` runs it on such a neck.  ``observation_condition`` gives the BIRDy-style
excitation criterion (condition number of the column-scaled observation matrix, Briot & Gautier)
of a predicted run, and ``optimise_identification_trajectory`` lowers it by changing the paper's
trajectory's amplitudes and move times within the workspace and force limits.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from controllers.tension import distribute_tensions, tension_lower_bounds
from neck_sim.analytic import (cable_lengths, elongation_series, linkage_dynamics, motor_friction,
                               transmission_matrix)
from neck_sim.params import NeckParams
from neck_sim.trajectory import Trajectory

from identification import regressors as reg
from identification.preprocessing import Measurements, Prepared

__all__ = ["PredictedRun", "predict_run", "CableExcitation", "cable_excitation", "JointExcitation",
           "joint_excitation", "synthetic_measurements", "prepared_from_prediction", "ExcitationQuality",
           "excitation_quality", "sequences_trajectory", "paper_amplitudes", "OptimisedExcitation",
           "optimise_identification_trajectory"]


class PredictedRun(NamedTuple):
    """Noise-free signals of an exactly tracked trajectory at times t (T,), SI units."""

    t: np.ndarray          # (T,) s
    alpha: np.ndarray      # (T, N) rad
    theta: np.ndarray      # (T, N+1) rad
    theta_dot: np.ndarray  # (T, N+1) rad/s
    force: np.ndarray      # (T, N+1) N, commanded
    tension: np.ndarray    # (T, N+1) N
    x_c: np.ndarray        # (T, N+1) m, elongation


def predict_run(alpha: npt.ArrayLike, alpha_dot: npt.ArrayLike, alpha_ddot: npt.ArrayLike, t: npt.ArrayLike,
                params: NeckParams, *, t_min: float | None = None) -> PredictedRun:
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
    x_c = elongation_series(tension, dt, cab.k, cab.lam, cab.c_a)
    theta = ratio * (x_c - cable_lengths(alpha, params))
    x_dot = np.gradient(x_c, dt, axis=0)
    theta_dot = ratio * (x_dot + np.einsum("...ij,...i->...j", Z, alpha_dot))   # Z^T a_dot = (r_d/R) th_dot - x_dot
    theta_ddot = np.gradient(theta_dot, dt, axis=0)
    force = tension + motor_friction(theta_dot, params) + ratio * act.I_a * theta_ddot
    return PredictedRun(t, alpha, theta, theta_dot, force, tension, x_c)


class CableExcitation(NamedTuple):
    """Per cable (m,): tension range (N), motor speed range (rad/s) and the number of times the
    motor reverses (speed sign changes between samples faster than the threshold)."""

    tension_min: np.ndarray
    tension_max: np.ndarray
    speed_min: np.ndarray
    speed_max: np.ndarray
    reversals: np.ndarray


def cable_excitation(t: npt.ArrayLike, theta: npt.ArrayLike, tension: npt.ArrayLike, *, start: float = 1.0,
                     moving: float = 0.5) -> CableExcitation:
    """What a run exercises per cable: ``t`` (T,) s, motor angles ``theta`` (T, m) rad and tensions
    (T, m) N; samples before ``start`` s (the cables' take-up) are left out, and a reversal counts
    between samples whose speed exceeds ``moving`` rad/s (speed from central differences)."""
    t = np.asarray(t, dtype=float)
    keep = t >= start
    speed = np.gradient(np.asarray(theta, dtype=float), t, axis=0)[keep]
    ten = np.asarray(tension, dtype=float)[keep]
    rev = []
    for c in range(speed.shape[1]):
        s = np.sign(speed[np.abs(speed[:, c]) > moving, c])
        rev.append(int(np.count_nonzero(np.diff(s))))
    return CableExcitation(ten.min(0), ten.max(0), speed.min(0), speed.max(0), np.array(rev))


class JointExcitation(NamedTuple):
    """Per joint (N,): the angle range max - min (rad), the largest |speed| (rad/s) and the number
    of times the joint reverses (speed sign changes between samples faster than the threshold)."""

    angle_range: np.ndarray
    speed_max: np.ndarray
    reversals: np.ndarray


def joint_excitation(t: npt.ArrayLike, alpha: npt.ArrayLike, *, start: float = 1.0,
                     moving: float = 0.05) -> JointExcitation:
    """What a run exercises per joint: ``t`` (T,) s and joint angles ``alpha`` (T, N) rad (the
    camera's, or a plan's); samples before ``start`` s are left out, a reversal counts between
    samples faster than ``moving`` rad/s (speed from central differences, so camera noise
    inflates ``speed_max``: smooth the angles first when that matters).  A per-joint effect (a side
    spring, a hinge's friction) is seen through its joint's range and reversals only: the
    diagnosis's gap notes ask for 5 deg of motion per joint."""
    t = np.asarray(t, dtype=float)
    keep = t >= start
    a = np.asarray(alpha, dtype=float)
    speed = np.gradient(a, t, axis=0)[keep]
    rev = [int(np.count_nonzero(np.diff(np.sign(speed[np.abs(speed[:, j]) > moving, j]))))
           for j in range(speed.shape[1])]
    return JointExcitation(np.ptp(a[keep], axis=0), np.abs(speed).max(0), np.array(rev))


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


def prepared_from_prediction(run: PredictedRun, alpha_dot: npt.ArrayLike, alpha_ddot: npt.ArrayLike,
                             rate_hz: float) -> Prepared:
    """A :class:`Prepared` of a predicted run sampled at ``rate_hz`` (no noise, no filtering)."""
    step = max(1, int(round(1.0 / (rate_hz * float(np.median(np.diff(run.t)))))))
    h = step * float(np.median(np.diff(run.t)))
    sl = slice(None, None, step)
    theta_dot = run.theta_dot[sl]
    x = run.x_c[sl]
    x_dot = np.gradient(x, h, axis=0)
    return Prepared(t=run.t[sl], theta=run.theta[sl], theta_dot=theta_dot,
                    theta_ddot=np.gradient(theta_dot, h, axis=0), force=run.force[sl], alpha=run.alpha[sl],
                    alpha_dot=np.asarray(alpha_dot)[sl], alpha_ddot=np.asarray(alpha_ddot)[sl], x_c=x,
                    x_c_dot=x_dot, x_c_ddot=np.gradient(x_dot, h, axis=0), motor_rate_hz=1.0 / h, rate_hz=1.0 / h,
                    decimation=1, camera=(run.t[sl], run.alpha[sl]))


class ExcitationQuality(NamedTuple):
    """Predicted conditioning of a trajectory's observation matrices (column-scaled, BIRDy-style).

    cond_friction, cond_elastic, cond_variable: models of eqs (46-47), (44-45), (54-57);
    force_max N, the largest predicted force; tension_range (N+1,) N, max - min tension per cable.
    """

    cond_friction: float
    cond_elastic: float
    cond_variable: float
    force_max: float
    tension_range: np.ndarray


def excitation_quality(trajectory: Trajectory, params: NeckParams, *, rate_hz: float = 100.0,
                       obs_rate_hz: float = 31.25) -> ExcitationQuality:
    """Predict the run of ``trajectory`` (``controllers.trajectories.Trajectory``) on ``params``
    and condition the observation matrices it would give (sampled at ``obs_rate_hz``)."""
    t = np.arange(0.0, trajectory.duration, 1.0 / rate_hz)
    s = trajectory.sample(t)
    run = predict_run(s.alpha, s.alpha_dot, s.alpha_ddot, t, params)
    prep = prepared_from_prediction(run, s.alpha_dot, s.alpha_ddot, obs_rate_hz)
    dyn = reg.joint_dynamics(prep, params)
    conds = []
    for W in (reg.friction_model(prep, params, dyn).W, reg.elastic_model(prep, params, dyn=dyn).W,
              reg.variable_stiffness_model(prep, params, params.friction.f_s).W):
        Ws = W / np.linalg.norm(W, axis=0)
        sv = np.linalg.svd(Ws, compute_uv=False)
        conds.append(float(sv[0] / sv[-1]))
    return ExcitationQuality(conds[0], conds[1], conds[2], float(run.force.max()), np.ptp(run.tension, axis=0))


def sequences_trajectory(amplitudes: npt.ArrayLike, move_time: float = 2.5, hold_time: float = 1.0,
                         name: str = "identification") -> Trajectory:
    """The §5.2.2 shape for any amplitudes (S, N) rad: per sequence a, -a, 0, -a, a, 0 from straight."""
    from controllers.trajectories import cycloidal_path

    amps = np.asarray(amplitudes, dtype=float)
    if amps.ndim != 2:
        raise ValueError(f"amplitudes: expected shape (sequences, N), got {amps.shape}")
    zero = np.zeros(amps.shape[1])
    poses = [zero]
    for a in amps:
        poses += [a, -a, zero, -a, a, zero]
    return cycloidal_path(poses, move_time, hold_time, name=name)


def paper_amplitudes(n_joints: int = 3) -> np.ndarray:
    """The paper's four sequences for N = 3 (rad): [40, 30, 20] deg, then each joint flipped."""
    base = np.radians(np.linspace(40.0, 20.0, n_joints))
    amps = np.tile(base, (n_joints + 1, 1))
    for j in range(n_joints):
        amps[j + 1, j] *= -1
    return amps


class OptimisedExcitation(NamedTuple):
    amplitudes: np.ndarray          # (S, N) rad
    trajectory: object              # controllers.trajectories.Trajectory
    quality: ExcitationQuality
    initial_quality: ExcitationQuality
    evaluations: int


def optimise_identification_trajectory(params: NeckParams, *, initial: npt.ArrayLike | None = None,
                                       move_time: float = 2.5,
                                       hold_time: float = 1.0, max_amplitude: float = np.radians(50.0),
                                       force_limit: float | None = None, max_evaluations: int = 300,
                                       rate_hz: float = 50.0) -> OptimisedExcitation:
    """Amplitudes of the §5.2.2 sequences that minimise the predicted condition number of the
    variable-stiffness observation matrix (eqs 56-57), the least well-conditioned of the three.

    Same shape, move and hold times as the paper's (so the same duration); each amplitude within
    +-``max_amplitude``; predicted forces above ``force_limit`` (default 0.9 f_max) are penalised.
    Nelder-Mead from ``initial`` (default the paper's amplitudes; first steps of 10 deg towards
    zero), ``max_evaluations`` predictions at ``rate_hz``; the best point evaluated is returned.
    """
    from scipy.optimize import minimize

    x0 = paper_amplitudes(params.n_joints) if initial is None else np.asarray(initial, dtype=float)
    shape = x0.shape
    limit = 0.9 * params.actuation.f_max if force_limit is None else force_limit
    best: dict[str, Any] = {"cost": np.inf, "x": None, "n": 0}

    def cost(x):
        best["n"] += 1
        inside = np.clip(x, -max_amplitude, max_amplitude)
        q = excitation_quality(sequences_trajectory(inside.reshape(shape), move_time, hold_time), params,
                               rate_hz=rate_hz)
        c = q.cond_variable + 0.5 * max(0.0, q.force_max - limit) + 10.0 * np.abs(x - inside).sum()
        if c < best["cost"]:            # keep the best point evaluated, whatever the simplex does
            best.update(cost=c, x=inside.copy())
        return c

    start = np.clip(x0.ravel(), -max_amplitude, max_amplitude)
    step = np.radians(10.0)
    simplex = np.vstack([start] + [start + step * np.sign(-start[i] or 1.0) * np.eye(start.size)[i]
                                   for i in range(start.size)])
    minimize(cost, start, method="Nelder-Mead",
             options={"maxfev": max_evaluations, "initial_simplex": simplex, "xatol": 1e-3, "fatol": 1e-3})
    count = [best["n"]]
    amps = best["x"].reshape(shape)
    traj = sequences_trajectory(amps, move_time, hold_time, name="identification (optimised)")
    return OptimisedExcitation(amps, traj, excitation_quality(traj, params, rate_hz=rate_hz),
                               excitation_quality(sequences_trajectory(x0, move_time, hold_time), params,
                                                  rate_hz=rate_hz), count[0])
