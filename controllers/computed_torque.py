"""Computed-torque control of the N-X neck with estimated joint angles (paper §6).

Every control period (1 / ``control.rate_hz``):

1. alpha_hat from the encoders by eq (35) corrected, with the law's cable model
   (:mod:`controllers.estimators`);
2. PID outer loop, eq (59): w = alpha_d'' + k_v e' + k_p e + k_i int e, e = alpha_d - alpha_hat,
   k_p = 3 w^2, k_v = 3 w, k_i = w^3 (``control.omega`` = 11 rad/s); e' uses the backward
   difference of alpha_hat;
3. desired torque, eq (66): Gamma_d = M(alpha_hat) w + g(alpha_hat) + Z(alpha_hat) f_friction(theta_d'),
   with M of eq (24) (linkage + reflected motor inertia) and the friction of eq (37) at the
   *desired* motor speeds theta_d' = (R/r_d) Z(alpha_d)^T alpha_d' (eq 21);
4. tension distribution, eqs (63)-(65) (:mod:`controllers.tension`), with the lower bounds from the
   desired motor speeds and accelerations theta_d'' = (R/r_d)(Z^T alpha_d'' + Zdot^T alpha_d').

The three laws of §6.3: law 1 leaves friction out of (66) and (65) and assumes inextensible
cables; law 2 adds friction; law 3 adds the variable-stiffness cable model (model 2) to the
estimator only.

The controller's *model* is separate from the plant's truth: ``params`` holds what the controller
knows of the neck (geometry -- set ``geometry.r = 0`` for a controller that ignores the pulleys --,
actuation, springs, inertia, gains); friction ``f_s`` and cable coefficients are constructor
arguments that default to the paper's Tables 1 and 2, not to a plant's hidden values.
"""

from __future__ import annotations

from enum import IntEnum
from typing import NamedTuple

import numpy as np

from controllers.estimators import CableModel, ElongationEstimator, JointAngleEstimator
from controllers.tension import distribute_tensions, tension_lower_bounds
from controllers.trajectories import TrajectorySample
from neck_sim.analytic.cables import cable_kinematics, transmission_matrix
from neck_sim.analytic.dynamics import linkage_dynamics, motor_friction
from neck_sim.params import NeckParams, default_params

__all__ = ["ControlLaw", "OutsideWorkspaceError", "MotorReference", "ControlStep", "ComputedTorqueController"]


class OutsideWorkspaceError(ValueError):
    """The estimated pose left |alpha| <= alpha_max: the controller cannot go on."""


class ControlLaw(IntEnum):
    """The three control tests of §6.3."""

    NO_FRICTION = 1          # test 1: friction and cable elasticity neglected
    FRICTION = 2             # test 2: friction, inextensible cables
    FRICTION_ELASTIC = 3     # test 3: friction and elastic cables (estimator only)

    @property
    def uses_friction(self) -> bool:
        return self is not ControlLaw.NO_FRICTION

    @property
    def default_cable_model(self) -> CableModel:
        return CableModel.VARIABLE if self is ControlLaw.FRICTION_ELASTIC else CableModel.INEXTENSIBLE


class MotorReference(NamedTuple):
    """The reference and what it asks of the motors, batched over time (T, ...) or one sample.

    alpha, alpha_dot, alpha_ddot (..., N); theta_dot, theta_ddot (..., N+1) desired motor speeds
    (rad/s) and accelerations (rad/s^2); friction (..., N+1) N the believed friction at theta_dot
    (zeros for law 1); lower (..., N+1) N the bounds of eq (65).
    """

    alpha: np.ndarray
    alpha_dot: np.ndarray
    alpha_ddot: np.ndarray
    theta_dot: np.ndarray
    theta_ddot: np.ndarray
    friction: np.ndarray
    lower: np.ndarray

    def at(self, k: int) -> "MotorReference":
        return MotorReference(*(x[k] for x in self))


class ControlStep(NamedTuple):
    """One control period's output.

    forces (N+1,) N commanded (clipped to f_max); requested (N+1,) before clipping; saturated
    (N+1,) bool; alpha_hat (N,) rad; elongation (N+1,) m the estimator's x_c; gamma (N,) N m the
    desired torque of eq (66); w (N,) rad/s^2 the outer-loop acceleration of eq (59).
    """

    forces: np.ndarray
    requested: np.ndarray
    saturated: np.ndarray
    alpha_hat: np.ndarray
    elongation: np.ndarray
    gamma: np.ndarray
    w: np.ndarray


class ComputedTorqueController:
    """PID + computed torque + tension distribution (eqs 59, 63-66) on estimated joint angles.

    Parameters
    ----------
    params: the controller's model of the neck (default ``default_params(3)``).
    law: 1, 2 or 3 (:class:`ControlLaw`).
    cable_model: override the law's estimator cable model ("inextensible", "constant", "variable").
    f_s: friction (N+1,) N believed by laws 2 and 3 (default: paper Table 1).
    k, lam, c_a: cable model coefficients for the estimator (defaults: paper Tables 1/2 and
        ``control.c_a_estimator``); see :class:`controllers.estimators.ElongationEstimator`.
    omega, t_min, f_min, f_max: override ``control.omega`` (rad/s) and ``actuation`` limits (N).
    """

    def __init__(self, params: NeckParams | None = None, law: int | ControlLaw = ControlLaw.FRICTION, *,
                 cable_model: CableModel | str | None = None, f_s=None, k=None, lam=None, c_a=None,
                 omega: float | None = None, t_min: float | None = None, f_min: float | None = None,
                 f_max: float | None = None):
        self.params = default_params(3) if params is None else params
        try:
            self.law = ControlLaw(int(law))
        except ValueError:
            raise ValueError(f"law: expected 1, 2 or 3 (the tests of §6.3), got {law!r}") from None
        p = self.params
        n = p.n_joints
        if not p.routing.is_paper_kind(n):
            raise ValueError(
                f"ComputedTorqueController: the paper's control laws (tension distribution of eqs 63-65) need the "
                f"paper's kind of routing -- N right cables, cable j strut-routed below joint j and attached at D_j, "
                f"plus one long left cable ({n + 1} cables for N = {n}); this neck's routing differs "
                f"({p.n_cables} cables:\n{p.routing.describe()})")
        self.cable_model = self.law.default_cable_model if cable_model is None else CableModel(cable_model)
        paper = default_params(n)
        self.f_s = np.asarray(paper.friction.f_s if f_s is None else f_s, dtype=float)
        if self.f_s.shape != (n + 1,) or not np.all(np.isfinite(self.f_s)):
            raise ValueError(f"f_s: expected {n + 1} finite values (one per cable), got {self.f_s!r}")
        w = p.control.omega if omega is None else float(omega)
        if not (np.isfinite(w) and w > 0):
            raise ValueError(f"omega: must be positive, got {w}")
        self.gains = (3 * w * w, 3 * w, w ** 3)           # k_p, k_v, k_i of eq (59)
        act = p.actuation
        self.t_min = act.t_min if t_min is None else float(t_min)
        self.f_min = act.f_min if f_min is None else float(f_min)
        self.f_max = act.f_max if f_max is None else float(f_max)
        if not (0 <= self.f_min <= self.f_max and self.t_min >= 0):
            raise ValueError(f"force limits: need 0 <= f_min <= f_max and t_min >= 0, got "
                             f"f_min = {self.f_min}, f_max = {self.f_max}, t_min = {self.t_min}")
        self.dt = 1.0 / p.control.rate_hz
        elong = ElongationEstimator.for_model(self.cable_model, p, k=k, lam=lam, c_a=c_a, f_s=f_s)
        self.estimator = JointAngleEstimator(p, elong)
        self.reset()

    # -- reference ---------------------------------------------------------------------------
    def motor_reference(self, sample: TrajectorySample) -> MotorReference:
        """Desired motor motion, believed friction and eq (65) bounds for a reference, batched."""
        p = self.params
        act = p.actuation
        a, ad, add = (np.asarray(x, dtype=float) for x in sample)
        ck = cable_kinematics(a, ad, p)
        ratio = act.R / act.r_d
        theta_dot = ratio * np.einsum("...ij,...i->...j", ck.Z, ad)
        theta_ddot = ratio * (np.einsum("...ij,...i->...j", ck.Z, add) + np.einsum("...ij,...i->...j", ck.Zdot, ad))
        f_s = self.f_s if self.law.uses_friction else None
        friction = motor_friction(theta_dot, p, f_s) if f_s is not None else np.zeros_like(theta_dot)
        lower = tension_lower_bounds(theta_dot, theta_ddot, p, f_s=f_s, t_min=self.t_min, f_min=self.f_min)
        return MotorReference(a, ad, add, theta_dot, theta_ddot, friction, lower)

    # -- loop --------------------------------------------------------------------------------
    def reset(self, alpha0=None, theta0=None) -> None:
        """Start from pose ``alpha0`` (default straight), encoders reading ``theta0`` there."""
        self.estimator.reset(alpha0, theta0)
        self._integral = np.zeros(self.params.n_joints)
        self._alpha_prev = self.estimator.alpha_hat.copy()
        self._force_prev = None
        self._theta_dot_prev = None

    def step(self, theta, ref: MotorReference) -> ControlStep:
        """Forces for the next period from the encoder reading ``theta`` (N+1,) rad and one
        reference sample ``ref`` (:meth:`motor_reference` of a single time, or ``.at(k)``)."""
        p = self.params
        alpha_hat = self.estimator.update(theta, self._force_prev, self._theta_dot_prev).copy()
        amax = p.geometry.alpha_max
        if np.any(np.abs(alpha_hat) > amax):
            j = int(np.argmax(np.abs(alpha_hat)))
            raise OutsideWorkspaceError(
                f"alpha_hat: joint {j + 1} estimated at {np.degrees(alpha_hat[j]):.1f} deg, outside the "
                f"workspace |alpha| <= {np.degrees(amax):.1f} deg")
        e = ref.alpha - alpha_hat
        e_dot = ref.alpha_dot - (alpha_hat - self._alpha_prev) / self.dt
        self._integral = self._integral + e * self.dt
        k_p, k_v, k_i = self.gains
        w = ref.alpha_ddot + k_v * e_dot + k_p * e + k_i * self._integral          # eq (59)

        lk = linkage_dynamics(alpha_hat, np.zeros_like(alpha_hat), p)
        Z = transmission_matrix(alpha_hat, p)
        M = lk.M + p.actuation.reflected_inertia * Z @ Z.T                          # eq (24)
        gamma = M @ w + lk.g + Z @ ref.friction                                     # eq (66)
        dist = distribute_tensions(Z, gamma, ref.lower, self.f_max)                 # eqs (63)-(65)

        self._alpha_prev = alpha_hat
        self._force_prev = dist.forces
        self._theta_dot_prev = ref.theta_dot
        return ControlStep(dist.forces, dist.requested, dist.saturated, alpha_hat,
                           self.estimator.x.copy(), gamma, w)

    def describe(self) -> str:
        """One line naming the law and the model it uses."""
        fr = "friction f_s = [" + ", ".join(f"{v:.2f}" for v in self.f_s) + "] N" if self.law.uses_friction \
            else "no friction"
        return (f"law {int(self.law)}: {fr}, {self.cable_model.value} cables in the estimator, "
                f"r = {1e3 * self.params.geometry.r:.1f} mm, omega = {self.gains[1] / 3:g} rad/s, "
                f"t_min = {self.t_min:g} N, f_min = {self.f_min:g} N, f_max = {self.f_max:g} N")
