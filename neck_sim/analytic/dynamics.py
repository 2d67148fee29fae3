"""Dynamics of the N-X neck: bar linkage, geared motors, friction and elastic cables (paper §3).

The bar linkage of each X-joint has three moving rigid bodies (diagonals AD and BC, top bar CD);
the base bar of joint 1 is the ground.  Bars are slender rods (I = m l^2 / 12).  With the
closed-form kinematics of :mod:`neck_sim.analytic.geometry`, each body's velocity is J(alpha)
alpha_dot and its velocity-dependent acceleration is h(alpha, alpha_dot); then

    M_m = sum m J_p^T J_p + I J_phi^T J_phi,    c_m = sum m J_p^T h_p + I J_phi^T h_phi,

the Lagrangian equations of the linkage.  g (``gravity_spring_torque``) is the gradient of the
potential of gravity (along -y) and of the side springs.  Motors add (eqs 24, 26 corrected):

    M = M_m + I_a (R/r_d)^2 Z Z^T,    c = c_m + I_a (R/r_d)^2 Z Zdot^T alpha_dot.

Where only the torque M alpha_ddot + c + g is needed, ``inverse_dynamics`` carries the bodies'
forces down the chain (Newton-Euler) without forming M: O(N) per sample, not O(N^3).  The cables' law
(eq 54) is :mod:`neck_sim.analytic.cable_law`, re-exported here.

Elastic cables use the sign convention of :mod:`neck_sim.analytic.cables`:
x_c = l_c - l_c0 + (r_d/R) theta, so that eqs (29), (30) read

    I_a theta_ddot = (r_d/R) (f - t_c - f_friction),    M_m alpha_ddot + c_m + g = Z t_c.

Shapes: alpha, alpha_dot (..., N); forces, tensions (..., m) (m cables, N + 1 for the paper's routing).  SI units throughout.
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np
import numpy.typing as npt

from neck_sim.analytic.cables import cable_kinematics, transmission_matrix, transmission_terms
from neck_sim.analytic.cable_law import (cable_stiffness, cable_tension, cap_elongation,  # noqa: F401 (re-exported)
                                         elongation_series, elongation_step, euler_elongation, secant_stiffness,
                                         static_elongation)
from neck_sim.analytic.geometry import (check_alpha, check_pose, corner_terms_kernel, forward_kinematics,
                                        side_terms_kernel)
from neck_sim.jit import dual, kernel
from neck_sim.params import NeckParams

__all__ = ["LinkageDynamics", "linkage_constants", "linkage_kernel", "linkage_dynamics", "mass_matrix",
           "bias_forces", "JointDynamics", "joint_dynamics", "inverse_dynamics",
           "gravity_spring_torque", "potential_energy", "kinetic_energy", "arctan_friction",
           "motor_friction", "cable_tension", "secant_stiffness", "cable_stiffness", "static_elongation",
           "euler_elongation", "elongation_step",
           "elongation_series", "rigid_acceleration",
           "ElasticState", "elastic_derivative", "simulate_elastic", "simulate_rigid"]



class LinkageDynamics(NamedTuple):
    """M_m (..., N, N) kg m^2, c_m (..., N) N m, g (..., N) N m of the bar linkage without motors."""

    M: np.ndarray
    c: np.ndarray
    g: np.ndarray


def linkage_constants(params: NeckParams) -> np.ndarray:
    """The linkage's constants as one float vector for :func:`linkage_kernel`.

    [b, L, diagonal mass, bar mass, gravity, payload mass, spring rest length, k_1 .. k_N].
    """
    g, inert, spr = params.geometry, params.inertia, params.springs
    k = np.broadcast_to(np.asarray(spr.stiffness, dtype=float), (g.n_joints,))
    return np.concatenate([[g.b, g.L, inert.diagonal_mass, inert.bar_mass, inert.gravity,
                            inert.payload_mass, spr.rest_length], k])


@kernel
def linkage_kernel(a: np.ndarray, ad: np.ndarray, const: np.ndarray, M: np.ndarray, c: np.ndarray,
                   G: np.ndarray) -> None:
    """M_m (N, N), c_m (N,), g (N,) of one sample into M, c, G (see :func:`_linkage_pass`)."""
    _linkage_pass(a, ad, const, M, c, G, np.empty((5, a.shape[0])))


@kernel
def _linkage_pass(a, ad, const, M, c, G, work) -> None:
    """M_m (N, N), c_m (N,), g (N,) of one sample into M, c, G.  ``work`` (5, N): scratch.

    Bodies of joint i: diagonal AD, diagonal BC, top bar CD (slender rods, I = m l^2 / 12).  Frame
    i has angle phi_i = sum_{k<i} alpha_k and origin p_i; the top-bar midpoint m_i(alpha_i) is
    the origin of frame i+1.  A body point q(alpha_i) of joint i has the velocity Jacobian
    J = J_{p_i} + S R q [k < i] + R q' [k = i] and the velocity-product acceleration
    h = h_{p_i} - phi_dot^2 R q + 2 phi_dot alpha_dot_i S R q' + alpha_dot_i^2 R q''; then
    M_m = sum m J^T J + I J_phi^T J_phi, c_m = sum m J^T h + I J_phi^T h_phi and g is the gradient of
    m g y plus the side springs' potential.  An optional payload is a point mass at the head's
    bar centre.
    """
    n = a.shape[0]
    b, L = const[0], const[1]
    mass = (const[2], const[2], const[3])
    inertia = (const[2] * L * L / 12.0, const[2] * L * L / 12.0, const[3] * b * b / 12.0)
    grav, payload, l0 = const[4], const[5], const[6]
    M[:, :] = 0.0
    c[:] = 0.0
    G[:] = 0.0
    Jo = work[:2]                     # frame-origin Jacobian J_{p_i}
    Jo[:, :] = 0.0
    hox, hoy = 0.0, 0.0               # frame-origin acceleration h_{p_i}
    Jx, Jy, Jr = work[2], work[3], work[4]
    phi, phid = 0.0, 0.0
    for i in range(n):
        sd = side_terms_kernel(a[i], b, L)
        k = corner_terms_kernel(a[i], b, L, sd)
        cx, cy, dcx, dcy, ddcx, ddcy = k[0], k[1], k[2], k[3], k[4], k[5]
        dx, dy, ddx, ddy, dddx, dddy = k[6], k[7], k[8], k[9], k[10], k[11]
        cp, sp = np.cos(phi), np.sin(phi)
        w = ad[i]
        for body in range(3):
            qx, qy, dqx, dqy, ddqx, ddqy, db, ddb = _body_point(body, k, b, L)
            rqx, rqy = cp * qx - sp * qy, sp * qx + cp * qy
            rdx, rdy = cp * dqx - sp * dqy, sp * dqx + cp * dqy
            rddx, rddy = cp * ddqx - sp * ddqy, sp * ddqx + cp * ddqy
            # joints above i do not move this body: their entries are never read (every sum below
            # runs to i; the payload's, at i = n - 1, too)
            for kk in range(i):
                Jx[kk] = Jo[0, kk] - rqy
                Jy[kk] = Jo[1, kk] + rqx
                Jr[kk] = 1.0
            Jx[i] = rdx
            Jy[i] = rdy
            Jr[i] = db
            hx = hox - phid * phid * rqx - 2 * phid * w * rdy + w * w * rddx
            hy = hoy - phid * phid * rqy + 2 * phid * w * rdx + w * w * rddy
            hr = ddb * w * w
            m, I = mass[body], inertia[body]
            # the upper triangle only, mirrored at the end: each term is symmetric bit for bit
            # (products commute, and of Jr[kk], Jr[ll] all but the diagonal's one is exactly 1)
            for kk in range(i + 1):
                for ll in range(kk, i + 1):
                    M[kk, ll] += m * (Jx[kk] * Jx[ll] + Jy[kk] * Jy[ll]) + I * Jr[kk] * Jr[ll]
                c[kk] += m * (Jx[kk] * hx + Jy[kk] * hy) + I * Jr[kk] * hr
                G[kk] += grav * m * Jy[kk]
            if body == 2 and i == n - 1 and payload > 0:      # point mass at the head's bar centre
                for kk in range(n):
                    for ll in range(kk, n):
                        M[kk, ll] += payload * (Jx[kk] * Jx[ll] + Jy[kk] * Jy[ll])
                    c[kk] += payload * (Jx[kk] * hx + Jy[kk] * hy)
                    G[kk] += payload * grav * Jy[kk]
        G[i] += const[7 + i] * ((sd[0] - l0) * sd[1] + (sd[3] - l0) * sd[4])
        # frame i+1: origin p_i + R(phi_i) m_i with m_i the top-bar midpoint
        mx, my = (cx + dx) / 2, (cy + dy) / 2
        dmx, dmy = (dcx + ddx) / 2, (dcy + ddy) / 2
        ddmx, ddmy = (ddcx + dddx) / 2, (ddcy + dddy) / 2
        rmx, rmy = cp * mx - sp * my, sp * mx + cp * my
        rdmx, rdmy = cp * dmx - sp * dmy, sp * dmx + cp * dmy
        for kk in range(i):
            Jo[0, kk] -= rmy
            Jo[1, kk] += rmx
        Jo[0, i] += rdmx
        Jo[1, i] += rdmy
        hox += -phid * phid * rmx - 2 * phid * w * rdmy + w * w * (cp * ddmx - sp * ddmy)
        hoy += -phid * phid * rmy + 2 * phid * w * rdmx + w * w * (sp * ddmx + cp * ddmy)
        phi += a[i]
        phid += w
    for kk in range(n):
        for ll in range(kk):
            M[kk, ll] = M[ll, kk]


@kernel
def _body_point(body, k, b, L):
    """Body ``body`` of a joint (0: diagonal A-D, 1: diagonal B-C, 2: top bar C-D) in the joint's
    frame: its centre q (m) and the derivatives q', q'' along alpha, the rotation rate d beta /
    d alpha and its derivative, from the corners' terms ``k`` (``corner_terms_kernel``)."""
    cx, cy, dcx, dcy, ddcx, ddcy = k[0], k[1], k[2], k[3], k[4], k[5]
    dx, dy, ddx, ddy, dddx, dddy = k[6], k[7], k[8], k[9], k[10], k[11]
    if body == 0:
        ax = -b / 2
        return ((ax + dx) / 2, dy / 2, ddx / 2, ddy / 2, dddx / 2, dddy / 2,
                ((dx - ax) * ddy - dy * ddx) / (L * L), ((dx - ax) * dddy - dy * dddx) / (L * L))
    if body == 1:
        bx = b / 2
        return ((bx + cx) / 2, cy / 2, dcx / 2, dcy / 2, ddcx / 2, ddcy / 2,
                ((cx - bx) * dcy - cy * dcx) / (L * L), ((cx - bx) * ddcy - cy * ddcx) / (L * L))
    return ((cx + dx) / 2, (cy + dy) / 2, (dcx + ddx) / 2, (dcy + ddy) / 2, (ddcx + dddx) / 2, (ddcy + dddy) / 2,
            1.0, 0.0)


@kernel
def _inverse_pass(a, ad, add, const, tau, work) -> None:
    """tau = M_m add + c_m + g (eq 30's left-hand side) of one sample into tau (N,) N m in O(N),
    M_m never formed.  ``work`` (8, N): scratch.

    The same bodies, frames and Jacobians as :func:`_linkage_pass`, summed the other way round
    (Newton-Euler): a forward pass gives each body's acceleration J add + h (the frame origin's
    carried from joint to joint, its rotation phi_ddot = sum_{k<i} add_k) and its force
    F = m (acceleration + gravity along +y, the potential's gradient) and moment I beta_ddot.  A
    body of joint i > k has J's column k = R_k m_k' + S (x - p_{k+1}) (S: rotation by +90 deg,
    x its centre, p_{k+1} the origin of frame k+1) and rotation column 1, so joint k receives
    R_k m_k' . F_{>k} + M_{>k}: the sum F_{>k} of the forces of the bodies above joint k and their
    moment M_{>k} about p_{k+1}, which a backward pass carries down the chain.
    """
    n = a.shape[0]
    b, L = const[0], const[1]
    mass = (const[2], const[2], const[3])
    inertia = (const[2] * L * L / 12.0, const[2] * L * L / 12.0, const[3] * b * b / 12.0)
    grav, payload, l0 = const[4], const[5], const[6]
    own, fx, fy, mo, rmx, rmy, rdmx, rdmy = work[0], work[1], work[2], work[3], work[4], work[5], work[6], work[7]
    aox, aoy = 0.0, 0.0               # acceleration of the frame origin p_i
    phi, phid, phidd = 0.0, 0.0, 0.0
    for i in range(n):
        sd = side_terms_kernel(a[i], b, L)
        k = corner_terms_kernel(a[i], b, L, sd)
        cp, sp = np.cos(phi), np.sin(phi)
        w, u = ad[i], add[i]
        t_own = const[7 + i] * ((sd[0] - l0) * sd[1] + (sd[3] - l0) * sd[4])    # side springs
        f_x, f_y, m_o = 0.0, 0.0, 0.0
        for body in range(3):
            qx, qy, dqx, dqy, ddqx, ddqy, db, ddb = _body_point(body, k, b, L)
            rqx, rqy = cp * qx - sp * qy, sp * qx + cp * qy
            rdx, rdy = cp * dqx - sp * dqy, sp * dqx + cp * dqy
            rddx, rddy = cp * ddqx - sp * ddqy, sp * ddqx + cp * ddqy
            accx = aox - phidd * rqy - phid * phid * rqx - 2 * phid * w * rdy + w * w * rddx + u * rdx
            accy = aoy + phidd * rqx - phid * phid * rqy + 2 * phid * w * rdx + w * w * rddy + u * rdy
            m = mass[body]
            if body == 2 and i == n - 1:      # the payload: a point mass at the head's bar centre
                m += payload
            px, py = m * accx, m * (accy + grav)
            nz = inertia[body] * (phidd + db * u + ddb * w * w)
            t_own += rdx * px + rdy * py + db * nz
            f_x, f_y, m_o = f_x + px, f_y + py, m_o + (rqx * py - rqy * px + nz)
            if body == 2:                     # frame i+1: origin p_i + R(phi_i) m_i, m_i the top bar's centre
                rmx[i], rmy[i], rdmx[i], rdmy[i], aox, aoy = rqx, rqy, rdx, rdy, accx, accy
        own[i], fx[i], fy[i], mo[i] = t_own, f_x, f_y, m_o
        phi, phid, phidd = phi + a[i], phid + w, phidd + u
    f_x, f_y, m_o = 0.0, 0.0, 0.0     # force of the bodies above joint i, moment about p_{i+1}
    for i in range(n - 1, -1, -1):
        tau[i] = own[i] + rdmx[i] * f_x + rdmy[i] * f_y + m_o
        m_o += mo[i] + rmx[i] * f_y - rmy[i] * f_x
        f_x, f_y = f_x + fx[i], f_y + fy[i]


@kernel
def _linkage_rows(a, ad, const, M, c, G) -> None:
    work = np.empty((5, a.shape[1]))    # scratch shared by the samples
    for r in range(a.shape[0]):
        _linkage_pass(a[r], ad[r], const, M[r], c[r], G[r], work)


@kernel
def _inverse_rows(a, ad, add, const, tau) -> None:
    work = np.empty((8, a.shape[1]))    # scratch shared by the samples
    for r in range(a.shape[0]):
        _inverse_pass(a[r], ad[r], add[r], const, tau[r], work)


def linkage_dynamics(alpha: npt.ArrayLike, alpha_dot: npt.ArrayLike, params: NeckParams, *,
                     allow_outside_range: bool = False) -> LinkageDynamics:
    """M_m, c_m and g of the bar linkage (eq 30's left-hand side), batched over leading axes.

    alpha, alpha_dot (..., N) rad, rad/s; M_m (..., N, N) kg m^2, c_m, g (..., N) N m
    (:func:`linkage_kernel`, one sample at a time).
    """
    n = params.n_joints
    a = check_pose(alpha, params, allow_outside_range=allow_outside_range)
    ad = check_alpha(alpha_dot, n, "alpha_dot")
    a, ad = np.broadcast_arrays(a, ad)
    batch = a.shape[:-1]
    rows = int(np.prod(batch))
    M = np.empty((rows, n, n))
    c = np.empty((rows, n))
    G = np.empty((rows, n))
    _linkage_rows(np.ascontiguousarray(a.reshape(rows, n)), np.ascontiguousarray(ad.reshape(rows, n)),
                  linkage_constants(params), M, c, G)
    return LinkageDynamics(M.reshape(batch + (n, n)), c.reshape(batch + (n,)), G.reshape(batch + (n,)))


def mass_matrix(alpha: npt.ArrayLike, params: NeckParams, motors: bool = True, *,
                allow_outside_range: bool = False) -> np.ndarray:
    """Inertia matrix M(alpha) of eq (24) (with motors) or M_m (without), (..., N, N), kg m^2."""
    a = check_pose(alpha, params, allow_outside_range=allow_outside_range)
    M = linkage_dynamics(a, np.zeros_like(a), params, allow_outside_range=True).M
    if motors:
        M = _with_motor_inertia(M, transmission_matrix(a, params, allow_outside_range=True), params)
    return M


def _with_motor_inertia(M_m: np.ndarray, Z: np.ndarray, params: NeckParams) -> np.ndarray:
    """Eq (24): M = M_m + I_a (R/r_d)^2 Z Z^T, (..., N, N) kg m^2."""
    return M_m + params.actuation.reflected_inertia * Z @ np.swapaxes(Z, -1, -2)


def _with_motor_bias(c_m: np.ndarray, Z: np.ndarray, Zdot: np.ndarray, alpha_dot: npt.ArrayLike,
                     params: NeckParams) -> np.ndarray:
    """Eq (26) corrected: c = c_m + I_a (R/r_d)^2 Z Zdot^T alpha_dot (erratum 5), (..., N) N m."""
    zdt_ad = np.einsum("...ij,...i->...j", Zdot, np.asarray(alpha_dot, dtype=float))
    return c_m + params.actuation.reflected_inertia * np.einsum("...ij,...j->...i", Z, zdt_ad)


def bias_forces(alpha: npt.ArrayLike, alpha_dot: npt.ArrayLike, params: NeckParams, motors: bool = True, *,
                allow_outside_range: bool = False) -> np.ndarray:
    """Coriolis/centrifugal vector c(alpha, alpha_dot) of eq (26) corrected, (..., N), N m.

    Motor part: I_a (R/r_d)^2 Z Zdot^T alpha_dot (erratum 5: not Zdot Z^T).
    """
    c = linkage_dynamics(alpha, alpha_dot, params, allow_outside_range=allow_outside_range).c
    if motors:
        c = _with_motor_bias(c, *transmission_terms(alpha, alpha_dot, params, allow_outside_range=True), alpha_dot,
                             params)
    return c


class JointDynamics(NamedTuple):
    """Z (..., N, m) m, M (..., N, N) kg m^2 and c (..., N) N m with the motors, g (..., N) N m."""

    Z: np.ndarray
    M: np.ndarray
    c: np.ndarray
    g: np.ndarray


def joint_dynamics(alpha: npt.ArrayLike, alpha_dot: npt.ArrayLike, params: NeckParams, *,
                   allow_outside_range: bool = False,
                   transmission: tuple[np.ndarray, np.ndarray] | None = None) -> JointDynamics:
    """:func:`transmission_matrix`, :func:`mass_matrix`, :func:`bias_forces` (both with motors) and
    :func:`gravity_spring_torque` in one pass, bit for bit: one linkage evaluation (M_m and g do
    not depend on alpha_dot) and one of the cable segments' derivatives, where the four functions
    take three and three (a 10-joint neck's identification computes these on every bootstrap
    replicate).  alpha, alpha_dot (..., N) rad, rad/s; ``transmission``: (Z, Zdot) of these
    angles and ``params`` when the caller has them (``cable_kinematics``)."""
    lk = linkage_dynamics(alpha, alpha_dot, params, allow_outside_range=allow_outside_range)
    Z, Zdot = transmission or transmission_terms(alpha, alpha_dot, params, allow_outside_range=True)
    return JointDynamics(Z, _with_motor_inertia(lk.M, Z, params), _with_motor_bias(lk.c, Z, Zdot, alpha_dot, params),
                         lk.g)


def inverse_dynamics(alpha: npt.ArrayLike, alpha_dot: npt.ArrayLike, alpha_ddot: npt.ArrayLike, params: NeckParams,
                     *, allow_outside_range: bool = False,
                     transmission: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """tau = M alpha_ddot + c + g with the motors (eqs 24, 26 corrected, erratum 5), (..., N) N m,
    without forming M: the linkage's part per sample in O(N) (:func:`_inverse_pass`),
    the motors' I_a (R/r_d)^2 Z (Z^T alpha_ddot + Zdot^T alpha_dot).  alpha, alpha_dot,
    alpha_ddot (..., N) rad, rad/s, rad/s^2; ``transmission`` as in :func:`joint_dynamics`."""
    n = params.n_joints
    a = check_pose(alpha, params, allow_outside_range=allow_outside_range)
    a, ad, add = np.broadcast_arrays(a, check_alpha(alpha_dot, n, "alpha_dot"), check_alpha(alpha_ddot, n, "alpha_ddot"))
    batch, rows = a.shape[:-1], int(np.prod(a.shape[:-1]))
    tau = np.empty((rows, n))
    _inverse_rows(*(np.ascontiguousarray(x.reshape(rows, n)) for x in (a, ad, add)), linkage_constants(params), tau)
    Z, Zdot = transmission or transmission_terms(a, ad, params, allow_outside_range=True)
    zeta = np.einsum("...ij,...i->...j", Z, add) + np.einsum("...ij,...i->...j", Zdot, ad)
    motors = params.actuation.reflected_inertia * np.einsum("...ij,...j->...i", Z, zeta)
    return tau.reshape(batch + (n,)) + motors


def gravity_spring_torque(alpha: npt.ArrayLike, params: NeckParams, *, allow_outside_range: bool = False) -> np.ndarray:
    """g(alpha): gradient of the gravity and side-spring potential (eq 25), (..., N), N m."""
    a = check_pose(alpha, params, allow_outside_range=allow_outside_range)
    return linkage_dynamics(a, np.zeros_like(a), params, allow_outside_range=True).g


def potential_energy(alpha: npt.ArrayLike, params: NeckParams, *, allow_outside_range: bool = False) -> np.ndarray:
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


def kinetic_energy(alpha: npt.ArrayLike, alpha_dot: npt.ArrayLike, params: NeckParams, motors: bool = True, *,
                   allow_outside_range: bool = False) -> np.ndarray:
    """1/2 alpha_dot^T M alpha_dot (J)."""
    ad = np.asarray(alpha_dot, dtype=float)
    M = mass_matrix(alpha, params, motors, allow_outside_range=allow_outside_range)
    return 0.5 * np.einsum("...i,...ij,...j->...", ad, M, ad)


@dual
def arctan_friction(theta_dot: np.ndarray | float, c_s: np.ndarray | float,
                    f_s: np.ndarray | float) -> np.ndarray | float:
    """Arctan dry friction of eq (37), (2/pi) arctan(c_s theta_dot) f_s, as a force along the cable (N).

    theta_dot rad/s, c_s s/rad, f_s N; arrays broadcast (numpy) or scalars (compiled twin ``.jit``).
    """
    return (2 / np.pi) * np.arctan(c_s * theta_dot) * f_s


def motor_friction(theta_dot: npt.ArrayLike, params: NeckParams, f_s: npt.ArrayLike | None = None) -> np.ndarray:
    """Arctan dry friction at the motors, eq (37): (2/pi) arctan(c_s theta_dot) f_s, (..., m), N.

    Expressed as a force along the cable; ``f_s`` defaults to the plant's ``params.friction.f_s``.
    """
    fs = np.asarray(params.friction.f_s if f_s is None else f_s, dtype=float)
    return arctan_friction(np.asarray(theta_dot, dtype=float), params.friction.c_s, fs)


def rigid_acceleration(alpha: npt.ArrayLike, alpha_dot: npt.ArrayLike, f: npt.ArrayLike, params: NeckParams,
                       friction: bool = True, *, allow_outside_range: bool = False) -> np.ndarray:
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
    forces = np.asarray(f, dtype=float)
    if friction:
        theta_dot = (act.R / act.r_d) * np.einsum("...ij,...i->...j", ck.Z, ad)
        forces = forces - motor_friction(theta_dot, params)
    rhs = np.einsum("...ij,...j->...i", ck.Z, forces) - c - lk.g
    return np.linalg.solve(M, rhs[..., None])[..., 0]


class ElasticState(NamedTuple):
    """State of eqs (29)-(30): joint angles/speeds (..., N) and motor angles/speeds (..., m)."""

    alpha: np.ndarray
    alpha_dot: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray


def elastic_derivative(state: ElasticState, f: npt.ArrayLike, params: NeckParams, friction: bool = True, *,
                       allow_outside_range: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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


def simulate_elastic(alpha0: npt.ArrayLike, theta0: npt.ArrayLike, forces: Callable[[float], np.ndarray],
                     duration: float, params: NeckParams, *, sample_dt: float = 1e-3, friction: bool = True,
                     alpha_dot0: npt.ArrayLike | None = None, theta_dot0: npt.ArrayLike | None = None,
                     rtol: float = 1e-8, atol: float = 1e-10,
                     allow_outside_range: bool = False) -> tuple[np.ndarray, ElasticState]:
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


def simulate_rigid(alpha0: npt.ArrayLike, forces: Callable[[float], np.ndarray], duration: float, params: NeckParams,
                   *, sample_dt: float = 1e-3, friction: bool = True, alpha_dot0: npt.ArrayLike | None = None,
                   rtol: float = 1e-10, atol: float = 1e-12,
                   allow_outside_range: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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
