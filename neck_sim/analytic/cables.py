"""Cable lengths with pulleys, the transmission matrix Z and its time derivative (paper §3.1).

Routing is data (:class:`neck_sim.routing.Routing`, m cables for N joints): on every joint a cable
follows one segment kind -- the paper's cases (a) eq (3), (b) eq (4), (c) eq (5), (d) eq (6) or the
mirror images c'(alpha) = c(-alpha) = l_r + r alpha (right cable up the right side) and
d'(alpha) = d(-alpha) (left cable crossing along the diagonal A->D); note b(alpha) = a(-alpha).
A cable's length is the sum of its segments, so every segment kind is evaluated per joint into
an array seg[..., K, N] and gathered with the routing's ``segment_cases`` (m, N):
``l_j = sum_i seg[case[j, i], i]`` and ``Z_ij = -dseg[case[j, i], i]``.  The paper's routing
(the default, design notes): right cable j (j = 1..N) case (d) on joints 1..j-1 and (b) on joint
j, attached at D_j; the left cable N+1 case (c) on joints 1..N-1 and (a) on joint N, attached at
C_N.  Errata fixed: eq (8) uses l_r (cable 1 is a right cable), eq (7) uses L.

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
import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import numpy.typing as npt

from neck_sim.analytic.geometry import (_corner_terms, _psi_derivatives, _side_terms, check_alpha, check_pose,
                                        corner_terms_kernel, side_terms_kernel)
from neck_sim.jit import dual, kernel
from neck_sim.params import NeckParams
from neck_sim.routing import (N_SEGMENT_KINDS, SEG_LEFT_END, SEG_LEFT_SIDE, SEG_LEFT_STRUT, SEG_RIGHT_END,
                              SEG_RIGHT_SIDE, SEG_RIGHT_STRUT)

if TYPE_CHECKING:
    from neck_sim.params import Routing

__all__ = ["cable_lengths", "transmission_matrix", "transmission_matrix_dot", "transmission_terms", "transmission_kernel",
           "CableKinematics", "cable_kinematics", "elongation", "motor_angles_rigid"]


@dual
def _segment_slopes(alpha, b, L, r, sides):
    """First alpha-derivatives of the six segment kinds (``SEG_*`` codes 1..6, in that order), m/rad.

    ``sides`` is :func:`neck_sim.analytic.geometry._side_terms` of the same angles; arrays (numpy)
    or one joint's scalars (compiled twin).  psi' of eq (7) comes from the rod B->C of constant
    length L; the mirrors are c'(alpha) = c(-alpha), d'(alpha) = d(-alpha).
    """
    s, c = np.sin(alpha / 2), np.cos(alpha / 2)
    l_l, dl_l, l_r, dl_r = sides[0], sides[1], sides[3], sides[4]
    t_l, t_r = np.sqrt(l_l * l_l - r * r), np.sqrt(l_r * l_r - r * r)
    return (dl_l * t_l / l_l - r / 2,                                                   # (a), eq (3)
            dl_r * t_r / l_r + r / 2,                                                   # (b), eq (4)
            dl_l - r,                                                                   # (c), eq (5)
            r * (2 * (0.5 * l_l * l_l + 0.5 * b * l_l * s - b * c * dl_l) / (L * L) - 1),  # (d), eq (6)
            dl_r + r,                                                                   # mirror of (c)
            r * (1 - 2 * (0.5 * l_r * l_r - 0.5 * b * l_r * s + b * c * dl_r) / (L * L)))  # mirror of (d)


_slopes_kernel = _segment_slopes.jit
if (SEG_LEFT_END, SEG_RIGHT_END, SEG_LEFT_SIDE, SEG_RIGHT_STRUT, SEG_RIGHT_SIDE, SEG_LEFT_STRUT) != (1, 2, 3, 4, 5, 6):
    raise ImportError("neck_sim.params: segment codes changed; update _segment_slopes' order")


@kernel
def transmission_kernel(alpha: np.ndarray, geometry: np.ndarray, cases: np.ndarray, Z: np.ndarray) -> None:
    """Z (N, m) of one pose alpha (N,) into ``Z``: geometry = (b, L, r) m, cases (m, N) the
    routing's ``segment_cases``; the same slopes and gather as :func:`transmission_matrix`."""
    b, L, r = geometry[0], geometry[1], geometry[2]
    slope = np.zeros(N_SEGMENT_KINDS)
    for i in range(alpha.shape[0]):
        sl = _slopes_kernel(alpha[i], b, L, r, side_terms_kernel(alpha[i], b, L))
        for kind in range(N_SEGMENT_KINDS - 1):
            slope[kind + 1] = sl[kind]
        for j in range(cases.shape[0]):
            Z[i, j] = -slope[cases[j, i]]


def _segments(alpha: np.ndarray, b: float, L: float, r: float, orders=(0, 1, 2),
              left_strut: bool = True, jl=None, strut_joints: np.ndarray | None = None) -> dict:
    """Per-joint variable length of every segment kind, order -> array (..., K, N) (K kinds).

    Row k holds kind k of :mod:`neck_sim.params` (``SEG_*``; row 0, "not on this joint", is
    zero); order 0 is the length (m), 1 and 2 its first two alpha-derivatives.  Only the
    ``orders`` asked for are computed: Z needs order 1 alone, and skipping the corner geometry
    of order 2 makes it several times cheaper; ``left_strut=False`` skips the mirror of case (d);
    ``jl``: :func:`~neck_sim.analytic.geometry._joint_local` of the same ``alpha``, when the caller
    has it (the statics' Hessian needs the same corners); ``strut_joints``: the joints whose mirror
    of case (d) is read (None: all), the others' second derivative of it left 0.
    """
    want = set(orders)
    if want == {1} and jl is None:
        # Z alone (the estimator's step, the control path): the slopes, the same rows as below,
        # none of the lengths' half-angle sines and tangents
        slopes = _segment_slopes(alpha, b, L, r, _side_terms(alpha, b, L))
        out1 = np.zeros(alpha.shape[:-1] + (N_SEGMENT_KINDS, alpha.shape[-1]))
        for kind in range(1, SEG_LEFT_STRUT + 1 if left_strut else SEG_LEFT_STRUT):
            out1[..., kind, :] = slopes[kind - 1]
        return {1: out1}
    half = alpha / 2
    s, c = np.sin(half), np.cos(half)
    sides = _side_terms(alpha, b, L) if jl is None else tuple(jl.sides)
    l_l, dl_l, ddl_l, l_r, dl_r, ddl_r = sides
    t_l, t_r = np.sqrt(l_l * l_l - r * r), np.sqrt(l_r * l_r - r * r)
    out = {k: np.zeros(alpha.shape[:-1] + (N_SEGMENT_KINDS, alpha.shape[-1])) for k in want}
    slopes = _segment_slopes(alpha, b, L, r, sides) if 1 in want else None

    def put(kind, val, d1, d2):
        for order, v in ((0, val), (2, d2)):
            if order in want:
                out[order][..., kind, :] = v()
        if 1 in want:
            out[1][..., kind, :] = slopes[kind - 1]

    # Tangent from a pulley of radius r to the attachment point at distance l, eqs (3), (4);
    # sign -1 for case (a) (left cable, clockwise), +1 for case (b) (right cable) = (a) mirrored.
    for kind, l, dl, t, sign in ((SEG_LEFT_END, l_l, dl_l, t_l, -1.0), (SEG_RIGHT_END, l_r, dl_r, t_r, 1.0)):
        ddl = ddl_l if kind == SEG_LEFT_END else ddl_r
        put(kind, lambda: t - r * np.arctan2(t, r) + sign * r * half, None,
            lambda: ddl * t / l + (dl * r) ** 2 / (t * l * l) if r > 0 else ddl)
    # Case (c), eq (5), and its mirror c'(alpha) = c(-alpha) = l_r + r alpha (the extra full turn
    # on the top pulley keeps the cable on it; it adds a constant only).
    put(SEG_LEFT_SIDE, lambda: l_l - r * alpha, None, lambda: ddl_l)
    put(SEG_RIGHT_SIDE, lambda: l_r + r * alpha, None, lambda: ddl_r)
    # Case (d), eq (6): psi = angle of B->C (eq 7 by atan2); psi' from the rod B->C of constant
    # length L.  Its mirror d'(alpha) = d(-alpha), with psi(-alpha) = atan2(l_r c, l_r s - b).
    ddpsi: np.ndarray | float = 0.0                                   # read only for order 2
    if 2 in want:
        ddpsi = _psi_second(alpha, b, L, sides) if jl is None else _psi_derivatives(jl, b, L)[1]
    put(SEG_RIGHT_STRUT, lambda: r * (2 * np.arctan2(l_l * c, -b - l_l * s) - alpha), None, lambda: 2 * r * ddpsi)
    if left_strut:
        ddpsi_m = _mirror_psi_second(alpha, b, L, strut_joints) if 2 in want else 0.0
        put(SEG_LEFT_STRUT, lambda: r * (2 * np.arctan2(l_r * c, l_r * s - b) + alpha), None, lambda: 2 * r * ddpsi_m)
    return out


def _psi_second(a: np.ndarray, b: float, L: float, sides: tuple) -> np.ndarray:
    """psi'' of :func:`~neck_sim.analytic.geometry._psi_derivatives` (the rod B->C of constant
    length L) from the corner terms as computed, not stacked into points: the same products."""
    k = _corner_terms(a, b, L, sides)
    cx, cy, ddcx, ddcy = k[0], k[1], k[4], k[5]
    return ((cx - b / 2) * ddcy - (cy - 0.0) * ddcx) / (L * L)


def _mirror_psi_second(alpha: np.ndarray, b: float, L: float, joints: np.ndarray | None) -> np.ndarray:
    """psi''(-alpha) (the mirror of case (d)) on ``joints`` (None: all), 0 on the others: a routing
    takes the mirror on a few joints (the 10-joint, 4-cable neck's left cable on 5 of 10)."""
    if joints is None or joints.size == alpha.shape[-1]:
        return _psi_second(-alpha, b, L, _side_terms(-alpha, b, L))
    am = -alpha[..., joints]
    out = np.zeros(alpha.shape)
    out[..., joints] = _psi_second(am, b, L, _side_terms(am, b, L))
    return out


def _geom(params: NeckParams) -> tuple[float, float, float]:
    g = params.geometry
    return g.b, g.L, g.r


def _cases(params: NeckParams) -> np.ndarray:
    """Segment kind of every (cable j, joint i), (m, N) int (:meth:`Routing.segment_cases`)."""
    return _routing_terms(params)[0]


def _gather(seg: np.ndarray, cases: np.ndarray) -> np.ndarray:
    """seg[..., cases[j, i], i] arranged as (..., m, N)."""
    return seg[..., cases, np.arange(cases.shape[1])]


def _evaluate(alpha: np.ndarray, params: NeckParams, orders, jl=None) -> dict:
    cases, _, left_strut = _routing_terms(params)
    joints = np.nonzero(np.any(cases == SEG_LEFT_STRUT, axis=0))[0] if left_strut and 2 in orders else None
    return _segments(alpha, *_geom(params), orders=orders, left_strut=left_strut, jl=jl, strut_joints=joints)


def _lengths(alpha: np.ndarray, params: NeckParams, seg0: np.ndarray) -> np.ndarray:
    """Sum of the cables' segments minus their value at the straight pose, (..., m)."""
    cases, straight, _ = _routing_terms(params)
    return _gather(seg0, cases).sum(axis=-1) - straight


# (id(routing), N, b, L, r) -> (routing, its terms): a Routing's dataclass hash walks every cable's
# tuples, which cost more than the 10-joint control step's cable geometry itself at every call.
# The routing object is kept with its entry, so its id cannot be reused while the entry lives.
_BY_ROUTING: dict = {}


def _routing_terms(params: NeckParams) -> tuple[np.ndarray, np.ndarray, bool]:
    """(segment cases (m, N), :func:`_straight_sums` (m,) m, whether a cable takes the mirror of
    case (d)) of ``params``' routing and geometry, computed once per routing object."""
    routing, n = params.routing, params.n_joints
    geom = _geom(params)
    key = (id(routing), n) + geom
    hit = _BY_ROUTING.get(key)
    if hit is not None and hit[0] is routing:
        return hit[1]
    cases = routing.segment_cases(n)
    terms = (cases, _straight_sums(*geom, routing, n), bool(np.any(cases == SEG_LEFT_STRUT)))
    if len(_BY_ROUTING) >= 256:
        _BY_ROUTING.clear()
    _BY_ROUTING[key] = (routing, terms)
    return terms


@functools.lru_cache(maxsize=256)
def _straight_sums(b: float, L: float, r: float, routing: "Routing", n_joints: int) -> np.ndarray:
    """Sum of each cable's segments at the straight pose, (m,) m (read-only): what every length
    is measured from, the same for every pose of a neck, so computed once per geometry and routing."""
    cases = routing.segment_cases(n_joints)
    zero = _segments(np.zeros(n_joints), b, L, r, orders=(0,), left_strut=bool(np.any(cases == SEG_LEFT_STRUT)))[0]
    out = _gather(zero, cases).sum(axis=-1)
    out.setflags(write=False)
    return out


def _z(seg: np.ndarray, params: NeckParams) -> np.ndarray:
    """-(segment derivative) arranged as an (..., N, m) matrix."""
    return -np.swapaxes(_gather(seg, _cases(params)), -1, -2)


def cable_lengths(alpha: npt.ArrayLike, params: NeckParams, *, allow_outside_range: bool = False) -> np.ndarray:
    """Variable cable lengths l_c(alpha) - l_c(0) (eqs 3-19 for any routing), shape (..., m), m."""
    a = check_pose(alpha, params, allow_outside_range=allow_outside_range)
    return _lengths(a, params, _evaluate(a, params, (0,))[0])


def transmission_matrix(alpha: npt.ArrayLike, params: NeckParams, *, allow_outside_range: bool = False) -> np.ndarray:
    """Z(alpha) = -d l_c / d alpha (eqs 22, 23), closed form, shape (..., N, m), m."""
    a = check_pose(alpha, params, allow_outside_range=allow_outside_range)
    return _z(_evaluate(a, params, (1,))[1], params)


def transmission_matrix_dot(alpha: npt.ArrayLike, alpha_dot: npt.ArrayLike, params: NeckParams, *,
                            allow_outside_range: bool = False) -> np.ndarray:
    """dZ/dt for joint velocities alpha_dot (rad/s), shape (..., N, m), m/s.

    Column j of Z depends on alpha_i only through row i, so Zdot_ij = (dZ_ij/dalpha_i) alpha_dot_i.
    """
    n = params.n_joints
    a = check_pose(alpha, params, allow_outside_range=allow_outside_range)
    ad = check_alpha(alpha_dot, n, "alpha_dot")
    return _z(_evaluate(a, params, (2,))[2], params) * ad[..., :, None]


class CableKinematics(NamedTuple):
    lengths: np.ndarray  # (..., m) l_c - l_c0, m
    Z: np.ndarray        # (..., N, m), m
    Zdot: np.ndarray     # (..., N, m), m/s


def cable_kinematics(alpha: npt.ArrayLike, alpha_dot: npt.ArrayLike, params: NeckParams, *,
                     allow_outside_range: bool = False) -> CableKinematics:
    """Lengths, Z and Zdot in one pass (what a dynamics step needs).

    A series of poses (alpha, alpha_dot (S, N)) runs :func:`_kinematics_rows`, one compiled
    pass over the samples that evaluates only the segment kinds the routing puts on each joint (a
    camera-noise bootstrap replicate of the 10-joint neck evaluates these at every sample); the
    numbers are those of the segment arrays below, bit for bit."""
    n = params.n_joints
    a = check_pose(alpha, params, allow_outside_range=allow_outside_range)
    ad = check_alpha(alpha_dot, n, "alpha_dot")
    if a.ndim == 2 and ad.shape == a.shape:
        return _batched_kinematics(a, ad, params)
    seg = _evaluate(a, params, (0, 1, 2))
    return CableKinematics(_lengths(a, params, seg[0]), *_z_and_dot(seg, ad, params))


def _batched_kinematics(a: np.ndarray, ad: np.ndarray, params: NeckParams) -> CableKinematics:
    """:func:`cable_kinematics` of poses a (S, N) by :func:`_kinematics_rows`."""
    cases, straight, _ = _routing_terms(params)
    (m, n), rows = cases.shape, a.shape[0]
    used = np.zeros((N_SEGMENT_KINDS, n), np.bool_)
    used[cases, np.arange(n)] = True
    # laid out as numpy laid out the gathered segments' sums, negations and products (samples
    # innermost): Z, Zdot come out with the strides the products downstream (M's Z Z^T, the torque
    # rows' einsums) saw before
    lengths, Z, Zdot = np.empty((m, rows)), np.empty((m, n, rows)), np.empty((m, rows, n))
    b, L, r = _geom(params)
    # b ** 4 as Python computes it (the numpy formula's power of a scalar), passed in
    _kinematics_rows(np.ascontiguousarray(a), np.ascontiguousarray(ad), np.array([b, L, r, b ** 4]),
                     np.ascontiguousarray(cases), used, straight, lengths, Z, Zdot)
    return CableKinematics(lengths.T, Z.transpose(2, 1, 0), Zdot.transpose(1, 2, 0))


@kernel
def _side_second(a, b, L, b4):      # pragma: no cover  (compiled)
    # ddl_l, ddl_r of _side_terms with numpy's arithmetic: q ** 3 of an array is pow(q, 3.0) and
    # b ** 4 Python's pow, where the compiled twin multiplies (an ulp apart at 6 % of the angles)
    s, c = np.sin(a / 2), np.cos(a / 2)
    q = np.sqrt(L * L - (b * c) * (b * c))
    u = 0.5 * np.sin(a)
    ddq = b * b * np.cos(a) / (4 * q) - b4 * u * u / (4 * math.pow(q, 3.0))
    return ddq + b * s / 4, ddq - b * s / 4


@kernel
def _psi_second_kernel(a, b, L, sides):      # pragma: no cover  (compiled)
    # _psi_second of one angle, ``sides`` its side terms with _side_second's second derivatives
    k = corner_terms_kernel(a, b, L, sides)
    return ((k[0] - b / 2) * k[5] - (k[1] - 0.0) * k[4]) / (L * L)


@kernel
def _kinematics_rows(alpha, alpha_dot, geometry, cases, used, straight, lengths, Z, Zdot):      # pragma: no cover
    # per sample and joint: the segment kinds ``used`` (K, N) there, each by _segments' formula
    # and operation order (orders 0 and 2; order 1 is _segment_slopes' twin), gathered by the
    # routing's cases (m, N): their sum over the joints in order minus ``straight`` (m,) into
    # lengths (m, R), -(order 1) into Z (m, N, R) and -(order 2) alpha_dot into Zdot (m, R, N),
    # each the operation numpy applied to the gathered arrays
    b, L, r, b4 = geometry[0], geometry[1], geometry[2], geometry[3]
    K = used.shape[0]
    v0 = np.zeros(K)
    v1 = np.zeros(K)
    v2 = np.zeros(K)
    for row in range(alpha.shape[0]):
        for i in range(alpha.shape[1]):
            a = alpha[row, i]
            half = a / 2
            s, c = np.sin(half), np.cos(half)
            sd = side_terms_kernel(a, b, L)
            ddl_l, ddl_r = _side_second(a, b, L, b4)
            l_l, dl_l, l_r, dl_r = sd[0], sd[1], sd[3], sd[4]
            t_l, t_r = np.sqrt(l_l * l_l - r * r), np.sqrt(l_r * l_r - r * r)
            sl = _slopes_kernel(a, b, L, r, sd)
            for kind in range(1, K):
                v1[kind] = sl[kind - 1]
            if used[SEG_LEFT_END, i]:
                v0[SEG_LEFT_END] = t_l - r * np.arctan2(t_l, r) + -1.0 * r * half
                q = dl_l * r
                v2[SEG_LEFT_END] = ddl_l * t_l / l_l + q * q / (t_l * l_l * l_l) if r > 0 else ddl_l
            if used[SEG_RIGHT_END, i]:
                v0[SEG_RIGHT_END] = t_r - r * np.arctan2(t_r, r) + 1.0 * r * half
                q = dl_r * r
                v2[SEG_RIGHT_END] = ddl_r * t_r / l_r + q * q / (t_r * l_r * l_r) if r > 0 else ddl_r
            v0[SEG_LEFT_SIDE] = l_l - r * a
            v2[SEG_LEFT_SIDE] = ddl_l
            v0[SEG_RIGHT_SIDE] = l_r + r * a
            v2[SEG_RIGHT_SIDE] = ddl_r
            if used[SEG_RIGHT_STRUT, i]:
                v0[SEG_RIGHT_STRUT] = r * (2 * np.arctan2(l_l * c, -b - l_l * s) - a)
                v2[SEG_RIGHT_STRUT] = 2 * r * _psi_second_kernel(a, b, L, (l_l, dl_l, ddl_l, l_r, dl_r, ddl_r))
            if used[SEG_LEFT_STRUT, i]:
                v0[SEG_LEFT_STRUT] = r * (2 * np.arctan2(l_r * c, l_r * s - b) + a)
                sm = side_terms_kernel(-a, b, L)
                ddm_l, ddm_r = _side_second(-a, b, L, b4)
                v2[SEG_LEFT_STRUT] = 2 * r * _psi_second_kernel(-a, b, L, (sm[0], sm[1], ddm_l, sm[3], sm[4], ddm_r))
            for j in range(cases.shape[0]):
                kind = cases[j, i]
                if i == 0:
                    lengths[j, row] = v0[kind]
                else:
                    lengths[j, row] += v0[kind]
                Z[j, i, row] = -v1[kind]
                Zdot[j, row, i] = -v2[kind] * alpha_dot[row, i]
        for j in range(cases.shape[0]):
            lengths[j, row] -= straight[j]


def transmission_terms(alpha: npt.ArrayLike, alpha_dot: npt.ArrayLike, params: NeckParams, *,
                       allow_outside_range: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(Z (..., N, m) m, Zdot (..., N, m) m/s) of :func:`cable_kinematics` without the lengths
    (the same arrays, bit for bit; the lengths' segment values cost a third of the pass)."""
    a = check_pose(alpha, params, allow_outside_range=allow_outside_range)
    ad = check_alpha(alpha_dot, params.n_joints, "alpha_dot")
    return _z_and_dot(_evaluate(a, params, (1, 2)), ad, params)


def _z_and_dot(seg: dict, ad: np.ndarray, params: NeckParams) -> tuple[np.ndarray, np.ndarray]:
    """Z and Zdot from the segments' first and second derivatives (``_evaluate`` orders 1, 2)."""
    return _z(seg[1], params), _z(seg[2], params) * ad[..., :, None]


def elongation(theta: npt.ArrayLike, alpha: npt.ArrayLike, params: NeckParams, *,
               allow_outside_range: bool = False, lengths: np.ndarray | None = None) -> np.ndarray:
    """Cable elongation x_c = l_c - l_c0 + (r_d/R) theta (corrected eq 27), shape (..., m), m.

    ``lengths``: :func:`cable_lengths` of ``alpha`` when the caller has them (``cable_kinematics``)."""
    a = params.actuation
    if lengths is None:
        lengths = cable_lengths(alpha, params, allow_outside_range=allow_outside_range)
    return lengths + (a.r_d / a.R) * np.asarray(theta, dtype=float)


def motor_angles_rigid(alpha: npt.ArrayLike, params: NeckParams, elongation: npt.ArrayLike | None = None, *,
                       allow_outside_range: bool = False) -> np.ndarray:
    """Motor angles theta = (R/r_d)(x_c - (l_c - l_c0)) (eq 20 when x_c = 0), shape (..., m), rad."""
    a = params.actuation
    x = 0.0 if elongation is None else np.asarray(elongation, dtype=float)
    return (a.R / a.r_d) * (x - cable_lengths(alpha, params, allow_outside_range=allow_outside_range))
