"""Dynamics of the N-X neck: bar linkage, geared motors, friction and elastic cables (paper §3).

The bar linkage of each X-joint has three moving rigid bodies (diagonals AD and BC, top bar CD);
the base bar of joint 1 is the ground.  Bars are slender rods (I = m l^2 / 12).  With the
closed-form kinematics of :mod:`neck_sim.analytic.geometry`, each body's velocity is J(alpha)
alpha_dot and its velocity-dependent acceleration is h(alpha, alpha_dot); then

    M_m = sum m J_p^T J_p + I J_phi^T J_phi,    c_m = sum m J_p^T h_p + I J_phi^T h_phi,

the Lagrangian equations of the linkage.  g (``gravity_spring_torque``) is the gradient of the
potential of gravity (along -y) and of the side springs.  Motors add (eqs 24, 26 corrected):

    M = M_m + I_a (R/r_d)^2 Z Z^T,    c = c_m + I_a (R/r_d)^2 Z Zdot^T alpha_dot.

Elastic cables use the sign convention of :mod:`neck_sim.analytic.cables`:
x_c = l_c - l_c0 + (r_d/R) theta, so that eqs (29), (30) read

    I_a theta_ddot = (r_d/R) (f - t_c - f_friction),    M_m alpha_ddot + c_m + g = Z t_c.

Shapes: alpha, alpha_dot (..., N); forces, tensions (..., m) (m cables, N + 1 for the paper's routing).  SI units throughout.
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np

from neck_sim.analytic.cables import cable_kinematics, transmission_matrix
from neck_sim.analytic.geometry import _cross, _joint_local, _vec2, check_alpha, check_pose, forward_kinematics
from neck_sim.params import NeckParams

__all__ = ["LinkageDynamics", "linkage_dynamics", "mass_matrix", "bias_forces", "gravity_spring_torque",
           "potential_energy", "kinetic_energy", "motor_friction", "cable_tension", "cable_stiffness",
           "static_elongation", "elongation_step", "elongation_series", "rigid_acceleration",
           "ElasticState", "elastic_derivative", "simulate_elastic", "simulate_rigid"]



class LinkageDynamics(NamedTuple):
    """M_m (..., N, N) kg m^2, c_m (..., N) N m, g (..., N) N m of the bar linkage without motors."""

    M: np.ndarray
    c: np.ndarray
    g: np.ndarray


def _exclusive_cumsum(x: np.ndarray, axis: int) -> np.ndarray:
    return np.cumsum(x, axis=axis) - x


def linkage_dynamics(alpha, alpha_dot, params: NeckParams, *, allow_outside_range: bool = False) -> LinkageDynamics:
    """M_m, c_m and g of the bar linkage (eq 30's left-hand side), batched over leading axes.

    Frame i (base bar of joint i) has world angle phi_i = sum_{k<i} alpha_k and origin p_i; the
    top-bar midpoint m_i(alpha_i) of joint i is the origin of frame i+1.  The recursion
    p_{i+1} = p_i + R(phi_i) m_i gives, as exclusive cumulative sums over joints, the frame
    Jacobians J_{p_i} and velocity-product accelerations h_{p_i}; a body point q(alpha_i) of joint i
    then has J = J_{p_i} + S R q [k < i] + R q' [k = i] and
    h = h_{p_i} - phi_dot^2 R q + 2 phi_dot alpha_dot_i S R q' + alpha_dot_i^2 R q''.
    """
    g = params.geometry
    n = g.n_joints
    a = check_pose(alpha, params, allow_outside_range=allow_outside_range)
    ad = check_alpha(alpha_dot, n, "alpha_dot")
    a, ad = np.broadcast_arrays(a, ad)
    b, L = g.b, g.L
    inert = params.inertia
    jl = _joint_local(a, b, L)                                    # corners per joint, (..., N, 2)
    A = np.array([-b / 2, 0.0])
    B = np.array([b / 2, 0.0])
    m, dm, ddm = (jl.C + jl.D) / 2, (jl.dC + jl.dD) / 2, (jl.ddC + jl.ddD) / 2
    # moving bodies of each joint: diagonal AD, diagonal BC, top bar CD -> axis -2 of size 3
    q = np.stack([(A + jl.D) / 2, (B + jl.C) / 2, m], -2)          # (..., N, 3, 2)
    dq = np.stack([jl.dD / 2, jl.dC / 2, dm], -2)
    ddq = np.stack([jl.ddD / 2, jl.ddC / 2, ddm], -2)
    one = np.ones_like(a)
    dbeta = np.stack([_cross(jl.D - A, jl.dD) / L ** 2, _cross(jl.C - B, jl.dC) / L ** 2, one], -1)
    ddbeta = np.stack([_cross(jl.D - A, jl.ddD) / L ** 2, _cross(jl.C - B, jl.ddC) / L ** 2, 0 * one], -1)
    mass = np.array([inert.diagonal_mass, inert.diagonal_mass, inert.bar_mass])
    rot_inertia = mass * np.array([L, L, b]) ** 2 / 12.0

    phi = _exclusive_cumsum(a, -1)
    phi_dot = _exclusive_cumsum(ad, -1)
    cphi, sphi = np.cos(phi), np.sin(phi)

    def rot(v, extra=0):  # R(phi_i) v for v of shape (..., N, [3,] 2)
        cc = cphi.reshape(cphi.shape + (1,) * extra)
        ss = sphi.reshape(sphi.shape + (1,) * extra)
        return _vec2(cc * v[..., 0] - ss * v[..., 1], ss * v[..., 0] + cc * v[..., 1])

    def turn(v):  # S v: rotation by +90 deg
        return _vec2(-v[..., 1], v[..., 0])

    Rm, Rdm, Rddm = rot(m), rot(dm), rot(ddm)
    lt = np.tril(np.ones((n, n)), -1)                             # lt[i, k] = 1 if k < i
    eye = np.eye(n)
    # increments of the frame-origin Jacobian and bias from joint j to j+1
    dJ = turn(Rm)[..., :, :, None] * lt[:, None, :] + Rdm[..., :, :, None] * eye[:, None, :]   # (..., N, 2, N)
    dh = ((-phi_dot ** 2)[..., None] * Rm + (2 * phi_dot * ad)[..., None] * turn(Rdm)
          + (ad ** 2)[..., None] * Rddm)                                                       # (..., N, 2)
    J_o = _exclusive_cumsum(dJ, -3)
    h_o = _exclusive_cumsum(dh, -2)

    Rq, Rdq, Rddq = rot(q, 1), rot(dq, 1), rot(ddq, 1)            # (..., N, 3, 2)
    pd, adn = phi_dot[..., None, None], ad[..., None, None]
    h = h_o[..., :, None, :] - pd ** 2 * Rq + 2 * pd * adn * turn(Rdq) + adn ** 2 * Rddq          # (..., N, 3, 2)
    hphi = ddbeta * (ad ** 2)[..., None]                                                          # (..., N, 3)

    # Mass-weighted velocity rows of every body (x, y, rotation): M = W^T W, c = W^T h_w.
    batch = a.shape[:-1]
    w_lin = np.sqrt(mass)[:, None, None]
    w_rot = np.sqrt(rot_inertia)[:, None]
    W = np.empty(batch + (n, 3, 3, n))
    J = W[..., :2, :]
    np.add(J_o[..., :, None, :, :], turn(Rq)[..., None] * lt[:, None, None, :], out=J)
    J += Rdq[..., None] * eye[:, None, None, :]                   # J: (..., N, 3, 2, N), unweighted here
    G = inert.gravity * np.einsum("...ibk,b->...k", J[..., 1, :], mass)
    Jh = J[..., n - 1, 2, :, :].copy()                            # head bar centre, for a payload
    J *= w_lin
    W[..., 2, :] = (lt[:, None, :] + dbeta[..., None] * eye[:, None, :]) * w_rot
    hw = np.concatenate([h * w_lin[..., 0], (hphi * w_rot[:, 0])[..., None]], -1)
    W = W.reshape(batch + (9 * n, n))
    Wt = np.swapaxes(W, -1, -2)
    M = Wt @ W
    c = (Wt @ hw.reshape(batch + (9 * n, 1)))[..., 0]
    if inert.payload_mass > 0:                                    # point mass at the head's bar centre
        hh = h[..., n - 1, 2, :]
        M = M + inert.payload_mass * np.einsum("...xk,...xl->...kl", Jh, Jh)
        c = c + inert.payload_mass * np.einsum("...xk,...x->...k", Jh, hh)
        G = G + inert.payload_mass * inert.gravity * Jh[..., 1, :]

    sd = jl.sides
    k = np.asarray(params.springs.stiffness)
    l0 = params.springs.rest_length
    G = G + k * ((sd.l_l - l0) * sd.dl_l + (sd.l_r - l0) * sd.dl_r)
    return LinkageDynamics(M, c, G)


def mass_matrix(alpha, params: NeckParams, motors: bool = True, *, allow_outside_range: bool = False) -> np.ndarray:
    """Inertia matrix M(alpha) of eq (24) (with motors) or M_m (without), (..., N, N), kg m^2."""
    a = check_pose(alpha, params, allow_outside_range=allow_outside_range)
    M = linkage_dynamics(a, np.zeros_like(a), params, allow_outside_range=True).M
    if motors:
        Z = transmission_matrix(a, params, allow_outside_range=True)
        M = M + params.actuation.reflected_inertia * Z @ np.swapaxes(Z, -1, -2)
    return M


def bias_forces(alpha, alpha_dot, params: NeckParams, motors: bool = True, *,
                allow_outside_range: bool = False) -> np.ndarray:
    """Coriolis/centrifugal vector c(alpha, alpha_dot) of eq (26) corrected, (..., N), N m.

    Motor part: I_a (R/r_d)^2 Z Zdot^T alpha_dot (erratum 5: not Zdot Z^T).
    """
    c = linkage_dynamics(alpha, alpha_dot, params, allow_outside_range=allow_outside_range).c
    if motors:
        ck = cable_kinematics(alpha, alpha_dot, params, allow_outside_range=True)
        zdt_ad = np.einsum("...ij,...i->...j", ck.Zdot, np.asarray(alpha_dot, dtype=float))
        c = c + params.actuation.reflected_inertia * np.einsum("...ij,...j->...i", ck.Z, zdt_ad)
    return c


def gravity_spring_torque(alpha, params: NeckParams, *, allow_outside_range: bool = False) -> np.ndarray:
    """g(alpha): gradient of the gravity and side-spring potential (eq 25), (..., N), N m."""
    a = check_pose(alpha, params, allow_outside_range=allow_outside_range)
    return linkage_dynamics(a, np.zeros_like(a), params, allow_outside_range=True).g


def potential_energy(alpha, params: NeckParams, *, allow_outside_range: bool = False) -> np.ndarray:
    """Gravity + side-spring potential (J), from the forward kinematics (independent of g)."""
    kin = forward_kinematics(alpha, params, allow_outside_range=allow_outside_range)
    inert = params.inertia
    corners = kin.corners                                  # (..., N, 4, 2): A, B, C, D
    y_ad = 0.5 * (corners[..., 0, 1] + corners[..., 3, 1])
    y_bc = 0.5 * (corners[..., 1, 1] + corners[..., 2, 1])
    y_cd = 0.5 * (corners[..., 2, 1] + corners[..., 3, 1])
    v = inert.gravity * (inert.diagonal_mass * (y_ad + y_bc) + inert.bar_mass * y_cd).sum(-1)
    v = v + inert.gravity * inert.payload_mass * kin.head_position[..., 1]
    left = np.linalg.norm(corners[..., 2, :] - corners[..., 0, :], axis=-1)
    right = np.linalg.norm(corners[..., 3, :] - corners[..., 1, :], axis=-1)
    k = np.asarray(params.springs.stiffness)
    l0 = params.springs.rest_length
    return v + 0.5 * (k * ((left - l0) ** 2 + (right - l0) ** 2)).sum(-1)


def kinetic_energy(alpha, alpha_dot, params: NeckParams, motors: bool = True, *,
                   allow_outside_range: bool = False) -> np.ndarray:
    """1/2 alpha_dot^T M alpha_dot (J)."""
    ad = np.asarray(alpha_dot, dtype=float)
    M = mass_matrix(alpha, params, motors, allow_outside_range=allow_outside_range)
    return 0.5 * np.einsum("...i,...ij,...j->...", ad, M, ad)


def motor_friction(theta_dot, params: NeckParams, f_s=None) -> np.ndarray:
    """Arctan dry friction at the motors, eq (37): (2/pi) arctan(c_s theta_dot) f_s, (..., m), N.

    Expressed as a force along the cable; ``f_s`` defaults to the plant's ``params.friction.f_s``.
    """
    fs = np.asarray(params.friction.f_s if f_s is None else f_s, dtype=float)
    return (2 / np.pi) * np.arctan(params.friction.c_s * np.asarray(theta_dot, dtype=float)) * fs


def cable_tension(x, x_dot, params: NeckParams, k=None, lam=None, c_a=None) -> np.ndarray:
    """Tension-only cable tension of eq (54) solved for t, (..., m), N.

    t = (k x + c_a x_dot) / (1 - lambda x) for x > 0, 0 when slack (x <= 0) and never negative.
    Above ``cables.t_cap`` the elastic part continues with its tangent stiffness, so there is no
    pole at x = 1/lambda.  Defaults are the plant's ``params.cables``.
    """
    cab = params.cables
    k = np.asarray(cab.k if k is None else k, dtype=float)
    lam = np.asarray(cab.lam if lam is None else lam, dtype=float)
    c_a = np.asarray(cab.c_a if c_a is None else c_a, dtype=float)
    x = np.asarray(x, dtype=float)
    x_dot = np.asarray(x_dot, dtype=float)
    x_star = cab.t_cap / (k + lam * cab.t_cap)             # elongation where t reaches t_cap
    xe = np.minimum(x, x_star)
    denom = 1.0 - lam * xe
    elastic = k * xe / denom + np.maximum(x - x_star, 0.0) * k / (1.0 - lam * x_star) ** 2
    t = elastic + c_a * x_dot / denom
    return np.where(x > 0, np.maximum(t, 0.0), 0.0)


def cable_stiffness(tension, k, lam) -> np.ndarray:
    """Secant stiffness k + lambda t of eq (54), (..., m) N/m, for tensions t (..., m) N
    (negative tensions count as 0: a cable cannot push); ``k`` N/m, ``lam`` 1/m."""
    return np.asarray(k, dtype=float) + np.asarray(lam, dtype=float) * np.maximum(np.asarray(tension, dtype=float), 0.0)


def static_elongation(tension, k, lam) -> np.ndarray:
    """Eq (54) inverted at rest (x_dot = 0): x = t / (k + lambda t), (..., m) m, 0 for t <= 0.

    The one definition of elongation from tension; :func:`elongation_step` and
    :func:`elongation_series` add the damping c_a x_dot."""
    return np.maximum(np.asarray(tension, dtype=float), 0.0) / cable_stiffness(tension, k, lam)


def elongation_step(x, tension, dt: float, k, lam, c_a) -> np.ndarray:
    """Eq (58): one explicit Euler step of eq (54), c_a x_dot = t - (k + lambda t) x, (m,) m.

    ``x`` (..., m) m the elongation at the start of the step, ``tension`` (..., m) N (>= 0)
    applied during it, ``dt`` s, ``c_a`` N s/m > 0."""
    return x + dt / c_a * (tension - cable_stiffness(tension, k, lam) * x)


def elongation_series(tension, dt: float, k, lam, c_a, x0=None) -> np.ndarray:
    """Elongations x (T, m) m of eq (54) for tensions (T, m) N held per sample of ``dt`` s.

    Each step is the exact solution x_inf + (x - x_inf) exp(-(k + lambda t) dt / c_a) with
    x_inf = :func:`static_elongation` (stable for any dt; c_a = 0 gives the static elongation);
    ``x0`` (m,) m defaults to the static elongation of the first sample."""
    tension = np.asarray(tension, dtype=float)
    c_a = np.asarray(c_a, dtype=float)
    stiff = cable_stiffness(tension, k, lam)
    x_inf = static_elongation(tension, k, lam)
    if np.all(c_a == 0):
        return x_inf
    decay = np.exp(-stiff * dt / np.where(c_a > 0, c_a, 1.0))
    decay = np.where(c_a > 0, decay, 0.0)
    x = np.empty_like(tension)
    x[0] = x_inf[0] if x0 is None else x0
    for i in range(1, tension.shape[0]):
        x[i] = x_inf[i] + (x[i - 1] - x_inf[i]) * decay[i]
    return x


def rigid_acceleration(alpha, alpha_dot, f, params: NeckParams, friction: bool = True, *,
                       allow_outside_range: bool = False) -> np.ndarray:
    """alpha_ddot of eq (32) with inextensible cables (x_c = 0), (..., N), rad/s^2.

    Motor speeds for friction follow eq (21): theta_dot = (R/r_d) Z^T alpha_dot.
    """
    act = params.actuation
    ck = cable_kinematics(alpha, alpha_dot, params, allow_outside_range=allow_outside_range)
    lk = linkage_dynamics(alpha, alpha_dot, params, allow_outside_range=True)
    Zt = np.swapaxes(ck.Z, -1, -2)
    ad = np.asarray(alpha_dot, dtype=float)
    ia = act.reflected_inertia
    M = lk.M + ia * ck.Z @ Zt
    c = lk.c + ia * np.einsum("...ij,...j->...i", ck.Z, np.einsum("...ij,...i->...j", ck.Zdot, ad))
    f = np.asarray(f, dtype=float)
    if friction:
        theta_dot = (act.R / act.r_d) * np.einsum("...ij,...i->...j", ck.Z, ad)
        f = f - motor_friction(theta_dot, params)
    rhs = np.einsum("...ij,...j->...i", ck.Z, f) - c - lk.g
    return np.linalg.solve(M, rhs[..., None])[..., 0]


class ElasticState(NamedTuple):
    """State of eqs (29)-(30): joint angles/speeds (..., N) and motor angles/speeds (..., m)."""

    alpha: np.ndarray
    alpha_dot: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray


def elastic_derivative(state: ElasticState, f, params: NeckParams, friction: bool = True, *,
                       allow_outside_range: bool = False):
    """(alpha_ddot, theta_ddot, tension) of eqs (29), (30) with elastic cables (eq 54)."""
    act = params.actuation
    ck = cable_kinematics(state.alpha, state.alpha_dot, params, allow_outside_range=allow_outside_range)
    ratio = act.r_d / act.R
    x = ck.lengths + ratio * state.theta
    x_dot = -np.einsum("...ij,...i->...j", ck.Z, state.alpha_dot) + ratio * state.theta_dot
    t = cable_tension(x, x_dot, params)
    lk = linkage_dynamics(state.alpha, state.alpha_dot, params, allow_outside_range=True)
    rhs = np.einsum("...ij,...j->...i", ck.Z, t) - lk.c - lk.g
    alpha_ddot = np.linalg.solve(lk.M, rhs[..., None])[..., 0]
    fr = motor_friction(state.theta_dot, params) if friction else 0.0
    theta_ddot = ratio * (np.asarray(f, dtype=float) - t - fr) / act.I_a
    return alpha_ddot, theta_ddot, t


def simulate_elastic(alpha0, theta0, forces: Callable[[float], np.ndarray], duration: float,
                     params: NeckParams, *, sample_dt: float = 1e-3, friction: bool = True,
                     alpha_dot0=None, theta_dot0=None, rtol: float = 1e-8, atol: float = 1e-10,
                     allow_outside_range: bool = False):
    """Integrate eqs (29)-(30) (scipy LSODA) for forces(t) -> (m,) N; returns (t, ElasticState)."""
    from scipy.integrate import solve_ivp

    n, m = params.n_joints, params.n_cables
    a0 = check_pose(alpha0, params, "alpha0", allow_outside_range=allow_outside_range)
    th0 = np.asarray(theta0, dtype=float).reshape(m)
    ad0 = np.zeros(n) if alpha_dot0 is None else np.asarray(alpha_dot0, dtype=float)
    td0 = np.zeros(m) if theta_dot0 is None else np.asarray(theta_dot0, dtype=float)

    def rhs(t, y):
        st = ElasticState(y[:n], y[n:2 * n], y[2 * n:2 * n + m], y[2 * n + m:])
        add, tdd, _ = elastic_derivative(st, forces(t), params, friction, allow_outside_range=allow_outside_range)
        return np.concatenate([st.alpha_dot, add, st.theta_dot, tdd])

    times = np.arange(0.0, duration + 0.5 * sample_dt, sample_dt)
    sol = solve_ivp(rhs, (0.0, times[-1]), np.concatenate([a0, ad0, th0, td0]), t_eval=times,
                    method="LSODA", rtol=rtol, atol=atol)
    if not sol.success:
        raise RuntimeError(f"simulate_elastic: integration failed ({sol.message})")
    y = sol.y.T
    return sol.t, ElasticState(y[:, :n], y[:, n:2 * n], y[:, 2 * n:2 * n + m], y[:, 2 * n + m:])


def simulate_rigid(alpha0, forces: Callable[[float], np.ndarray], duration: float, params: NeckParams,
                   *, sample_dt: float = 1e-3, friction: bool = True, alpha_dot0=None,
                   rtol: float = 1e-10, atol: float = 1e-12, allow_outside_range: bool = False):
    """Integrate eq (32) with inextensible cables (scipy DOP853); returns (t, alpha, alpha_dot)."""
    from scipy.integrate import solve_ivp

    n = params.n_joints
    a0 = check_pose(alpha0, params, "alpha0", allow_outside_range=allow_outside_range)
    ad0 = np.zeros(n) if alpha_dot0 is None else np.asarray(alpha_dot0, dtype=float)

    def rhs(t, y):
        add = rigid_acceleration(y[:n], y[n:], forces(t), params, friction, allow_outside_range=allow_outside_range)
        return np.concatenate([y[n:], add])

    times = np.arange(0.0, duration + 0.5 * sample_dt, sample_dt)
    sol = solve_ivp(rhs, (0.0, times[-1]), np.concatenate([a0, ad0]), t_eval=times, method="DOP853",
                    rtol=rtol, atol=atol)
    if not sol.success:
        raise RuntimeError(f"simulate_rigid: integration failed ({sol.message})")
    return sol.t, sol.y[:n].T, sol.y[n:].T
