"""X-joint geometry and forward kinematics of the N-joint chain (paper §2.1, eqs 1, 2, 7).

Conventions (held by tests, see ``docs/geometry-and-errata.md``):

* One X-joint in its base-bar frame: x along A->B, y up, origin at the middle of AB,
  ``A = (-b/2, 0)``, ``B = (b/2, 0)``, ``C = A + l_l (-sin(a/2), cos(a/2))``,
  ``D = C + b (cos a, sin a)``.  Diagonals AD and BC have length L; springs lie on AC (left side,
  length l_l) and BD (right side, length l_r).
* alpha > 0 is counter-clockwise: the neck bends to the left, the right side gets longer.
* The top bar CD of joint i is the base bar of joint i+1: frame i+1 has its origin at the middle
  of CD and is rotated by alpha_i.  Frame 1 is the ground; gravity acts along -y.

All functions broadcast over leading batch axes; angles in rad, lengths in m.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from neck_sim.jit import dual
from neck_sim.params import NeckParams

__all__ = ["SideLengths", "side_lengths", "joint_corners", "psi", "Kinematics",
           "forward_kinematics", "rotation", "PoseRangeError", "check_alpha", "check_pose", "check_cables"]


class SideLengths(NamedTuple):
    """Side lengths of eqs (1), (2) and their first two derivatives with respect to alpha."""

    l_l: np.ndarray
    dl_l: np.ndarray
    ddl_l: np.ndarray
    l_r: np.ndarray
    dl_r: np.ndarray
    ddl_r: np.ndarray


def _check_last_axis(arr, size: int, name: str, what: str) -> np.ndarray:
    a = np.asarray(arr, dtype=float)
    if a.ndim == 0 or a.shape[-1] != size:
        raise ValueError(f"{name}: expected shape (..., {size}) ({what}), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: contains NaN or infinity")
    return a


class PoseRangeError(ValueError):
    """Joint angles outside |alpha| <= ``geometry.alpha_max``, where the model is not valid.

    ``problem`` is the message without the advice to Python callers (the command line words its own).
    """

    def __init__(self, problem: str) -> None:
        super().__init__(f"{problem}; pass allow_outside_range=True to evaluate the model there")
        self.problem = problem

    def __reduce__(self):          # rebuilt from the problem alone (other processes, pickling)
        return type(self), (self.problem,)


def check_alpha(alpha: npt.ArrayLike, n_joints: int, name: str = "alpha", alpha_max: float | None = None) -> np.ndarray:
    """Return ``alpha`` as a float array of shape (..., n_joints) or raise naming the problem.

    With ``alpha_max`` (rad), angles beyond |alpha| <= alpha_max raise :class:`PoseRangeError`.
    """
    a = _check_last_axis(alpha, n_joints, name, "one angle per X-joint")
    if alpha_max is not None and not np.all(np.abs(a) <= alpha_max):
        idx = tuple(int(i) for i in np.argwhere(np.abs(a) > alpha_max)[0])
        raise PoseRangeError(
            f"{name}: joint {idx[-1] + 1} at {np.degrees(a[idx]):.2f} deg (index {idx}) is outside the joint "
            f"range |alpha| <= {np.degrees(alpha_max):.2f} deg (geometry.alpha_max)")
    return a


def check_pose(alpha: npt.ArrayLike, params: NeckParams, name: str = "alpha",
               allow_outside_range: bool = False) -> np.ndarray:
    """:func:`check_alpha` against the neck's joint range, unless ``allow_outside_range``."""
    return check_alpha(alpha, params.n_joints, name, None if allow_outside_range else params.geometry.alpha_max)


def check_cables(values: npt.ArrayLike, n_cables: int, name: str) -> np.ndarray:
    """Return a per-cable array of shape (..., n_cables) or raise naming the problem."""
    return _check_last_axis(values, n_cables, name, "one value per cable")


def side_lengths(alpha: npt.ArrayLike, params: NeckParams) -> SideLengths:
    """Left and right side lengths l_l, l_r (eqs 1, 2) and d/dalpha, d2/dalpha2; shape of ``alpha``."""
    g = params.geometry
    return _sides(np.asarray(alpha, dtype=float), g.b, g.L)


@dual
def _side_terms(a, b, L):
    """(l_l, dl_l, ddl_l, l_r, dl_r, ddl_r) of eqs (1), (2) for angles a (array, or scalar compiled)."""
    s, c = np.sin(a / 2), np.cos(a / 2)
    q = np.sqrt(L * L - (b * c) ** 2)
    u = 0.5 * np.sin(a)                       # = s c
    dq = b * b * u / (2 * q)
    ddq = b * b * np.cos(a) / (4 * q) - b ** 4 * u * u / (4 * q ** 3)
    return (q - b * s, dq - b * c / 2, ddq + b * s / 4,
            q + b * s, dq + b * c / 2, ddq - b * s / 4)


side_terms_kernel = _side_terms.jit


def _sides(a: np.ndarray, b: float, L: float) -> SideLengths:
    return SideLengths(*_side_terms(a, b, L))


def rotation(phi: npt.ArrayLike) -> np.ndarray:
    """2-D rotation matrices, shape (..., 2, 2)."""
    phi = np.asarray(phi, dtype=float)
    c, s = np.cos(phi), np.sin(phi)
    return np.stack([_vec2(c, -s), _vec2(s, c)], -2)


def _cross(u, v):
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


class _JointLocal(NamedTuple):
    """Corners C, D of one joint in its base frame with first and second alpha-derivatives."""

    sides: SideLengths
    C: np.ndarray
    dC: np.ndarray
    ddC: np.ndarray
    D: np.ndarray
    dD: np.ndarray
    ddD: np.ndarray


def _vec2(x, y) -> np.ndarray:
    """Stack two equally shaped arrays on a new last axis (cheaper than np.stack for small arrays)."""
    x = np.asarray(x)
    out = np.empty(np.broadcast_shapes(x.shape, np.shape(y)) + (2,))
    out[..., 0] = x
    out[..., 1] = y
    return out


@dual
def _corner_terms(a, b, L, sides):
    """C, C', C'', D, D', D'' of one joint in its base frame, as 12 coordinates (x, y of each).

    ``sides`` is :func:`_side_terms` of the same angles.
    """
    s, c = np.sin(a / 2), np.cos(a / 2)
    ca, sa = np.cos(a), np.sin(a)
    ll, dll, ddll = sides[0], sides[1], sides[2]
    # C = A + l_l e with side direction e = (-s, c); D = C + b (cos a, sin a)
    cx, cy = -b / 2 - ll * s, ll * c
    dcx, dcy = -dll * s - ll * c / 2, dll * c - ll * s / 2
    ddcx = -ddll * s - dll * c + ll * s / 4
    ddcy = ddll * c - dll * s - ll * c / 4
    return (cx, cy, dcx, dcy, ddcx, ddcy,
            cx + b * ca, cy + b * sa, dcx - b * sa, dcy + b * ca, ddcx - b * ca, ddcy - b * sa)


corner_terms_kernel = _corner_terms.jit


def _joint_local(a: np.ndarray, b: float, L: float, sides: tuple | None = None) -> _JointLocal:
    """Corners of joints at angles ``a`` (rad); ``sides``: :func:`_side_terms` of the same ``a``
    when the caller has them already."""
    if sides is None:
        sides = _side_terms(a, b, L)
    k = _corner_terms(a, b, L, sides)
    # one (..., 6, 2) block for the six points: the control step calls this every estimate
    xy = np.stack(k, -1)
    xy = xy.reshape(xy.shape[:-1] + (6, 2))
    return _JointLocal(SideLengths(*sides), *(xy[..., i, :] for i in range(6)))


def joint_corners(alpha: npt.ArrayLike, params: NeckParams) -> np.ndarray:
    """Corners A, B, C, D of single X-joints in their own base frames, shape (..., 4, 2)."""
    g = params.geometry
    a = np.asarray(alpha, dtype=float)
    jl = _joint_local(a, g.b, g.L)
    A = np.broadcast_to(np.array([-g.b / 2, 0.0]), jl.C.shape)
    B = np.broadcast_to(np.array([g.b / 2, 0.0]), jl.C.shape)
    return np.stack([A, B, jl.C, jl.D], -2)


def psi(alpha: npt.ArrayLike, params: NeckParams) -> np.ndarray:
    """Angle psi of the diagonal B->C from the direction A->B (eqs 6, 7, by atan2); shape of alpha.

    120 deg at alpha = 0 for the paper's b, L.
    """
    g = params.geometry
    a = np.asarray(alpha, dtype=float)
    sd = _sides(a, g.b, g.L)
    x = -g.b - sd.l_l * np.sin(a / 2)
    y = sd.l_l * np.cos(a / 2)
    return np.arctan2(y, x)


def _psi_derivatives(jl: _JointLocal, b: float, L: float):
    """psi' and psi'' from the rod B->C of constant length L."""
    B = np.array([b / 2, 0.0])
    v = jl.C - B
    return _cross(v, jl.dC) / (L * L), _cross(v, jl.ddC) / (L * L)


class Kinematics(NamedTuple):
    """Forward kinematics of the chain, world frame = base frame of joint 1.

    corners: (..., N, 4, 2) A, B, C, D of every joint; frame_origin: (..., N+1, 2) middle of each
    bar (index 0 the fixed base bar, N the head); frame_angle: (..., N+1) bar angles;
    head_position (..., 2) and head_angle (...) are those of the top bar of joint N.
    """

    corners: np.ndarray
    frame_origin: np.ndarray
    frame_angle: np.ndarray
    head_position: np.ndarray
    head_angle: np.ndarray


def forward_kinematics(alpha: npt.ArrayLike, params: NeckParams, *, allow_outside_range: bool = False) -> Kinematics:
    """Corners, bar frames and head pose of the N-joint neck for joint angles alpha (..., N)."""
    g = params.geometry
    a = check_pose(alpha, params, allow_outside_range=allow_outside_range)
    batch = a.shape[:-1]
    origin = np.zeros(batch + (2,))
    phi = np.zeros(batch)
    origins, angles, corners = [origin], [phi], []
    local = joint_corners(a, params)                      # (..., N, 4, 2)
    for i in range(g.n_joints):
        rot = rotation(phi)
        world = origin[..., None, :] + np.einsum("...jk,...pk->...pj", rot, local[..., i, :, :])
        corners.append(world)
        origin = 0.5 * (world[..., 2, :] + world[..., 3, :])
        phi = phi + a[..., i]
        origins.append(origin)
        angles.append(phi)
    return Kinematics(np.stack(corners, -3), np.stack(origins, -2), np.stack(angles, -1), origin, phi)
