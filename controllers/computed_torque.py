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

Steps 1-4 run as one compiled call (numba, :mod:`neck_sim.jit`) built from the same formula
kernels the numpy API of :mod:`neck_sim.analytic` and :mod:`controllers.tension` calls; the state
of K controllers is stacked in a :class:`ControllerState` so that lockstep batches
(:func:`controllers.closed_loop.run_lockstep`) advance in one call.

The controller's *model* is separate from the plant's truth: ``params`` holds what the controller
knows of the neck (geometry -- set ``geometry.r = 0`` for a controller that ignores the pulleys --,
actuation, springs, inertia, gains); friction ``f_s`` and cable coefficients are constructor
arguments that default to the paper's Tables 1 and 2, not to a plant's hidden values.
"""

from __future__ import annotations

from enum import IntEnum
from typing import Iterable, NamedTuple

import numpy as np
import numpy.typing as npt

from controllers.estimators import CableModel, ElongationEstimator, estimated_tension
from controllers.tension import (TensionInfeasibleError, distribute_kernel, infeasible_message,
                                 tension_lower_bounds)
from neck_sim.analytic.cables import cable_kinematics, transmission_kernel, transmission_matrix
from neck_sim.analytic.dynamics import (arctan_friction, euler_elongation, linkage_constants, linkage_kernel,
                                       motor_friction, secant_stiffness)
from neck_sim.analytic.estimation import UnreachableError, pinv_increment_kernel
from neck_sim.analytic.geometry import check_cables
from neck_sim.jit import kernel
from neck_sim.params import NeckParams, default_params
from neck_sim.trajectory import TrajectorySample

__all__ = ["ControlLaw", "OutsideWorkspaceError", "MotorReference", "ControlStep", "ComputedTorqueController",
           "reference_table", "output_slices", "ControllerState", "advance", "step_error",
           "outside_workspace"]


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


def reference_table(ref: MotorReference) -> np.ndarray:
    """The reference as one C-contiguous (..., 6N + 3) row per sample for the compiled step:
    alpha, alpha_dot, alpha_ddot (N each), theta_dot, friction, lower (N+1 each)."""
    return np.ascontiguousarray(np.concatenate(
        [ref.alpha, ref.alpha_dot, ref.alpha_ddot, ref.theta_dot, ref.friction, ref.lower], axis=-1))


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

# -- the compiled step ------------------------------------------------------------------------
# State rows (ControllerState.values, (K, 7, N+1)): joint rows use the first N entries.
_ALPHA_HAT, _ALPHA_PREV, _INTEGRAL, _THETA_PREV, _X, _FORCE_PREV, _THETA_DOT_PREV = range(7)
# Constants (K, 9): gains of eq (59), period, reflected inertia, force cap, joint range, r_d/R,
# elastic estimator on/off.
_KP, _KV, _KI, _DT, _IA, _FMAX, _AMAX, _RATIO, _ELASTIC = range(9)
# Output row per sample, (..., 7N + 4): alpha_hat, elongation (N+1), gamma, w, forces (N+1),
# requested (N+1), saturated (N+1, 0/1).
# Status codes of the kernels (0: done).
_SINGULAR_ESTIMATE, _NOT_FINITE, _OUTSIDE, _TENSION = 1, 2, 100, 1000
# the compiled twins of the numpy formulas (numba resolves module globals, not attributes)
_friction, _tension_hat = arctan_friction.jit, estimated_tension.jit
_stiff, _euler = secant_stiffness.jit, euler_elongation.jit


def output_slices(n: int, m: int | None = None) -> dict[str, slice]:
    """Columns of one output row for N joints and m cables (default N + 1, the compiled layout)."""
    m = n + 1 if m is None else m
    sizes = (("alpha_hat", n), ("elongation", m), ("gamma", n), ("w", n), ("forces", m),
             ("requested", m), ("saturated", m))
    out, start = {}, 0
    for name, size in sizes:
        out[name] = slice(start, start + size)
        start += size
    return out


@kernel
def _estimate_and_pid(theta, k, st, flags, const, cab, Z, ref, out) -> int:
    """Eq (35) corrected (with the eq-58 elongation when elastic), the workspace check and eq (59)
    for one controller; Z (N, N+1) is Z(alpha_hat) of the previous step.  Returns a status."""
    n = Z.shape[0]
    for j in range(n + 1):
        if not np.isfinite(theta[j]):
            return _NOT_FINITE
    ah = st[_ALPHA_HAT]
    if flags[0] == 0:                       # first reading: it defines theta at the start pose
        flags[0] = 1
    else:
        rhs = np.empty(n + 1)
        for j in range(n + 1):
            rhs[j] = const[_RATIO] * (theta[j] - st[_THETA_PREV, j])
        if const[_ELASTIC] != 0.0 and flags[1] != 0:
            for j in range(n + 1):
                fr = _friction(st[_THETA_DOT_PREV, j], cab[4, 0], cab[3, j])
                t_hat = _tension_hat(st[_FORCE_PREV, j], fr)
                x_new = _euler(st[_X, j], t_hat, cab[4, 1], cab[2, j], _stiff(t_hat, cab[0, j], cab[1, j]))
                rhs[j] -= x_new - st[_X, j]
                st[_X, j] = x_new
        inc = np.empty(n)
        if not pinv_increment_kernel(Z, rhs, inc):
            return _SINGULAR_ESTIMATE
        for i in range(n):
            ah[i] += inc[i]
    for j in range(n + 1):
        st[_THETA_PREV, j] = theta[j]
    for i in range(n):
        if abs(ah[i]) > const[_AMAX]:
            return _OUTSIDE + i
    dt = const[_DT]
    o = out[k]
    r = ref[k]
    for i in range(n):                      # eq (59)
        e = r[i] - ah[i]
        e_dot = r[n + i] - (ah[i] - st[_ALPHA_PREV, i]) / dt
        st[_INTEGRAL, i] += e * dt
        o[3 * n + 1 + i] = r[2 * n + i] + const[_KV] * e_dot + const[_KP] * e + const[_KI] * st[_INTEGRAL, i]
        o[i] = ah[i]
    for j in range(n + 1):
        o[n + j] = st[_X, j]
    return 0


@kernel
def _torque_and_tensions(k, st, flags, const, lk, Z, ref, out) -> int:
    """M, g at alpha_hat (eq 24), Gamma_d of eq (66) and the tension distribution (eqs 63-65)."""
    n = Z.shape[0]
    o = out[k]
    r = ref[k]
    ah = st[_ALPHA_HAT, :n]
    M = np.empty((n, n))
    c = np.empty(n)
    g = np.empty(n)
    linkage_kernel(ah, np.zeros(n), lk, M, c, g)
    ia = const[_IA]
    w = o[3 * n + 1: 4 * n + 1]
    gamma = o[2 * n + 1: 3 * n + 1]
    for i in range(n):
        acc = g[i]
        for j in range(n):
            mij = M[i, j]
            for q in range(n + 1):
                mij += ia * Z[i, q] * Z[j, q]
            acc += mij * w[j]
        for q in range(n + 1):
            acc += Z[i, q] * r[3 * n + (n + 1) + q]          # Z f_friction(theta_d')
        gamma[i] = acc
    base = 4 * n + 1
    forces = o[base: base + n + 1]
    requested = o[base + n + 1: base + 2 * n + 2]
    sat = np.empty(n + 1, dtype=np.bool_)
    status, _ = distribute_kernel(Z, gamma, r[3 * n + 2 * (n + 1): 3 * n + 3 * (n + 1)], const[_FMAX],
                                  forces, requested, sat)
    if status != 0:
        return _TENSION + status
    for j in range(n + 1):
        o[base + 2 * n + 2 + j] = 1.0 if sat[j] else 0.0
        st[_FORCE_PREV, j] = forces[j]
        st[_THETA_DOT_PREV, j] = r[3 * n + j]
    for i in range(n):
        st[_ALPHA_PREV, i] = ah[i]
    flags[1] = 1
    return 0


@kernel
def control_rows(theta, k, st, flags, const, cab, lk, geometry, cases, Z, ref, out, status) -> None:
    """One control period of K controllers (leading axis of every argument but ``k``).

    Per controller: eq (35) with Z of the previous estimate, eq (59), Z at the new estimate
    (``transmission_kernel``, geometry (b, L, r), routing cases (m, N)), eqs (24), (66), (63)-(65).
    Rows with a non-zero status are skipped; a failing row sets its status.
    """
    for r in range(theta.shape[0]):
        if status[r] != 0:
            continue
        status[r] = _estimate_and_pid(theta[r], k, st[r], flags[r], const[r], cab[r], Z[r], ref[r], out[r])
        if status[r] != 0:
            continue
        transmission_kernel(st[r, _ALPHA_HAT, : Z.shape[1]], geometry[r], cases[r], Z[r])
        status[r] = _torque_and_tensions(k, st[r], flags[r], const[r], lk[r], Z[r], ref[r], out[r])


def step_error(status: int, alpha_hat: np.ndarray, alpha_max: float) -> ValueError:
    """The exception a kernel status stands for (alpha_hat (N,) rad the estimate then, alpha_max rad)."""
    if status == _NOT_FINITE:
        return ValueError("theta: contains NaN or infinity")
    if status == _SINGULAR_ESTIMATE:
        return UnreachableError("alpha_hat: Z Z^T is singular (pose outside the workspace)")
    if _OUTSIDE <= status < _TENSION:
        return outside_workspace(status - _OUTSIDE, alpha_hat, alpha_max)
    return TensionInfeasibleError(infeasible_message(status - _TENSION, ()))


def outside_workspace(j: int, alpha_hat: np.ndarray, alpha_max: float) -> OutsideWorkspaceError:
    """The error of an estimate alpha_hat (N,) rad whose joint j (0-based) is beyond alpha_max rad."""
    return OutsideWorkspaceError(f"alpha_hat: joint {j + 1} estimated at {np.degrees(alpha_hat[j]):.1f} deg, "
                                 f"outside the workspace |alpha| <= {np.degrees(alpha_max):.1f} deg")


class ControllerState:
    """Everything the compiled step of K controllers reads and writes, stacked on axis 0.

    values (K, 7, N+1), flags (K, 2) int (encoder read once, a force commanded once), const
    (K, 9), cables (K, 5, N+1) the eq-58 coefficients, linkage (K, 7 + N) the model's linkage
    constants, geometry (K, 3) b, L, r, cases (K, N+1, N) the routing, Z (K, N, N+1) Z at the
    current estimate, status (K,) int.
    """

    def __init__(self, controllers: Iterable[ComputedTorqueController]) -> None:
        ctrls = list(controllers)
        n = ctrls[0].params.n_joints
        if any(c.params.n_joints != n for c in ctrls):
            raise ValueError("controllers: every controller of a batch must have the same number of joints")
        self.n = n
        self.values = np.zeros((len(ctrls), 7, n + 1))
        self.flags = np.zeros((len(ctrls), 2), dtype=np.int64)
        self.const = np.stack([c._constants() for c in ctrls])
        self.cables = np.stack([c._cable_constants() for c in ctrls])
        self.linkage = np.stack([linkage_constants(c.params) for c in ctrls])
        self.geometry = np.array([[c.params.geometry.b, c.params.geometry.L, c.params.geometry.r] for c in ctrls])
        self.cases = np.stack([c.params.routing.segment_cases(n) for c in ctrls]).astype(np.int64)
        self.Z = np.zeros((len(ctrls), n, n + 1))
        self.status = np.zeros(len(ctrls), dtype=np.int64)

    @classmethod
    def stack(cls, states: Iterable[ControllerState]) -> "ControllerState":
        """One state of the controllers of several states, in order (arrays copied)."""
        states = list(states)
        if any(s.n != states[0].n for s in states):
            raise ValueError("controllers: every controller of a batch must have the same number of joints")
        out = cls.__new__(cls)
        out.n = states[0].n
        for name in ("values", "flags", "const", "cables", "linkage", "geometry", "cases", "Z", "status"):
            setattr(out, name, np.concatenate([getattr(s, name) for s in states]))
        return out



def advance(state: ControllerState, theta: np.ndarray, k: int, ref: np.ndarray, out: np.ndarray) -> None:
    """One control period of K controllers: theta (K, N+1), row k of ref (K, T, 6N+3) -> out (K, T, 7N+4).

    Controllers whose status is not 0 are left alone (their status says why they stopped).
    """
    control_rows(theta, k, state.values, state.flags, state.const, state.cables, state.linkage, state.geometry,
                 state.cases, state.Z, ref, out, state.status)


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
                 cable_model: CableModel | str | None = None, f_s: npt.ArrayLike | None = None,
                 k: npt.ArrayLike | None = None, lam: npt.ArrayLike | None = None, c_a: npt.ArrayLike | None = None,
                 omega: float | None = None, t_min: float | None = None, f_min: float | None = None,
                 f_max: float | None = None) -> None:
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
        self.elongation = ElongationEstimator.for_model(self.cable_model, p, k=k, lam=lam, c_a=c_a, f_s=f_s)
        self.state = ControllerState([self])
        self._columns = output_slices(n)
        self.reset()

    def _constants(self) -> np.ndarray:
        act = self.params.actuation
        k_p, k_v, k_i = self.gains
        return np.array([k_p, k_v, k_i, self.dt, act.reflected_inertia, self.f_max, self.params.geometry.alpha_max,
                         act.r_d / act.R, float(self.elongation is not None)])

    def _cable_constants(self) -> np.ndarray:
        n1 = self.params.n_cables
        return np.zeros((5, n1)) if self.elongation is None else self.elongation.constants()

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
    def reset(self, alpha0: npt.ArrayLike | None = None, theta0: npt.ArrayLike | None = None) -> None:
        """Start from pose ``alpha0`` (default straight), encoders reading ``theta0`` there
        (None: the first reading given to :meth:`step`), cables unstretched."""
        p = self.params
        n = p.n_joints
        st = self.state
        st.values[0] = 0.0
        st.flags[0] = 0
        st.status[0] = 0
        if alpha0 is not None:
            st.values[0, _ALPHA_HAT, :n] = check_cables(alpha0, n, "alpha0")
            st.values[0, _ALPHA_PREV, :n] = st.values[0, _ALPHA_HAT, :n]
        if theta0 is not None:
            st.values[0, _THETA_PREV] = check_cables(theta0, n + 1, "theta0")
            st.flags[0, 0] = 1
        st.Z[0] = transmission_matrix(st.values[0, _ALPHA_HAT, :n], p)

    @property
    def alpha_hat(self) -> np.ndarray:
        """The current estimate (N,) rad."""
        return self.state.values[0, _ALPHA_HAT, : self.params.n_joints].copy()

    def step_into(self, theta: npt.ArrayLike, k: int, ref_table: np.ndarray, out_table: np.ndarray) -> None:
        """One control period from encoder reading ``theta`` (N+1,) rad and row ``k`` of
        :func:`reference_table`, written into row ``k`` of ``out_table`` (T, 7N + 4) (see
        :func:`output_slices`).  Raises the controller's errors (ValueError subclasses)."""
        advance(self.state, np.asarray(theta, dtype=float)[None], k, ref_table[None], out_table[None])
        if self.state.status[0]:
            # the state holds the estimate that failed (a failing step writes no output row)
            raise step_error(int(self.state.status[0]), self.state.values[0, _ALPHA_HAT, : self.params.n_joints],
                             self.params.geometry.alpha_max)

    def step(self, theta: npt.ArrayLike, ref: MotorReference) -> ControlStep:
        """Forces for the next period from the encoder reading ``theta`` (N+1,) rad and one
        reference sample ``ref`` (:meth:`motor_reference` of a single time, or ``.at(k)``)."""
        n = self.params.n_joints
        theta = np.asarray(theta, dtype=float)
        if theta.shape != (n + 1,):
            raise ValueError(f"theta: expected shape ({n + 1},) (one angle per motor), got {theta.shape}")
        table = reference_table(MotorReference(*(np.asarray(x, dtype=float) for x in ref)))[None]
        out = np.zeros((1, 7 * n + 4))
        self.step_into(theta, 0, table, out)
        o = {name: out[0, sl] for name, sl in self._columns.items()}
        return ControlStep(o["forces"], o["requested"], o["saturated"] > 0.5, o["alpha_hat"], o["elongation"],
                           o["gamma"], o["w"])

    def describe(self) -> str:
        """One line naming the law and the model it uses."""
        fr = "friction f_s = [" + ", ".join(f"{v:.2f}" for v in self.f_s) + "] N" if self.law.uses_friction \
            else "no friction"
        return (f"law {int(self.law)}: {fr}, {self.cable_model.value} cables in the estimator, "
                f"r = {1e3 * self.params.geometry.r:.1f} mm, omega = {self.gains[1] / 3:g} rad/s, "
                f"t_min = {self.t_min:g} N, f_min = {self.f_min:g} N, f_max = {self.f_max:g} N")
