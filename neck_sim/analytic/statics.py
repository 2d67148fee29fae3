"""Statics of an N-X neck driven by any number m of cables.

A neck with fewer cables than N + 1 cannot hold an arbitrary pose: its equilibria form an
m-dimensional set in alpha-space.  This module finds them and says whether they are stable.

Potential.  With cable tensions t (..., m) the joints feel tau = Z t (eq 30) and the linkage
g(alpha) (eq 25, gravity + side springs + payload); a static pose solves

    r(alpha) = g(alpha) - Z(alpha) t = 0.

* Given cable **forces** f (motors as ideal force sources, t = f): the potential is
  U = V(alpha) + f . l_c(alpha) (Z = -dl_c/dalpha, eq 22), its Hessian
  ``K_f = H_V - diag_i(sum_j dZ_ij/dalpha_i f_j)``.
* Given **motor angles** theta (motors held, elastic cables of eq 54 at rest, x_c_dot = 0):
  x_c = l_c - l_c0 + (r_d/R) theta, t = t(x_c), U = V + sum_j E_j(x_cj) with E_j' = t_j, and
  ``K_theta = K_f(t) + Z diag(dt/dx) Z^T``.

An equilibrium is *stable* when its stiffness matrix K (the Hessian of U) is positive definite.

How K is computed (closed form, no numerical differentiation):

* H_V: side springs from eqs (1), (2) and their derivatives; gravity (and a payload at the head
  bar's centre) from the chain written as V_g = gravity * sum_i e_y . R(phi_i) u_i(alpha_i), with
  phi_i = sum_{k<i} alpha_k and u_i the mass moment of joint i's bars plus everything above it;
  its second derivatives are those of rotations (``potential_hessian``).
* The cable terms use that cable j's length is a sum of per-joint segments, so d^2 l_j / dalpha^2
  is diagonal, = -Zdot(alpha, alpha_dot = 1) (``transmission_matrix_dot``).

Both are held against finite differences of the potential in ``tests/test_statics.py``.

Shapes: alpha (..., N) rad, forces / tensions / theta (..., m); K (..., N, N) N m/rad.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from neck_sim.analytic.cables import CableKinematics, _evaluate, _lengths, _z, cable_kinematics, cable_lengths
from neck_sim.analytic.dynamics import cable_tension, cap_elongation, gravity_spring_torque, static_elongation
from neck_sim.analytic.geometry import _joint_local, check_alpha, check_cables, check_pose
from neck_sim.params import NeckParams

__all__ = ["Equilibrium", "potential_hessian", "head_jacobian", "tension_slope", "tension_elongation",
           "force_stiffness", "motor_stiffness", "equilibrium_for_forces", "equilibrium_for_motor_angles",
           "HeldPose", "held_pose",
           "motor_angles_for", "with_payload", "HoldingSolution", "inverse_statics", "least_tensions", "friction_band"]


class Equilibrium(NamedTuple):
    """Static poses found for a batch of forces or motor angles.

    alpha (..., N) rad (the last iterate where not converged); tension (..., m) N at the pose; residual (..., N) N m (g - Z t);
    stiffness (..., N, N) N m/rad, its eigenvalues (..., N) ascending; converged (...) bool
    (|residual| below tolerance, inside the joint range); stable (...) bool: converged and K
    positive definite.
    """

    alpha: np.ndarray
    tension: np.ndarray
    residual: np.ndarray
    stiffness: np.ndarray
    eigenvalues: np.ndarray
    converged: np.ndarray
    stable: np.ndarray


def with_payload(params: NeckParams, payload_mass: float | None) -> NeckParams:
    """``params`` with a point mass (kg) at the head bar's centre (None keeps the file's value)."""
    if payload_mass is None:
        return params
    if not np.isfinite(payload_mass) or payload_mass < 0:
        raise ValueError(f"payload_mass: must be finite and >= 0 kg, got {payload_mass!r}")
    return params.replace(**{"inertia.payload_mass": float(payload_mass)})


def _rot_apply(c, s, v):
    """R(phi) v for cos/sin (..., N) and vectors (..., N, 2)."""
    return c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]


def _chain(alpha: np.ndarray, params: NeckParams, jl=None):
    """Joint-local corners with derivatives (``jl`` when the caller has them), and cos/sin of the
    base-bar angles phi_i."""
    g = params.geometry
    if jl is None:
        jl = _joint_local(alpha, g.b, g.L)
    phi = np.cumsum(alpha, -1) - alpha
    return jl, np.cos(phi), np.sin(phi)


def potential_hessian(alpha: npt.ArrayLike, params: NeckParams) -> np.ndarray:
    """Hessian of the gravity + side-spring (+ payload) potential V, closed form, (..., N, N) N m/rad.

    Its gradient is g(alpha) of eq (25) (:func:`~neck_sim.analytic.gravity_spring_torque`).
    """
    return _potential_hessian(check_alpha(alpha, params.n_joints), params)


def _potential_hessian(a: np.ndarray, params: NeckParams, jl=None) -> np.ndarray:
    """:func:`potential_hessian` of checked angles; ``jl``: their joint-local corners, if known."""
    n = params.n_joints
    g, inert = params.geometry, params.inertia
    jl, c, s = _chain(a, params, jl)
    A = np.array([-g.b / 2, 0.0])
    B = np.array([g.b / 2, 0.0])
    md, mb = inert.diagonal_mass, inert.bar_mass
    per_joint = 2 * md + mb
    above = per_joint * (n - 1 - np.arange(n)) + inert.payload_mass        # mass carried by joint i's top bar
    top = (mb + above)[:, None]
    u = md * (A + B + jl.C + jl.D) / 2 + top * (jl.C + jl.D) / 2           # mass moment of joint i
    du = md * (jl.dC + jl.dD) / 2 + top * (jl.dC + jl.dD) / 2
    ddu = md * (jl.ddC + jl.ddD) / 2 + top * (jl.ddC + jl.ddD) / 2
    a_i = -_rot_apply(c, s, u)[1]               # d2/dphi2 of e_y.R u
    b_i = _rot_apply(c, s, du)[0]               # d2/dphi dalpha_i of e_y.R u
    c_i = _rot_apply(c, s, ddu)[1]              # d2/dalpha_i^2
    tail = np.cumsum(a_i[..., ::-1], -1)[..., ::-1] - a_i                  # sum_{i > j} a_i
    idx = np.arange(n)
    j = np.maximum(idx[:, None], idx[None, :])
    H = tail[..., j] + b_i[..., j]
    H[..., idx, idx] = tail + c_i
    H *= inert.gravity
    sd = jl.sides                               # side_lengths(a, params), computed with the corners
    k = np.asarray(params.springs.stiffness)
    l0 = params.springs.rest_length
    H[..., idx, idx] += k * ((sd.l_l - l0) * sd.ddl_l + sd.dl_l ** 2 + (sd.l_r - l0) * sd.ddl_r + sd.dl_r ** 2)
    return H


def head_jacobian(alpha: npt.ArrayLike, params: NeckParams) -> np.ndarray:
    """d(head x, head y, head angle)/dalpha of the head bar's centre, closed form, (..., 3, N)."""
    a = check_alpha(alpha, params.n_joints)
    jl, c, s = _chain(a, params)
    mx, my = _rot_apply(c, s, (jl.C + jl.D) / 2)
    dmx, dmy = _rot_apply(c, s, (jl.dC + jl.dD) / 2)
    # S R m summed over the joints above k, plus R m' of joint k itself
    tail_x = np.cumsum(-my[..., ::-1], -1)[..., ::-1] + my
    tail_y = np.cumsum(mx[..., ::-1], -1)[..., ::-1] - mx
    return np.stack([tail_x + dmx, tail_y + dmy, np.ones_like(a)], -2)


def tension_slope(x: npt.ArrayLike, params: NeckParams) -> np.ndarray:
    """dt/dx of the static cable law (eq 54 at x_dot = 0), (..., m) N/m; 0 where slack."""
    cab = params.cables
    k, lam = np.asarray(cab.k), np.asarray(cab.lam)
    x = np.asarray(x, dtype=float)
    x_star = cap_elongation(k, lam, cab.t_cap)
    return np.where(x > 0, k / (1.0 - lam * np.minimum(x, x_star)) ** 2, 0.0)


def tension_elongation(tension: npt.ArrayLike, params: NeckParams) -> np.ndarray:
    """Elongation x_c (m) at which a resting cable carries ``tension`` (N): eq (54) inverted."""
    cab = params.cables
    k, lam = np.asarray(cab.k), np.asarray(cab.lam)
    t = check_cables(tension, params.n_cables, "tension")
    if np.any(t < 0):
        raise ValueError(f"tension: cables only pull, got {t.min():.3g} N")
    x_star = cap_elongation(k, lam, cab.t_cap)
    beyond = (t - cab.t_cap) * (1.0 - lam * x_star) ** 2 / k
    return np.where(t <= cab.t_cap, static_elongation(t, k, lam), x_star + beyond)


def motor_angles_for(alpha: npt.ArrayLike, tension: npt.ArrayLike, params: NeckParams) -> np.ndarray:
    """Motor angles theta (..., m) rad that hold pose ``alpha`` with resting cables at ``tension``
    (inverse statics for motor-angle control): theta = (R/r_d)(x_c(t) - (l_c - l_c0))."""
    act = params.actuation
    return (act.R / act.r_d) * (tension_elongation(tension, params) - cable_lengths(alpha, params))


def _cable_curvature_term(Zp: np.ndarray, t: np.ndarray) -> np.ndarray:
    """-diag_i(sum_j dZ_ij/dalpha_i t_j): the cables' geometric stiffness, (..., N, N)."""
    d = -np.einsum("...ij,...j->...i", Zp, t)
    return d[..., :, None] * np.eye(d.shape[-1])


def force_stiffness(alpha: npt.ArrayLike, forces: npt.ArrayLike, params: NeckParams, *,
                    kinematics: CableKinematics | None = None) -> np.ndarray:
    """K_f: Hessian of V + f . l_c (cables as ideal force sources), (..., N, N) N m/rad.

    ``kinematics``: :func:`cable_kinematics` at ``alpha`` with alpha_dot = 1 (rad/s), when the
    caller has it already (its Zdot is then dZ/dalpha); computed here otherwise."""
    a = check_alpha(alpha, params.n_joints)
    f = check_cables(forces, params.n_cables, "forces")
    ck = cable_kinematics(a, np.ones_like(a), params) if kinematics is None else kinematics
    return potential_hessian(a, params) + _cable_curvature_term(ck.Zdot, f)


def motor_stiffness(alpha: npt.ArrayLike, theta: npt.ArrayLike, params: NeckParams) -> np.ndarray:
    """K_theta: Hessian of V + sum_j E_j(x_cj) with motors held at ``theta``, (..., N, N) N m/rad."""
    return _motor_terms(check_alpha(alpha, params.n_joints), _check_theta(theta, params), params)[1]


def _check_theta(theta, params: NeckParams) -> np.ndarray:
    return check_cables(theta, params.n_cables, "theta")


def _kinematics_and_hessian(a: np.ndarray, params: NeckParams) -> tuple[CableKinematics, np.ndarray]:
    """``cable_kinematics(a, 1, params)`` and ``potential_hessian(a, params)`` from one pass over the
    joints' corners (both need them; the Newton solvers evaluate this at every trial pose)."""
    g = params.geometry
    a = check_pose(a, params)
    jl = _joint_local(a, g.b, g.L)
    seg = _evaluate(a, params, (0, 1, 2), jl)
    ck = CableKinematics(_lengths(a, params, seg[0]), _z(seg[1], params), _z(seg[2], params))
    return ck, _potential_hessian(a, params, jl)


def _force_terms(a, f, params):
    ck, H = _kinematics_and_hessian(a, params)
    r = gravity_spring_torque(a, params) - np.einsum("...ij,...j->...i", ck.Z, f)
    K = H + _cable_curvature_term(ck.Zdot, f)
    return r, K, np.broadcast_to(f, r.shape[:-1] + f.shape[-1:])


def _motor_terms(a, theta, params):
    """r, K_theta, t and, for :func:`held_pose`, the cable lengths and Z at ``a`` (computed anyway)."""
    act = params.actuation
    ck, H = _kinematics_and_hessian(a, params)
    x = ck.lengths + (act.r_d / act.R) * theta
    t = cable_tension(x, np.zeros_like(x), params)
    r = gravity_spring_torque(a, params) - np.einsum("...ij,...j->...i", ck.Z, t)
    K = (H + _cable_curvature_term(ck.Zdot, t)
         + np.einsum("...ij,...j,...kj->...ik", ck.Z, tension_slope(x, params), ck.Z))
    return r, K, t, ck.lengths, ck.Z


def _newton(terms, a0: np.ndarray, params: NeckParams, tol: float, max_iter: int,
            max_step: float) -> tuple[Equilibrium, list[np.ndarray]]:
    """Batched Levenberg-Marquardt on r(alpha) = 0 with the exact Jacobian K (the stiffness).

    A step -(K^T K + mu I)^-1 K^T r, at most ``max_step`` rad per joint, is kept when it lowers
    |r| and stays inside the joint range (then mu shrinks, towards Newton's step), else mu grows:
    near-singular K (soft modes of an underactuated neck) makes plain Newton cycle.  Vectorised
    over the batch; converged samples leave the iteration.  ``terms(alpha, rows)`` gives r, K, t
    and any further per-sample arrays; every one is kept at each sample's last accepted pose, so
    the answer needs no evaluation of its own.  Returns the equilibria and those further arrays.
    """
    n = params.n_joints
    amax = params.geometry.alpha_max
    alpha = np.array(a0, dtype=float).reshape(-1, n)
    eye = np.eye(n)
    everything = np.arange(alpha.shape[0])
    at_alpha = [np.array(x) for x in terms(alpha, everything)]     # copies: a term may be a broadcast view
    active = everything
    mu = np.full(active.size, 1e-9)
    for _ in range(max_iter):
        r_all = at_alpha[0][active]
        keep = (np.max(np.abs(r_all), -1) >= tol) & np.all(np.isfinite(r_all), -1) & (mu < 1e6)
        active, mu = active[keep], mu[keep]
        if active.size == 0:
            break
        r, K = at_alpha[0][active], at_alpha[1][active]
        Kt = np.swapaxes(K, -1, -2)
        KtK = Kt @ K
        scale = np.einsum("...ii->...", KtK)[:, None, None] / n
        step = np.linalg.solve(KtK + (mu[:, None, None] * scale) * eye, (Kt @ r[..., None]))[..., 0]
        big = np.max(np.abs(step), -1, keepdims=True)
        step *= np.minimum(1.0, max_step / np.maximum(big, 1e-300))
        new = alpha[active] - step
        inside = np.all(np.abs(new) < amax, -1)
        trial = terms(np.where(inside[:, None], new, alpha[active]), active)
        better = inside & (np.sum(trial[0] ** 2, -1) < np.sum(r ** 2, -1))
        alpha[active[better]] = new[better]
        for kept, value in zip(at_alpha, trial):
            kept[active[better]] = value[better]
        mu = np.where(better, np.maximum(mu / 10, 1e-12), mu * 10)
    r, K, t = at_alpha[:3]
    eig = np.linalg.eigvalsh(K)
    converged = np.max(np.abs(r), -1) < tol * 10
    return Equilibrium(alpha, t, r, K, eig, converged, converged & (eig[:, 0] > 0)), at_alpha[3:]


def _start(alpha0, shape, params):
    n = params.n_joints
    if alpha0 is None:
        return np.zeros(shape + (n,))
    a0 = check_alpha(alpha0, n, "alpha0")
    return np.broadcast_to(a0, shape + (n,)).copy()


def equilibrium_for_forces(forces: npt.ArrayLike, params: NeckParams, alpha0: npt.ArrayLike | None = None, *,
                           payload_mass: float | None = None,
                           tol: float = 1e-9, max_iter: int = 60, max_step: float = 0.1) -> Equilibrium:
    """Static poses for constant cable forces ``forces`` (..., m) N (t = f), from ``alpha0``.

    Stability is that of force control (``K_f``).  ``payload_mass`` (kg) adds a point mass at the
    head; ``tol`` is the torque residual (N m) accepted.
    """
    p = with_payload(params, payload_mass)
    f = check_cables(forces, p.n_cables, "forces")
    if np.any(f < 0):
        raise ValueError(f"forces: cables only pull, got {f.min():.3g} N")
    flat = f.reshape(-1, p.n_cables)
    a0 = _start(alpha0, f.shape[:-1], p).reshape(-1, p.n_joints)
    eq = _newton(lambda a, idx: _force_terms(a, flat[idx], p), a0, p, tol, max_iter, max_step)[0]
    return Equilibrium(*(x.reshape(f.shape[:-1] + x.shape[1:]) for x in eq))


def equilibrium_for_motor_angles(theta: npt.ArrayLike, params: NeckParams, alpha0: npt.ArrayLike | None = None, *,
                                 payload_mass: float | None = None,
                                 tol: float = 1e-9, max_iter: int = 60, max_step: float = 0.1) -> Equilibrium:
    """Static poses with motors held at ``theta`` (..., m) rad and elastic cables (eq 54, at rest).

    theta = 0 is the straight pose with unstretched cables (convention of
    :mod:`neck_sim.analytic.cables`).  Stability is that of held motors (``K_theta``).
    """
    return held_pose(theta, params, alpha0, payload_mass=payload_mass, tol=tol, max_iter=max_iter,
                     max_step=max_step).equilibrium


class HeldPose(NamedTuple):
    """:func:`equilibrium_for_motor_angles` with the cables' geometry at the poses it found:
    lengths l_c - l_c0 (..., m) m and Z (..., N, m) m (eqs 3-19, 22), those of
    :func:`~neck_sim.analytic.cables.cable_kinematics` at ``equilibrium.alpha``."""

    equilibrium: Equilibrium
    lengths: np.ndarray
    Z: np.ndarray


def held_pose(theta: npt.ArrayLike, params: NeckParams, alpha0: npt.ArrayLike | None = None, *,
              payload_mass: float | None = None,
              tol: float = 1e-9, max_iter: int = 60, max_step: float = 0.1) -> HeldPose:
    """:func:`equilibrium_for_motor_angles` (same arguments) and the cable lengths and Z at its
    poses, which the solver computed there: a pose estimator reads them without evaluating the
    cables again."""
    p = with_payload(params, payload_mass)
    th = _check_theta(theta, p)
    flat = th.reshape(-1, p.n_cables)
    a0 = _start(alpha0, th.shape[:-1], p).reshape(-1, p.n_joints)
    eq, (lengths, Z) = _newton(lambda a, idx: _motor_terms(a, flat[idx], p), a0, p, tol, max_iter, max_step)
    batch = th.shape[:-1]
    return HeldPose(Equilibrium(*(x.reshape(batch + x.shape[1:]) for x in eq)),
                    lengths.reshape(batch + lengths.shape[1:]), Z.reshape(batch + Z.shape[1:]))


class HoldingSolution(NamedTuple):
    """Inverse statics: forces (m,) N in the box that hold ``equilibrium`` (a single pose), and
    the task error left (rad per joint for a joint target, m / rad for a head target)."""

    forces: np.ndarray
    equilibrium: Equilibrium
    task_error: np.ndarray


def _task(alpha, params, alpha_target, head_target):
    """Task value and its alpha-Jacobian: joint angles, or head (x, y[, angle])."""
    if alpha_target is not None:
        return alpha - alpha_target, np.eye(params.n_joints)
    from neck_sim.analytic.geometry import forward_kinematics
    kin = forward_kinematics(alpha, params)
    head = np.r_[kin.head_position, kin.head_angle][: head_target.size]
    return head - head_target, head_jacobian(alpha, params)[: head_target.size]


def inverse_statics(params: NeckParams, *, alpha_target: npt.ArrayLike | None = None,
                    head_target: npt.ArrayLike | None = None, alpha0: npt.ArrayLike | None = None,
                    f_min: float | None = None, f_max: float | None = None, regularisation: float = 1e-3,
                    payload_mass: float | None = None) -> HoldingSolution:
    """Forces in [f_min, f_max] whose equilibrium comes closest to a target (inverse statics).

    The target is a pose ``alpha_target`` (N,) rad or a head pose ``head_target`` (x, y) m or
    (x, y, angle) m, m, rad.  With fewer cables than N + 1 a pose is in general not reachable: the
    answer is the nearest pose of the reachable set, found over poses and tensions together
    (scipy's SLSQP: minimise |task(alpha) - target|^2 subject to g(alpha) = Z(alpha) t and the
    force box, with the exact constraint Jacobian [K_f, -Z]); searching over tensions alone would
    have to follow the equilibrium map, which is many-valued where force control is unstable.
    ``regularisation`` (relative to f_max) prefers small tensions among equally good ones (the
    co-contraction of N + 1 cables) and, for a head target, poses near ``alpha0``.  Defaults:
    the actuation limits f_min, f_max; ``alpha0`` the target pose or the straight one.
    """
    from scipy.optimize import lsq_linear, minimize

    p = with_payload(params, payload_mass)
    n, m = p.n_joints, p.n_cables
    amax = p.geometry.alpha_max
    lo = p.actuation.f_min if f_min is None else float(f_min)
    hi = p.actuation.f_max if f_max is None else float(f_max)
    if not 0 <= lo < hi:
        raise ValueError(f"force box: need 0 <= f_min < f_max, got [{lo}, {hi}] N")
    if (alpha_target is None) == (head_target is None):
        raise ValueError("inverse_statics: give exactly one of alpha_target (N,) and head_target (2,) or (3,)")
    if alpha_target is not None:
        alpha_target = check_alpha(alpha_target, n, "alpha_target")
        if np.any(np.abs(alpha_target) >= amax):
            raise ValueError(f"alpha_target: outside the joint range |alpha| < {amax:.3g} rad")
        start = alpha_target if alpha0 is None else check_alpha(alpha0, n, "alpha0")
    else:
        head_target = np.asarray(head_target, dtype=float)
        if head_target.shape not in ((2,), (3,)) or not np.all(np.isfinite(head_target)):
            raise ValueError(f"head_target: expected finite (x, y) or (x, y, angle), got {head_target!r}")
        start = np.zeros(n) if alpha0 is None else check_alpha(alpha0, n, "alpha0")
    Z0 = cable_kinematics(start, np.zeros(n), p).Z
    f0 = lsq_linear(Z0, gravity_spring_torque(start, p), bounds=(lo, hi)).x
    w = regularisation / hi
    w_pose = regularisation if head_target is not None else 0.0

    def objective(x):
        a, f = x[:n], x[n:]
        err, J = _task(a, p, alpha_target, head_target)
        value = 0.5 * (err @ err + w * w * np.sum((f - lo) ** 2) + w_pose ** 2 * np.sum((a - start) ** 2))
        return value, np.r_[J.T @ err + w_pose ** 2 * (a - start), w * w * (f - lo)]

    def balance(x):
        a, f = x[:n], x[n:]
        return _force_terms(a, f, p)[0]

    def balance_jac(x):
        a, f = x[:n], x[n:]
        ck = cable_kinematics(a, np.ones(n), p)
        return np.hstack([potential_hessian(a, p) + _cable_curvature_term(ck.Zdot, f), -ck.Z])

    bounds = [(-0.98 * amax, 0.98 * amax)] * n + [(lo, hi)] * m
    sol = minimize(objective, np.r_[start, f0], jac=True, method="SLSQP", bounds=bounds,
                   constraints=[{"type": "eq", "fun": balance, "jac": balance_jac}],
                   options={"maxiter": 100, "ftol": 1e-14})
    forces = np.clip(sol.x[n:], lo, hi)
    eq = equilibrium_for_forces(forces, p, sol.x[:n])
    if not eq.converged:
        raise ValueError(f"inverse_statics: no equilibrium inside the joint range found for the target "
                         f"({sol.message}); it is out of reach with tensions in [{lo:g}, {hi:g}] N")
    err, _ = _task(eq.alpha, p, alpha_target, head_target)
    return HoldingSolution(forces, eq, err)


def least_tensions(alpha: npt.ArrayLike, params: NeckParams, f_min: float | None = None,
                   f_max: float | None = None) -> np.ndarray:
    """The smallest total tension (m,) N in [f_min, f_max] that holds pose ``alpha`` (N,) exactly:
    the linear program min sum t subject to Z t = g (eq 30 at rest); ValueError if none does."""
    from scipy.optimize import linprog

    a = check_alpha(alpha, params.n_joints)
    lo = params.actuation.f_min if f_min is None else float(f_min)
    hi = params.actuation.f_max if f_max is None else float(f_max)
    Z = cable_kinematics(a, np.zeros_like(a), params).Z
    res = linprog(np.ones(params.n_cables), A_eq=Z, b_eq=gravity_spring_torque(a, params), bounds=(lo, hi),
                  method="highs")
    if res.status != 0:
        raise ValueError(f"least_tensions: no tensions in [{lo:g}, {hi:g}] N hold this pose ({res.message})")
    return res.x


def friction_band(forces: npt.ArrayLike, alpha: npt.ArrayLike, params: NeckParams, f_s: npt.ArrayLike | None = None,
                  max_corners: int = 256, seed: int = 0) -> Equilibrium:
    """Equilibria between dry friction acting one way and the other at every motor.

    A motor commanded ``forces`` (m,) N that has stopped holds its cable at any tension in
    [f - f_s, f + f_s] (eq 37 at its limits: winding in, friction subtracts; paying out, it adds).
    Returns the equilibria (K, N) at the 2^m sign corners (a random ``max_corners`` of them for many
    cables), solved from the pose ``alpha`` (N,) the forces hold.  ``f_s`` defaults to
    ``params.friction.f_s``.
    """
    f = check_cables(forces, params.n_cables, "forces")
    fs = np.asarray(params.friction.f_s if f_s is None else f_s, dtype=float)
    m = params.n_cables
    if 2 ** m <= max_corners:
        signs = ((np.arange(2 ** m)[:, None] >> np.arange(m)) & 1) * 2.0 - 1.0
    else:
        signs = np.random.default_rng(seed).choice([-1.0, 1.0], (max_corners, m))
    tension = np.maximum(f + signs * fs, 0.0)
    return equilibrium_for_forces(tension, params, alpha)
