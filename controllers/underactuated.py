"""Moving a neck with fewer cables than N + 1: inverse statics + motor PID.

A neck with m < N + 1 cables holds only an m-dimensional set of poses (the equilibria of
:mod:`neck_sim.analytic.statics`), so its reference must stay on that set, and its pose follows
from the motor angles through the elastic cables rather than from a torque command.

* :class:`ReachablePath` plans on the reachable set: waypoint tensions (from
  :func:`~neck_sim.analytic.statics.inverse_statics` for target shapes), cycloidal moves between
  them in tension space, the equilibrium of every grid point (continuation from the previous
  one), and a cubic spline of those poses.  It has the interface of
  :class:`neck_sim.trajectory.Trajectory`, so :func:`controllers.closed_loop.run_closed_loop` runs it.
* :class:`UnderactuatedController`, every control period: the holding tensions of the reference
  pose, t_d = Z^+ g (exact on the reachable set), the motor angles that hold it with elastic
  cables, theta_d = (R/r_d)(x_c(t_d) - (l_c - l_c0)) (eq 54 inverted, sign convention of
  :mod:`neck_sim.analytic.cables`), and a PID on the motor angles (in cable length, m) plus the
  feed-forward t_d and the believed friction of eq (37) at the desired motor speed:

      f = t_d + f_friction(theta_d') + K_p e + K_d e' + K_i int e,   e = (r_d/R)(theta_d - theta).

  The pose estimate (for logs and the error metrics) is the static equilibrium of the measured
  motor angles (:func:`~neck_sim.analytic.statics.held_pose`), refreshed every
  ``estimate_every`` periods.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from controllers.computed_torque import ControlStep
from neck_sim.analytic.cables import transmission_matrix
from neck_sim.analytic.dynamics import gravity_spring_torque, motor_friction
from neck_sim.analytic.statics import equilibrium_for_forces, held_pose, motor_angles_for, motor_stiffness
from neck_sim.params import NeckParams
from neck_sim.trajectory import TrajectorySample

__all__ = ["ReachablePath", "ReachableSample", "UnderactuatedReference", "UnderactuatedController",
           "holding_tensions"]


class ReachableSample(NamedTuple):
    """A :class:`~neck_sim.trajectory.TrajectorySample` on the reachable set with the tensions
    that hold it, t.shape + (N,) rad, rad/s, rad/s^2 and t.shape + (m,) N."""

    alpha: np.ndarray
    alpha_dot: np.ndarray
    alpha_ddot: np.ndarray
    tension: np.ndarray


def holding_tensions(alpha: npt.ArrayLike, params: NeckParams, t_min: float = 0.0) -> np.ndarray:
    """Tensions (..., m) N with Z t = g at poses ``alpha`` (..., N): Z^+ g, least squares.

    On the reachable set of an m <= N neck with a well-conditioned Z this is the unique holding
    tension; antagonist pairs make Z nearly rank-deficient near symmetric poses (their
    co-contraction), so a path should carry its own tensions (:class:`ReachableSample`).  With a null space
    (m = N + 1: co-contraction) the positive null vector is added until the smallest tension is
    ``t_min``.
    """
    Z = transmission_matrix(alpha, params)
    g = gravity_spring_torque(alpha, params)
    t = np.einsum("...ij,...j->...i", np.linalg.pinv(Z), g)
    n, m = params.n_joints, params.n_cables
    if m > n:
        null = np.linalg.svd(Z)[2][..., -1, :]                       # (..., m), unit
        null = null * np.sign(null.sum(-1, keepdims=True))
        positive = np.all(null > 0, -1, keepdims=True)
        shift = np.max((t_min - t) / np.where(null > 0, null, np.inf), -1, keepdims=True)
        t = t + np.where(positive, shift * null, 0.0)
    return t


class ReachablePath:
    """A path of equilibria through tension waypoints (K+1, m) N, cycloidal in tension space.

    ``move_time`` s per move, ``hold_time`` s at each waypoint (also before the first move, for the
    cables to take up their slack); equilibria solved every ``grid_dt`` s.
    """

    labels: list[str]       # a name per waypoint, set by the planners of controllers.reachable_paths

    def __init__(self, params: NeckParams, waypoints: npt.ArrayLike, *, move_time: float = 2.5, hold_time: float = 1.0,
                 grid_dt: float = 0.05, name: str = "reachable path", alpha0: npt.ArrayLike | None = None) -> None:
        from scipy.interpolate import CubicSpline

        w = np.asarray(waypoints, dtype=float)
        if w.ndim != 2 or w.shape[0] < 2 or w.shape[1] != params.n_cables:
            raise ValueError(f"waypoints: expected (K+1, {params.n_cables}) tensions, K >= 1, got {w.shape}")
        if move_time <= 0 or hold_time < 0 or grid_dt <= 0:
            raise ValueError("move_time and grid_dt must be > 0, hold_time >= 0")
        self.params, self.name, self.waypoints = params, name, w
        knots, forces = [0.0], [w[0]]
        for k in range(1, len(w)):
            knots += [knots[-1] + hold_time, knots[-1] + hold_time + move_time]
            forces += [w[k - 1], w[k]]
        knots.append(knots[-1] + hold_time)
        forces.append(w[-1])
        self.knots, self.knot_forces = np.array(knots), np.array(forces)
        self.duration = float(knots[-1])
        t = np.linspace(0.0, self.duration, int(np.ceil(self.duration / grid_dt)) + 1)
        f = self.forces_at(t)
        alpha = np.empty((t.size, params.n_joints))
        a = np.zeros(params.n_joints) if alpha0 is None else np.asarray(alpha0, dtype=float)
        for k in range(t.size):                    # continuation along the path
            eq = equilibrium_for_forces(f[k], params, a)
            if not eq.converged:
                raise ValueError(f"{name}: no equilibrium in the joint range at t = {t[k]:.2f} s "
                                 f"(tensions {np.round(f[k], 1).tolist()} N): the path leaves the reachable set")
            a = alpha[k] = eq.alpha
        # a position-controlled neck holds only equilibria that are stable with the motors held
        K = motor_stiffness(alpha, motor_angles_for(alpha, f, params), params)
        unstable = np.linalg.eigvalsh(K)[:, 0] <= 0
        if unstable.any():
            k = int(np.argmax(unstable))
            raise ValueError(f"{name}: the equilibrium at t = {t[k]:.2f} s (tensions {np.round(f[k], 1).tolist()} N) "
                             "is unstable even with the motors held (K_theta not positive definite): raise the "
                             "pretension or choose other waypoints")
        self.grid_t, self.grid_alpha = t, alpha
        self._spline = CubicSpline(t, alpha, axis=0, bc_type="clamped")

    def forces_at(self, t: npt.ArrayLike) -> np.ndarray:
        """Tensions (..., m) N on the path at times t (cycloidal between waypoints)."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        k = np.clip(np.searchsorted(self.knots, t, side="right") - 1, 0, len(self.knots) - 2)
        t0, t1 = self.knots[k], self.knots[k + 1]
        tau = np.where(t1 > t0, (t - t0) / np.where(t1 > t0, t1 - t0, 1.0), 0.0)
        s = tau - np.sin(2 * np.pi * tau) / (2 * np.pi)
        return self.knot_forces[k] + s[..., None] * (self.knot_forces[k + 1] - self.knot_forces[k])

    @property
    def n_joints(self) -> int:
        return self.params.n_joints

    def sample(self, t: npt.ArrayLike) -> ReachableSample:
        """Reference poses, velocities, accelerations t.shape + (N,) and holding tensions (m,)."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        return ReachableSample(self._spline(t), self._spline(t, 1), self._spline(t, 2), self.forces_at(t))

    def check_workspace(self, params: NeckParams) -> None:
        if params.n_joints != self.n_joints:
            raise ValueError(f"{self.name}: a path for {self.n_joints} joints, the controller has {params.n_joints}")


class UnderactuatedReference(NamedTuple):
    """Reference batched over time (T, ...) or one sample: alpha (..., N) rad, tension (..., m) N
    holding it, theta, theta_dot (..., m) the motor angles (rad) and speeds (rad/s) that hold it,
    friction (..., m) N the believed friction at theta_dot."""

    alpha: np.ndarray
    tension: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    friction: np.ndarray

    def at(self, k: int) -> "UnderactuatedReference":
        return UnderactuatedReference(*(x[k] for x in self))


class UnderactuatedController:
    """Inverse statics on the reachable set + motor-angle PID (module docstring).

    ``params``: the controller's model; ``f_s`` (m,) N the friction it believes (default the
    model's ``friction.f_s``); ``bandwidth`` rad/s of the motor loop (K_p = m_r w^2, K_d = 2 m_r w,
    K_i = ``integral`` m_r w^3 / 4 with m_r = I_a (R/r_d)^2 the motor inertia seen along the cable);
    ``estimate_every`` periods between two static pose estimates.

    No integral action by default: the joint-space modes the cables cannot reach (N - m of them)
    are damped only by the cables and the motors' friction, and the integrator's phase lag feeds
    them.  On the 10-X, 4-cable neck held straight at 61 N after a 3 N kick, the largest joint error
    per 1.5 s grew from 2.7 to 9.5 deg over 15 s with ``integral=1`` at 40 rad/s and fell from 5.2 to 2.2 deg
    with ``integral=0`` and ``bandwidth=20`` (7.0 to 4.0 deg at 40 rad/s).  The feed-forward
    tension already holds the pose; the proportional term's static error is (tension error) / K_p,
    about 0.2 mm of cable per N at 20 rad/s.
    """

    law = 0     # not one of the paper's computed-torque laws (logs record it as 0)

    def __init__(self, params: NeckParams, *, f_s: npt.ArrayLike | None = None, bandwidth: float = 20.0,
                 integral: float = 0.0, estimate_every: int = 10) -> None:
        self.params = params
        m = params.n_cables
        self.f_s = np.asarray(params.friction.f_s if f_s is None else f_s, dtype=float)
        if self.f_s.shape != (m,) or not np.all(np.isfinite(self.f_s)):
            raise ValueError(f"f_s: expected {m} finite values (one per cable), got {self.f_s!r}")
        if not (np.isfinite(bandwidth) and bandwidth > 0):
            raise ValueError(f"bandwidth: must be positive (rad/s), got {bandwidth}")
        if not (np.isfinite(integral) and integral >= 0):
            raise ValueError(f"integral: must be finite and >= 0, got {integral}")
        if int(estimate_every) < 1:
            raise ValueError(f"estimate_every: must be >= 1, got {estimate_every}")
        act = params.actuation
        m_r = act.reflected_inertia
        self.gains = (m_r * bandwidth ** 2, 2 * m_r * bandwidth, integral * m_r * bandwidth ** 3 / 4)
        self.ratio = act.r_d / act.R                    # cable length per motor radian
        self.dt = 1.0 / params.control.rate_hz
        self.estimate_every = int(estimate_every)
        self.reset()

    def motor_reference(self, sample: ReachableSample | TrajectorySample) -> UnderactuatedReference:
        """Holding tensions (the sample's own, else :func:`holding_tensions`), motor angles and
        speeds for reference poses (batched)."""
        p = self.params
        a, ad = np.asarray(sample.alpha, dtype=float), np.asarray(sample.alpha_dot, dtype=float)
        t = getattr(sample, "tension", None)
        t = np.maximum(holding_tensions(a, p, p.actuation.t_min) if t is None else np.asarray(t, dtype=float), 0.0)
        theta = motor_angles_for(a, t, p)
        # rigid part of eq (21): the elongation changes little along a path
        theta_dot = np.einsum("...ij,...i->...j", transmission_matrix(a, p), ad) / self.ratio
        return UnderactuatedReference(a, t, theta, theta_dot, motor_friction(theta_dot, p, self.f_s))

    def reset(self, alpha0: npt.ArrayLike | None = None, theta0: npt.ArrayLike | None = None) -> None:
        n, m = self.params.n_joints, self.params.n_cables
        self.alpha_hat = np.zeros(n) if alpha0 is None else np.asarray(alpha0, dtype=float).copy()
        self._integral = np.zeros(m)
        self._theta_prev = None if theta0 is None else np.asarray(theta0, dtype=float).copy()
        self._k = 0

    def _estimate(self, theta) -> None:
        # one Newton step from the last estimate per refresh: the pose moves little in between;
        # the solver's own lengths and Z at that pose are those of cable_lengths and transmission_matrix
        held = held_pose(theta, self.params, self.alpha_hat, max_iter=2)
        self.alpha_hat, self._lengths, self._Z = held.equilibrium.alpha, held.lengths, held.Z

    def step(self, theta: npt.ArrayLike, ref: UnderactuatedReference) -> ControlStep:
        """Forces (m,) N for the next period from encoder angles ``theta`` (m,) rad."""
        p = self.params
        theta = np.asarray(theta, dtype=float)
        if self._theta_prev is None:
            self._theta_prev = theta
        e = self.ratio * (ref.theta - theta)
        e_dot = self.ratio * (ref.theta_dot - (theta - self._theta_prev) / self.dt)
        self._integral += e * self.dt
        k_p, k_d, k_i = self.gains
        requested = ref.tension + ref.friction + k_p * e + k_d * e_dot + k_i * self._integral
        f_max = p.actuation.f_max
        forces = np.clip(requested, 0.0, f_max)
        saturated = requested > f_max
        # anti-windup: do not integrate further into a saturated command
        self._integral -= np.where(saturated | (requested < 0), e * self.dt, 0.0)
        self._theta_prev = theta
        if self._k % self.estimate_every == 0:
            self._estimate(theta)
        self._k += 1
        elongation = self._lengths + self.ratio * theta
        gamma = self._Z @ forces
        return ControlStep(forces, requested, saturated, self.alpha_hat.copy(), elongation, gamma,
                           np.zeros(p.n_joints))

    def describe(self) -> str:
        k_p, k_d, k_i = self.gains
        return (f"underactuated: inverse statics + motor-angle PID (K_p = {k_p:.0f} N/m, K_d = {k_d:.0f} N s/m, "
                f"K_i = {k_i:.0f} N/(m s)), friction f_s = [" + ", ".join(f"{v:.2f}" for v in self.f_s) + "] N, "
                f"{self.params.n_cables} cables")
