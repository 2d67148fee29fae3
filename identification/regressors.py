"""Observation matrices of the paper's identification models (eqs 43-47, 54-57), errata fixed.

Every model is a linear system W v + rho = Y (eq 48) stacked over the slow-grid samples of a
:class:`~identification.preprocessing.Prepared`.  Signs follow the convention of
:mod:`neck_sim.analytic.cables` (x_c > 0 stretched, Z^T alpha_dot = (r_d/R) theta_dot - x_c_dot),
so the corrected full model (eq 32) reads

    M alpha_ddot + c + g = Z (f - f_friction - I_a (R/r_d)^2 x_c_ddot),

the x_c term being the second derivative (erratum 4) with its sign flipped (erratum 6).  Any
routing: N joints and m cables (``params.n_cables``), Z (S, N, m); the paper's routing has m = N + 1.

Models
------
* ``friction_model`` -- friction alone, the paper's "model without cable elasticity" (eqs 46-47,
  Table 1 column 2): eq (38) with x_c = 0, i.e. rows Z diag(a) f_s = Z f - M alpha_ddot - c - g,
  a = (2/pi) arctan(c_s theta_dot).  As printed, eqs (46)-(47) would regress f - (R/r_d) I_a
  theta_ddot (= tension + friction) on diag(a) and fit the friction to the cable tension; the
  text ("model without cable elasticity", values within 2 % of column 1) describes eq (38).
* ``elastic_model`` -- eqs (44)-(45), v = (k, c_a, f_s): per sample m tension rows
  diag(x_c) k + diag(x_c_dot) c_a + diag(a) f_s = f - (R/r_d) I_a theta_ddot (eq 42), then N
  torque rows weighted by W (default 100): W Z diag(a) f_s = W (Z (f - I_a (R/r_d)^2 x_c_ddot)
  - M alpha_ddot - c - g).
* ``variable_stiffness_model`` -- eqs (54)-(57) with f_s fixed, v = (k, lambda, c_a): rows
  diag(x_c) k + diag(x_c t_c) lambda + diag(x_c_dot) c_a = t_c, t_c from eq (55).

Tension rows of a slack cable are left out (``taut`` masks): eq (39) describes a taut cable only.
A sample counts as slack for cable i when its tension from eq (41) is below a threshold or its
measured elongation is not positive; the mask is widened by a margin in time because filtering
smears the edges of a slack interval (``taut_samples``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from neck_sim.analytic import motor_friction
from neck_sim.analytic.cables import transmission_terms
from neck_sim.analytic.dynamics import JointDynamics, inverse_dynamics
from neck_sim.analytic.dynamics import joint_dynamics as analytic_joint_dynamics
from neck_sim.params import NeckParams

from identification.preprocessing import Prepared

__all__ = ["Regression", "Dynamics", "joint_dynamics", "Torques", "joint_torques", "friction_basis",
           "slow_friction_basis", "tension_from_forces",
           "taut_samples", "friction_model", "elastic_model", "variable_stiffness_model", "parameter_names"]


class Regression(NamedTuple):
    """Observation matrix W (r, p), observations Y (r,), parameter names and units (p,)."""

    W: np.ndarray
    Y: np.ndarray
    names: tuple
    units: tuple


#: Z (S, N, m) m, M (S, N, N) kg m^2 with motors, c (S, N) N m with motors, g (S, N) N m.
Dynamics = JointDynamics


def parameter_names(symbol: str, n_cables: int) -> tuple:
    """("k(1)", ..., "k(m)") -- the paper's labels, cables numbered in the routing's order."""
    return tuple(f"{symbol}({i + 1})" for i in range(n_cables))


_UNITS = {"k": "N/m", "c_a": "N s/m", "f_s": "N", "lambda": "1/m"}


def _names_units(symbols, n_cables):
    names = sum((parameter_names(s, n_cables) for s in symbols), ())
    units = sum(((_UNITS[s],) * n_cables for s in symbols), ())
    return names, units


class _Camera(NamedTuple):
    """The camera-derived signals of a :class:`Prepared` that has a camera, none of them None."""

    alpha: np.ndarray
    alpha_dot: np.ndarray
    alpha_ddot: np.ndarray
    x_c: np.ndarray
    x_c_dot: np.ndarray
    x_c_ddot: np.ndarray


def _need_camera(prep: Prepared, model: str) -> _Camera:
    a, ad, add, x, xd, xdd = prep.alpha, prep.alpha_dot, prep.alpha_ddot, prep.x_c, prep.x_c_dot, prep.x_c_ddot
    if a is None or ad is None or add is None or x is None or xd is None or xdd is None:
        raise ValueError(f"{model}: needs the joint angles of the camera topic (/neck/camera) for eq (27)'s "
                         f"elongations and the joint accelerations; this log has no camera frames")
    return _Camera(a, ad, add, x, xd, xdd)


def joint_dynamics(prep: Prepared, params: NeckParams) -> Dynamics:
    """Z, M, c, g (with the geared motors, eqs 24 and 26 corrected) at the camera's joint angles."""
    cam = _need_camera(prep, "joint dynamics")
    return analytic_joint_dynamics(cam.alpha, cam.alpha_dot, params, transmission=prep.transmission_for(params))


class Torques(NamedTuple):
    """Z (S, N, m) m and tau = M alpha_ddot + c + g (S, N) N m with the motors: all the torque rows
    read (the bootstrap's replicates use this, M never formed; the diagnosis needs :class:`Dynamics`)."""

    Z: np.ndarray
    tau: np.ndarray


def joint_torques(prep: Prepared, params: NeckParams) -> Torques:
    """Z and M alpha_ddot + c + g (eqs 24, 26 corrected) at the camera's joint angles, in O(N) per
    sample (:func:`neck_sim.analytic.dynamics.inverse_dynamics`); equal to :func:`joint_dynamics`'
    to rounding."""
    cam = _need_camera(prep, "joint torques")
    Z, Zdot = prep.transmission_for(params) or transmission_terms(cam.alpha, cam.alpha_dot, params)
    return Torques(Z, inverse_dynamics(cam.alpha, cam.alpha_dot, cam.alpha_ddot, params, transmission=(Z, Zdot)))


def friction_basis(theta_dot: npt.ArrayLike, params: NeckParams) -> np.ndarray:
    """a = (2/pi) arctan(c_s theta_dot), the eq (37) friction per unit f_s, (..., m)."""
    th = np.asarray(theta_dot, dtype=float)
    return motor_friction(th, params, f_s=np.ones(th.shape[-1]))


def slow_friction_basis(prep: Prepared, params: NeckParams) -> np.ndarray:
    """The eq (37) basis on the slow grid, (S, m): computed at the control rate from the encoders'
    speed and taken through the chain the forces took (``prep.chain``: parallel filtering, as the
    diagnosis does).  The arctan of the filtered slow-grid speed would differ from the filtered
    arctan wherever the speed oscillates faster than the common cutoff (the ringing of a neck with
    fewer cables than N + 1: f_s 6-8 % low on the 10-joint, 4-cable neck).  A ``Prepared`` without a
    chain (``excitation.prepared_from_prediction``, unfiltered) uses its slow-grid speed.

    The control-rate part (the arctan at every encoder sample, the low-pass and the decimation) is
    kept in ``prep``'s memo, which the camera-noise bootstrap's replicates share (their encoders
    are the log's): only the common bandwidth, which moves with a replicate's camera cutoff, is
    applied on every call."""
    chain, fast = prep.chain, prep.fast
    if chain is None or fast is None:
        return friction_basis(prep.theta_dot, params)
    c_s = np.asarray(params.friction.c_s, dtype=float)
    key = ("friction_basis", c_s.shape, c_s.tobytes(), chain.decimation_key())
    hit = prep._memo.get(key)
    if hit is None or hit[0] is not fast.theta_dot:
        if len(prep._memo) >= 16:
            prep._memo.clear()
        hit = (fast.theta_dot, chain.to_decimation(friction_basis(fast.theta_dot, params)))
        prep._memo[key] = hit
    return chain.after_decimation(hit[1])


def tension_from_forces(prep: Prepared, params: NeckParams, f_s: npt.ArrayLike) -> np.ndarray:
    """Cable tensions of eq (41)/(55): f - a f_s - (R/r_d) I_a theta_ddot, (S, m) N."""
    act = params.actuation
    return (prep.force - slow_friction_basis(prep, params) * np.asarray(f_s, dtype=float)
            - (act.R / act.r_d) * act.I_a * prep.theta_ddot)


def taut_samples(prep: Prepared, params: NeckParams, f_s: npt.ArrayLike, *, threshold: float = 2.0,
                 margin_s: float = 0.1) -> np.ndarray:
    """Mask (S, m), True where cable i is taut at sample s (see the module docstring).

    ``threshold`` N on the eq (41) tension with friction ``f_s``; ``margin_s`` s added on both
    sides of every slack interval.  Needs the camera for the elongation test.
    """
    cam = _need_camera(prep, "slack detection")
    slack = (tension_from_forces(prep, params, f_s) < threshold) | (cam.x_c <= 0)
    pad = int(np.ceil(margin_s * prep.rate_hz))
    if pad > 0 and slack.any():
        kernel = np.ones(2 * pad + 1)
        widened = np.stack([np.convolve(slack[:, i].astype(float), kernel, mode="same") > 0
                            for i in range(slack.shape[1])], axis=1)
        slack = widened
    return ~slack


def _diag_rows(cols: list[np.ndarray], taut: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Per-cable rows: for cable i, row [c1[:, i] e_i, c2[:, i] e_i, ...]; returns (W, cable index)."""
    S, C = cols[0].shape
    W = np.zeros((S, C, len(cols) * C))
    idx = np.arange(C)
    for b, col in enumerate(cols):
        W[:, idx, b * C + idx] = col
    keep = np.ones((S, C), bool) if taut is None else np.asarray(taut, bool)
    if keep.shape != (S, C):
        raise ValueError(f"taut: expected shape ({S}, {C}), got {keep.shape}")
    return W[keep], keep


def _torque_rows(prep: Prepared, params: NeckParams, dyn: Dynamics | Torques,
                 elastic: bool) -> tuple[np.ndarray, np.ndarray]:
    """(Z diag(a) (S*N, m), Z (f - I_a (R/r_d)^2 x_c_ddot) - M alpha_ddot - c - g (S*N,)); with
    :class:`Torques`, M alpha_ddot + c + g is its tau."""
    cam = _need_camera(prep, "joint torques")
    a = slow_friction_basis(prep, params)
    Za = dyn.Z * a[:, None, :]
    f = prep.force
    if elastic:
        f = f - params.actuation.reflected_inertia * cam.x_c_ddot
    if isinstance(dyn, Torques):
        y = np.einsum("sij,sj->si", dyn.Z, f) - dyn.tau
    else:
        y = (np.einsum("sij,sj->si", dyn.Z, f) - np.einsum("sij,sj->si", dyn.M, cam.alpha_ddot) - dyn.c - dyn.g)
    return Za.reshape(-1, Za.shape[2]), y.reshape(-1)


def friction_model(prep: Prepared, params: NeckParams, dyn: Dynamics | Torques | None = None) -> Regression:
    """Friction alone from the joint torques, rigid cables (eqs 46-47 as meant, eq 38 with x_c = 0)."""
    _need_camera(prep, "friction model (eqs 46-47)")
    dyn = dyn or joint_dynamics(prep, params)
    W, Y = _torque_rows(prep, params, dyn, elastic=False)
    names, units = _names_units(("f_s",), params.n_cables)
    return Regression(W, Y, names, units)


def elastic_model(prep: Prepared, params: NeckParams, *, weight: float = 100.0, taut: np.ndarray | None = None,
                  dyn: Dynamics | Torques | None = None) -> Regression:
    """Friction, linear stiffness and damping (eqs 44-45 corrected), v = (k, c_a, f_s)."""
    cam = _need_camera(prep, "elastic model (eqs 44-45)")
    if not (np.isfinite(weight) and weight > 0):
        raise ValueError(f"weight: must be positive, got {weight!r}")
    dyn = dyn or joint_dynamics(prep, params)
    act = params.actuation
    C = params.n_cables
    a = slow_friction_basis(prep, params)
    Wt, keep = _diag_rows([cam.x_c, cam.x_c_dot, a], taut)
    Yt = (prep.force - (act.R / act.r_d) * act.I_a * prep.theta_ddot)[keep]
    Za, yq = _torque_rows(prep, params, dyn, elastic=True)
    Wq = np.concatenate([np.zeros((Za.shape[0], 2 * C)), weight * Za], axis=1)
    names, units = _names_units(("k", "c_a", "f_s"), C)
    return Regression(np.concatenate([Wt, Wq]), np.concatenate([Yt, weight * yq]), names, units)


def variable_stiffness_model(prep: Prepared, params: NeckParams, f_s: npt.ArrayLike, *,
                             taut: np.ndarray | None = None) -> Regression:
    """Tension-dependent stiffness with friction fixed (eqs 54-57), v = (k, lambda, c_a)."""
    cam = _need_camera(prep, "variable-stiffness model (eqs 54-57)")
    t = tension_from_forces(prep, params, f_s)
    W, keep = _diag_rows([cam.x_c, cam.x_c * t, cam.x_c_dot], taut)
    names, units = _names_units(("k", "lambda", "c_a"), params.n_cables)
    return Regression(W, t[keep], names, units)
