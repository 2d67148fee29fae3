"""Cable lengths with pulleys, the transmission matrix Z and its time derivative (paper §3.1).

Routing (``shared/design/geometry-and-errata.md``): right cable j (j = 1..N) follows case (d)
(strut routed, eq 6) on joints 1..j-1 and case (b) (eq 4) on joint j, where it is attached at D_j;
the left cable N+1 follows case (c) (eq 5) on joints 1..N-1 and case (a) (eq 3) on joint N,
attached at C_N.  Errata fixed: eq (8) uses l_r (cable 1 is a right cable), eq (7) uses L.

Sign convention -- written here once, held by ``tests/test_conventions.py``:

* ``cable_lengths`` returns the variable part l_c(alpha) - l_c(0) (zero at the straight pose).
* Z_ij = -d l_cj / d alpha_i (eq 22): a cable that shortens as alpha_i grows has Z_ij > 0.
* theta_j > 0 winds cable j onto its drum; theta = 0 at the straight rest pose.
* Elongation (positive = stretched): ``x_c = l_c - l_c0 + (r_d/R) theta``, hence
  ``Z^T alpha_dot = (r_d/R) theta_dot - x_c_dot``.  This replaces eqs (27)/(28), which contradict
  eq (20); it flips the sign of every x_c-derivative term in eqs (31), (32), (34), (35), (38),
  (44), (51)-(53), (60), (61).  For rigid cables, theta = -(R/r_d)(l_c - l_c0), eq (20).
* Joint torques produced by cable tensions t (>= 0): tau = Z t (eq 30).
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import numpy as np

from neck_sim.analytic.geometry import _joint_local, _psi_derivatives, check_alpha, check_pose
from neck_sim.params import NeckParams

__all__ = ["cable_lengths", "transmission_matrix", "transmission_matrix_dot", "CableKinematics",
           "cable_kinematics", "elongation", "motor_angles_rigid"]


class _Segments(NamedTuple):
    """Per-joint variable lengths of the four routing cases, with d/dalpha and d2/dalpha2."""

    a: tuple  # case (a), left cable on its attaching joint
    b: tuple  # case (b), right cable on its attaching joint
    c: tuple  # case (c), left cable passing a joint
    d: tuple  # case (d), right cable passing a joint (strut routed)


def _segments(alpha: np.ndarray, b: float, L: float, r: float, orders=(0, 1, 2)) -> _Segments:
    """Segments for joint angles of any shape, for bars b, diagonals L and pulleys r (m).

    Only the derivative ``orders`` asked for are computed (the others are None): Z needs order 1
    alone, and skipping the corner geometry of order 2 makes it several times cheaper.
    """
    want = set(orders)
    half = alpha / 2
    s, c = np.sin(half), np.cos(half)
    q = np.sqrt(L * L - (b * c) ** 2)
    dq = (b * b / 2) * s * c / q
    l_l, l_r = q - b * s, q + b * s
    dl_l, dl_r = dq - (b / 2) * c, dq + (b / 2) * c
    t_l, t_r = np.sqrt(l_l * l_l - r * r), np.sqrt(l_r * l_r - r * r)
    if 2 in want:
        jl = _joint_local(alpha, b, L)
        ddl_l, ddl_r = jl.sides.ddl_l, jl.sides.ddl_r
    seg = {}
    # Tangent from a pulley of radius r to the attachment point at distance l, eqs (3), (4);
    # sign -1 for case (a) (left cable, clockwise), +1 for case (b) (right cable).
    for name, l, dl, t, sign in (("a", l_l, dl_l, t_l, -1.0), ("b", l_r, dl_r, t_r, 1.0)):
        val = t - r * np.arctan2(t, r) + sign * r * half if 0 in want else None
        d1 = dl * t / l + sign * r / 2 if 1 in want else None
        d2 = None
        if 2 in want:
            ddl = ddl_l if name == "a" else ddl_r
            d2 = ddl * t / l + (dl * r) ** 2 / (t * l * l) if r > 0 else ddl
        seg[name] = (val, d1, d2)
    seg["c"] = (l_l - r * alpha if 0 in want else None, dl_l - r if 1 in want else None,
                ddl_l if 2 in want else None)
    # psi = angle of B->C (eq 7 by atan2); psi' from the rod B->C of constant length L.
    psi_ = np.arctan2(l_l * c, -b - l_l * s) if 0 in want else None
    dpsi = (0.5 * l_l * l_l + 0.5 * b * l_l * s - b * c * dl_l) / (L * L) if 1 in want else None
    ddpsi = _psi_derivatives(jl, b, L)[1] if 2 in want else None
    seg["d"] = (r * (2 * psi_ - alpha) if 0 in want else None, r * (2 * dpsi - 1) if 1 in want else None,
                2 * r * ddpsi if 2 in want else None)
    return _Segments(seg["a"], seg["b"], seg["c"], seg["d"])


def _geom(params: NeckParams) -> tuple[float, float, float]:
    g = params.geometry
    return g.b, g.L, g.r


def _assemble_lengths(seg: _Segments, n: int) -> np.ndarray:
    d_val = seg.d[0]
    passed = np.cumsum(d_val, axis=-1) - d_val            # sum over joints i < j of case (d)
    right = passed + seg.b[0]
    left = np.sum(seg.c[0][..., : n - 1], axis=-1) + seg.a[0][..., n - 1]
    return np.concatenate([right, left[..., None]], axis=-1)


@functools.lru_cache(maxsize=None)
def _z_indices(n: int):
    """(rows, cols) of joints i passed by right cables j > i, and the diagonal indices."""
    rows, cols = np.triu_indices(n, 1)
    return rows, cols, np.arange(n)


def _assemble_z(seg: _Segments, n: int, order: int) -> np.ndarray:
    """-(d^order l_c / d alpha^order) arranged as an (..., N, N+1) matrix (order 1 or 2)."""
    dd, db, dc, da = seg.d[order], seg.b[order], seg.c[order], seg.a[order]
    out = np.zeros(db.shape[:-1] + (n, n + 1))
    rows, cols, idx = _z_indices(n)
    out[..., rows, cols] = -dd[..., rows]
    out[..., idx, idx] = -db
    out[..., : n - 1, n] = -dc[..., : n - 1]
    out[..., n - 1, n] = -da[..., n - 1]
    return out


def cable_lengths(alpha, params: NeckParams, *, allow_outside_range: bool = False) -> np.ndarray:
    """Variable cable lengths l_c(alpha) - l_c(0) (eqs 3-19 for N joints), shape (..., N+1), m."""
    n = params.n_joints
    a = check_pose(alpha, params, allow_outside_range=allow_outside_range)
    zero = _assemble_lengths(_segments(np.zeros(n), *_geom(params), orders=(0,)), n)
    return _assemble_lengths(_segments(a, *_geom(params), orders=(0,)), n) - zero


def transmission_matrix(alpha, params: NeckParams, *, allow_outside_range: bool = False) -> np.ndarray:
    """Z(alpha) = -d l_c / d alpha (eqs 22, 23), closed form, shape (..., N, N+1), m."""
    n = params.n_joints
    a = check_pose(alpha, params, allow_outside_range=allow_outside_range)
    return _assemble_z(_segments(a, *_geom(params), orders=(1,)), n, 1)


def transmission_matrix_dot(alpha, alpha_dot, params: NeckParams, *, allow_outside_range: bool = False) -> np.ndarray:
    """dZ/dt for joint velocities alpha_dot (rad/s), shape (..., N, N+1), m/s.

    Column j of Z depends on alpha_i only through row i, so Zdot_ij = (dZ_ij/dalpha_i) alpha_dot_i.
    """
    n = params.n_joints
    a = check_pose(alpha, params, allow_outside_range=allow_outside_range)
    ad = check_alpha(alpha_dot, n, "alpha_dot")
    return _assemble_z(_segments(a, *_geom(params), orders=(2,)), n, 2) * ad[..., :, None]


class CableKinematics(NamedTuple):
    lengths: np.ndarray  # (..., N+1) l_c - l_c0, m
    Z: np.ndarray        # (..., N, N+1), m
    Zdot: np.ndarray     # (..., N, N+1), m/s


def cable_kinematics(alpha, alpha_dot, params: NeckParams, *, allow_outside_range: bool = False) -> CableKinematics:
    """Lengths, Z and Zdot in one pass (what a dynamics step needs)."""
    n = params.n_joints
    a = check_pose(alpha, params, allow_outside_range=allow_outside_range)
    ad = check_alpha(alpha_dot, n, "alpha_dot")
    seg = _segments(a, *_geom(params))
    zero = _assemble_lengths(_segments(np.zeros(n), *_geom(params), orders=(0,)), n)
    return CableKinematics(_assemble_lengths(seg, n) - zero, _assemble_z(seg, n, 1),
                           _assemble_z(seg, n, 2) * ad[..., :, None])


def elongation(theta, alpha, params: NeckParams, *, allow_outside_range: bool = False) -> np.ndarray:
    """Cable elongation x_c = l_c - l_c0 + (r_d/R) theta (corrected eq 27), shape (..., N+1), m."""
    a = params.actuation
    return (cable_lengths(alpha, params, allow_outside_range=allow_outside_range)
            + (a.r_d / a.R) * np.asarray(theta, dtype=float))


def motor_angles_rigid(alpha, params: NeckParams, elongation=None, *, allow_outside_range: bool = False) -> np.ndarray:
    """Motor angles theta = (R/r_d)(x_c - (l_c - l_c0)) (eq 20 when x_c = 0), shape (..., N+1), rad."""
    a = params.actuation
    x = 0.0 if elongation is None else np.asarray(elongation, dtype=float)
    return (a.R / a.r_d) * (x - cable_lengths(alpha, params, allow_outside_range=allow_outside_range))
