"""LQR on the linearised neck-cable-motor model, for long necks on elastic cables.

Law 2 (:mod:`controllers.computed_torque`) treats the cables as inextensible: its feedback acts on
eq (35)'s alpha_hat, which follows the motors.  On a long neck gravity leaves the neck held by its
motors through elastic cables with little stiffness, and the neck's weakest mode (about 0.5 Hz
at N = 10 with the default constants) rides on nearly still motors: eq (35) hardly sees it, and
the loop lets it grow (README, Known limitations).

This controller keeps law 2's feed-forward and replaces its feedback:

* **Neck observer.**  The motors are measured (encoders, 500 Hz); the neck is driven by them
  through the cables.  The observer integrates the analytic neck (eq 24's M_m without motors,
  c_m, g of eq 25, the tension of eq 54 with its damping) driven by the measured motor slides
  s = (r_d/R) theta, one implicit Euler step per period (the light bars on stiff cables have modes
  near 500 rad/s).  It needs no tension sensor and no friction model: friction acts on the
  motors, which are measured.  It reads the controller's model (``params``), never the plant.
* **LQR** (discrete, at the control rate) on the coupled model -- neck angles and speeds, motor
  slides and speeds, and the integral of the joint-angle error -- with every cable force as an
  input, so that the feedback damps the cable-motor-gravity mode with all N + 1 motors.

The gain is computed once, at the straight pose held by the least tensions of eqs (63)-(65); the
observer and the feed-forward are nonlinear.

Sign conventions are those of :mod:`neck_sim.analytic.cables`: x_c = (l_c - l_c0) + s, the cable
tension acts as tau = Z t on the joints and as -t on its motor.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt
from scipy.linalg import expm, solve_discrete_are

from controllers.computed_torque import (ComputedTorqueController, ControlLaw, ControlStep, MotorReference,
                                         outside_workspace)
from controllers.tension import distribute_tensions
from controllers.trajectories import reference_feedforward
from neck_sim.trajectory import TrajectorySample
from neck_sim.analytic import gravity_spring_torque, mass_matrix, transmission_matrix
from neck_sim.analytic.cables import cable_kinematics, cable_lengths
from neck_sim.analytic.dynamics import cable_tension, cap_elongation, linkage_dynamics
from neck_sim.analytic.statics import force_stiffness, tension_elongation, tension_slope
from neck_sim.analytic.geometry import check_cables
from neck_sim.params import NeckParams

__all__ = ["LinearNeck", "linearise", "LQRWeights", "lqr_gain", "closed_loop_rates",
           "ElasticReference", "ElasticLQRController"]


@dataclass(frozen=True, eq=False)
class LinearNeck:
    """The neck, its elastic cables and its motors linearised at one pose.

    Z (N, m) m at the pose; Mn (N, N) kg m^2 the linkage's inertia (no motors); Kf (N, N) N m/rad
    gravity, springs and cable curvature at the operating tensions (cables as force sources);
    Kc, C (m,) N/m and N s/m the cables' tangent stiffness and damping (eq 54); m_r kg the
    reflected motor inertia; friction (m,) N s/m the motors' linearised friction; tension (m,) N
    the operating tensions; elongation (m,) m the cables' elongation under them.
    """

    Z: np.ndarray
    Mn: np.ndarray
    Kf: np.ndarray
    Kc: np.ndarray
    C: np.ndarray
    m_r: float
    friction: np.ndarray
    tension: np.ndarray
    elongation: np.ndarray

    @property
    def n(self) -> int:
        return self.Z.shape[0]

    @property
    def m(self) -> int:
        return self.Z.shape[1]

    def neck_matrices(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Continuous neck dynamics driven by the motors: Mn a'' = -Ka a - Ca a' + Zk s + Zc s'.

        Returns (Ka, Ca, Zk, Zc); s is the motor slides' deviation from the operating point (m)."""
        Z = self.Z
        return (self.Kf + (Z * self.Kc) @ Z.T, (Z * self.C) @ Z.T, Z * self.Kc, Z * self.C)

    def state_space(self) -> tuple[np.ndarray, np.ndarray]:
        """A (2(N+m), 2(N+m)), B (2(N+m), m) of x = [alpha, s, alpha', s'], u = forces (N)."""
        n, m = self.n, self.m
        Ka, Ca, Zk, Zc = self.neck_matrices()
        Mi = np.linalg.inv(self.Mn)
        size = 2 * (n + m)
        A = np.zeros((size, size))
        B = np.zeros((size, m))
        a, s, ad, sd = slice(0, n), slice(n, n + m), slice(n + m, 2 * n + m), slice(2 * n + m, size)
        A[a, ad] = np.eye(n)
        A[s, sd] = np.eye(m)
        A[ad, a], A[ad, s], A[ad, ad], A[ad, sd] = -Mi @ Ka, Mi @ Zk, -Mi @ Ca, Mi @ Zc
        A[sd, a] = Zk.T / self.m_r
        A[sd, s] = -np.diag(self.Kc) / self.m_r
        A[sd, ad] = Zc.T / self.m_r
        A[sd, sd] = -np.diag(self.C + self.friction) / self.m_r
        B[sd] = np.eye(m) / self.m_r
        return A, B


def cable_damping(x, params: NeckParams) -> np.ndarray:
    """d t / d x_c' of eq (54) at elongation x (..., m) m: c_a / (1 - lambda x), N s/m, with x
    capped as in :func:`~neck_sim.analytic.dynamics.cable_tension`; 0 where slack."""
    cab = params.cables
    k, lam = np.asarray(cab.k), np.asarray(cab.lam)
    xe = np.clip(np.asarray(x, dtype=float), 0.0, cap_elongation(k, lam, cab.t_cap))
    return np.where(np.asarray(x) > 0, np.asarray(cab.c_a) / (1.0 - lam * xe), 0.0)


def linearise(params: NeckParams, alpha: npt.ArrayLike | None = None, *, t_min: float | None = None,
              friction_scale: float = 0.3) -> LinearNeck:
    """:class:`LinearNeck` at pose ``alpha`` (N,) rad (default straight), held at rest with the
    least tensions of eqs (63)-(65) above ``t_min`` (N, default ``actuation.t_min``).

    The friction of eq (37) is linearised at zero speed, (2/pi) f_s c_s R/r_d per cable, times
    ``friction_scale``: the arctan saturates within a few rad/s, so a moving motor feels much
    less than the slope at rest.
    """
    n, m = params.n_joints, params.n_cables
    a = np.zeros(n) if alpha is None else np.asarray(alpha, dtype=float)
    act, cab, fr = params.actuation, params.cables, params.friction
    Z = transmission_matrix(a, params)
    lower = np.full(m, act.t_min if t_min is None else float(t_min))
    tension = distribute_tensions(Z, gravity_spring_torque(a, params), lower, 1e12).requested
    x = tension_elongation(tension, params)
    slope = (2 / np.pi) * np.asarray(fr.f_s, dtype=float) * fr.c_s * act.R / act.r_d
    return LinearNeck(Z=Z, Mn=mass_matrix(a, params, motors=False), Kf=force_stiffness(a, tension, params),
                      Kc=tension_slope(x, params), C=cable_damping(x, params), m_r=act.reflected_inertia,
                      friction=friction_scale * slope, tension=tension, elongation=x)


@dataclass(frozen=True)
class LQRWeights:
    """Diagonal LQR weights per unit of state (SI units squared) against 1 per N^2 of force."""

    alpha: float = 1e7          # per rad^2 of joint angle
    slide: float = 0.0          # per m^2 of motor slide
    alpha_dot: float = 1e3      # per (rad/s)^2
    slide_dot: float = 0.0      # per (m/s)^2
    integral: float = 1e6       # per (rad s)^2 of the integrated angle error
    force: float = 1.0          # per N^2


def _discretise(A: np.ndarray, B: np.ndarray, dt: float):
    """Zero-order-hold discretisation of x' = A x + B u over dt s (matrix exponential)."""
    size, k = B.shape
    E = np.zeros((size + k, size + k))
    E[:size, :size], E[:size, size:] = A, B
    F = expm(E * dt)
    return F[:size, :size], F[:size, size:]


def _with_integral(lin: LinearNeck) -> tuple[np.ndarray, np.ndarray]:
    A, B = lin.state_space()
    n, size = lin.n, A.shape[0]
    Ai = np.zeros((size + n, size + n))
    Ai[:size, :size] = A
    Ai[size:, :n] = np.eye(n)
    return Ai, np.vstack([B, np.zeros((n, lin.m))])


def lqr_gain(lin: LinearNeck, dt: float, weights: LQRWeights = LQRWeights()) -> np.ndarray:
    """Discrete LQR gain K (m, 2(N+m) + N): u = -K [alpha, s, alpha', s', int alpha] (deviations)."""
    n, m = lin.n, lin.m
    Ad, Bd = _discretise(*_with_integral(lin), dt)
    w = weights
    q = np.concatenate([np.full(n, w.alpha), np.full(m, w.slide), np.full(n, w.alpha_dot), np.full(m, w.slide_dot),
                        np.full(n, w.integral)])
    R = w.force * np.eye(m)
    X = solve_discrete_are(Ad, Bd, np.diag(q) + 1e-9 * np.eye(q.size), R)
    return np.linalg.solve(R + Bd.T @ X @ Bd, Bd.T @ X @ Ad)


def closed_loop_rates(lin_plant: LinearNeck, K: np.ndarray, dt: float) -> np.ndarray:
    """Continuous-time eigenvalues (1/s) of ``lin_plant`` under u = -K x with full state, sorted
    by decreasing real part (the first is the least damped)."""
    Ad, Bd = _discretise(*_with_integral(lin_plant), dt)
    mu = np.linalg.eigvals(Ad - Bd @ K).astype(complex)
    rates = np.log(mu) / dt
    return rates[np.argsort(-rates.real)]


class ElasticReference(NamedTuple):
    """Law 2's :class:`~controllers.computed_torque.MotorReference` (its seven fields first) and the
    feed-forward every sample needs, computed once for the whole reference, batched (T, ...) or one
    sample: gamma (..., N) N m and forces (..., N+1) N of :func:`reference_feedforward`, slide
    (..., N+1) m the motor slides of the reference state (cables stretched by the feed-forward
    tension)."""

    alpha: np.ndarray
    alpha_dot: np.ndarray
    alpha_ddot: np.ndarray
    theta_dot: np.ndarray
    theta_ddot: np.ndarray
    friction: np.ndarray
    lower: np.ndarray
    gamma: np.ndarray
    forces: np.ndarray
    slide: np.ndarray

    def at(self, k: int) -> "ElasticReference":
        return ElasticReference(*(x[k] for x in self))


class ElasticLQRController:
    """Law 2's feed-forward plus LQR feedback on a neck observer (see the module docstring).

    The interface of :class:`~controllers.computed_torque.ComputedTorqueController` that
    :func:`controllers.closed_loop.run_lockstep` uses (its Python path: one ``step`` per period).

    Parameters
    ----------
    params: the controller's model of the neck (paper kind of routing, N + 1 cables).
    weights: :class:`LQRWeights`.
    friction_scale: share of the friction slope at rest the design counts on (:func:`linearise`).
    t_min, f_min, f_max: override ``actuation`` (N).
    """

    law = ControlLaw.FRICTION          # its feed-forward is law 2's (friction at the desired speeds)

    def __init__(self, params: NeckParams, *, weights: LQRWeights = LQRWeights(), friction_scale: float = 0.3,
                 t_min: float | None = None, f_min: float | None = None, f_max: float | None = None) -> None:
        if not (np.isfinite(friction_scale) and friction_scale >= 0):
            raise ValueError(f"friction_scale: must be finite and >= 0, got {friction_scale!r}")
        self.params = params
        # law 2 supplies the reference (desired motor speeds, friction, eq 65 bounds) and checks the limits
        self._law2 = ComputedTorqueController(params, ControlLaw.FRICTION, t_min=t_min, f_min=f_min, f_max=f_max)
        self.t_min, self.f_min, self.f_max = self._law2.t_min, self._law2.f_min, self._law2.f_max
        self.dt = self._law2.dt
        self.weights = weights
        self.lin = linearise(params, t_min=self.t_min, friction_scale=friction_scale)
        self.K = lqr_gain(self.lin, self.dt, weights)
        act = params.actuation
        self._ratio = act.r_d / act.R
        self.reset()

    def describe(self) -> str:
        """One line naming the controller and its settings."""
        w = self.weights
        return (f"elastic LQR: law 2 feed-forward, LQR on a neck observer (alpha {w.alpha:g}, alpha_dot "
                f"{w.alpha_dot:g}, integral {w.integral:g} per N^2), t_min = {self.t_min:g} N, "
                f"f_min = {self.f_min:g} N, f_max = {self.f_max:g} N")

    def motor_reference(self, sample: TrajectorySample) -> ElasticReference | MotorReference:
        """Desired motor motion, believed friction and eq (65) bounds (law 2's), batched, with the
        feed-forward of every sample (:class:`ElasticReference`).  Law 2's reference alone where
        some sample has no positive forces or leaves the workspace: :meth:`step` then stops there."""
        ref = self._law2.motor_reference(sample)
        try:
            gamma, f_ff = reference_feedforward(ref, self.params)
            return ElasticReference(*ref, gamma, f_ff, self._reference_slide(ref, f_ff))
        except ValueError:          # TensionInfeasibleError, a reference pose outside the workspace
            return ref

    def _reference_slide(self, ref: MotorReference, f_ff: np.ndarray) -> np.ndarray:
        """Motor slides (m) of the reference state: cables stretched by the feed-forward tension
        (force minus the believed friction and the reference's motor inertia)."""
        p = self.params
        tension = np.maximum(f_ff - ref.friction - self.lin.m_r * self._ratio * ref.theta_ddot, 0.0)
        # lengths pose by pose: numpy's batched evaluation can differ from one pose's in the last bit,
        # and the loop would carry that into every later sample
        alpha = np.asarray(ref.alpha)
        lengths = (cable_lengths(alpha, p) if alpha.ndim == 1 else
                   np.stack([cable_lengths(a, p) for a in alpha.reshape(-1, alpha.shape[-1])]).reshape(
                       alpha.shape[:-1] + (p.n_cables,)))
        return tension_elongation(tension, p) - lengths

    def reset(self, alpha0: npt.ArrayLike | None = None, theta0: npt.ArrayLike | None = None) -> None:
        """Start from pose ``alpha0`` (default straight) at rest, encoders reading ``theta0`` there
        (None: the first reading given to :meth:`step`)."""
        n, m = self.params.n_joints, self.params.n_cables
        self.alpha = np.zeros(n) if alpha0 is None else check_cables(alpha0, n, "alpha0").astype(float)
        self.alpha_dot = np.zeros(n)
        self.integral = np.zeros(n)
        self.slide = None if theta0 is None else self._ratio * check_cables(theta0, m, "theta0")
        self.slide_dot = np.zeros(m)
        self._kinematics: tuple[np.ndarray | None, Any] = (None, None)

    def _kinematics_at(self, alpha: np.ndarray):
        """Cable lengths (m), Z and dZ/dalpha (alpha_dot = 1) at the observer's pose ``alpha`` (the
        array itself: the observer replaces it, never writes into it).  A step reports the lengths
        and the next observer step reuses all three: one evaluation per period instead of three."""
        if self._kinematics[0] is not alpha:
            self._kinematics = (alpha, cable_kinematics(alpha, np.ones_like(alpha), self.params,
                                                        allow_outside_range=True))
        return self._kinematics[1]

    @property
    def alpha_hat(self) -> np.ndarray:
        """The neck observer's joint angles (N,) rad."""
        return self.alpha.copy()

    def _observe(self, s: np.ndarray, s_dot: np.ndarray) -> None:
        """One implicit Euler step of the neck, M_m a'' + c_m + g = Z t(x_c, x_c') (eqs 24, 30, 54),
        driven by the measured slides s (m) moving at s_dot (m/s); Jacobians of the right-hand
        side in closed form (:mod:`neck_sim.analytic.statics`)."""
        p, dt = self.params, self.dt
        a, ad = self.alpha, self.alpha_dot
        ck = self._kinematics_at(a)
        ld = linkage_dynamics(a, ad, p, allow_outside_range=True)
        Z = ck.Z
        x = ck.lengths + s
        t = cable_tension(x, s_dot - Z.T @ ad, p)
        Ka = force_stiffness(a, t, p, kinematics=ck) + (Z * tension_slope(x, p)) @ Z.T
        Ca = (Z * cable_damping(x, p)) @ Z.T
        rhs = Z @ t - ld.c - ld.g
        delta = np.linalg.solve(ld.M + dt * Ca + dt * dt * Ka, dt * (rhs - dt * Ka @ ad))
        self.alpha_dot = ad + delta
        self.alpha = a + dt * self.alpha_dot

    def step(self, theta: npt.ArrayLike, ref: ElasticReference | MotorReference) -> ControlStep:
        """Forces for the next period from the encoder reading ``theta`` (N+1,) rad and one
        reference sample (``motor_reference(...).at(k)``).  ``gamma`` is the feed-forward torque
        of eq (66) at the reference and ``w`` the reference acceleration (no eq 59 loop)."""
        p = self.params
        theta = check_cables(theta, p.n_cables, "theta")
        if not np.all(np.isfinite(theta)):
            raise ValueError("theta: contains NaN or infinity")
        s = self._ratio * theta
        if self.slide is not None:
            self.slide_dot = (s - self.slide) / self.dt
            self._observe(s, self.slide_dot)
        self.slide = s
        a_max = p.geometry.alpha_max
        if np.any(np.abs(self.alpha) > a_max):
            raise outside_workspace(int(np.argmax(np.abs(self.alpha))), self.alpha, a_max)
        if isinstance(ref, ElasticReference):
            gamma, f_ff, s_d = ref.gamma.copy(), ref.forces, ref.slide
        else:
            gamma, f_ff = reference_feedforward(ref, p)
            s_d = self._reference_slide(ref, f_ff)
        # the reference state: s_d, motors at the speeds of eq (21)
        error = self.alpha - ref.alpha
        self.integral += error * self.dt
        x = np.concatenate([error, s - s_d, self.alpha_dot - ref.alpha_dot,
                            self.slide_dot - self._ratio * ref.theta_dot, self.integral])
        requested = f_ff - self.K @ x
        forces = np.clip(requested, self.f_min, self.f_max)
        return ControlStep(forces, requested, requested > self.f_max, self.alpha.copy(),
                           self._kinematics_at(self.alpha).lengths + s, gamma,
                           np.asarray(ref.alpha_ddot, dtype=float).copy())
