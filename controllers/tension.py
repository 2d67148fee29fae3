"""Tension distribution of the over-actuated neck (paper §6.2, eqs 62-65), for any N.

The desired joint torque Gamma (N,) must be produced by N + 1 cable forces: Gamma = Z f with
Z = (Z1 Z2) (eq 23), Z1 (N, N) for the right cables c1..cN, Z2 (N,) for the long left cable.
Because Z1 is invertible, the solutions form a one-parameter family in the long cable's force
s = f_{N+1} (eq 63):

    f = u + v s,    u = (Z1^{-1} Gamma, 0),    v = (-Z1^{-1} Z2, 1).

Over the workspace every entry of -Z1^{-1} Z2 is positive (about 0.5 to 2.1 in [-90, 90] deg^N
for the paper's geometry), so every force grows with s: the smallest s meeting all lower bounds
lb (eq 65) minimises every force and hence |f| -- it is the largest of the N + 1 candidates
s_j = (lb_j - u_j) / v_j.  Forces above f_max are then clipped to f_max and reported as saturated
(the torque is then no longer exact).  A pose where some entry of -Z1^{-1} Z2 is not positive
has no such family (tensions could not all stay positive): :class:`TensionInfeasibleError`.

Shapes: Z (..., N, N+1) m, Gamma (..., N) N m, forces and bounds (..., N+1) N.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from neck_sim.analytic.dynamics import arctan_friction
from neck_sim.analytic.geometry import check_cables
from neck_sim.jit import kernel, solve_in_place
from neck_sim.params import NeckParams

__all__ = ["TensionInfeasibleError", "TensionDistribution", "tension_lower_bounds", "distribute_tensions"]


class TensionInfeasibleError(ValueError):
    """No positive one-parameter family of cable forces exists (pose outside the workspace)."""


class TensionDistribution(NamedTuple):
    """Result of :func:`distribute_tensions`.

    forces: (..., N+1) N, the commanded forces, clipped to f_max.
    requested: (..., N+1) N, the forces before clipping (Z requested = Gamma exactly).
    saturated: (..., N+1) bool, True where requested > f_max.
    binding: (...) int, index of the cable whose lower bound set the long cable's force.
    """

    forces: np.ndarray
    requested: np.ndarray
    saturated: np.ndarray
    binding: np.ndarray

    @property
    def any_saturated(self) -> np.ndarray | np.bool_:
        """(...) bool: at least one cable was clipped, so Z f != Gamma."""
        return self.saturated.any(axis=-1)


def tension_lower_bounds(theta_dot_d: npt.ArrayLike, theta_ddot_d: npt.ArrayLike, params: NeckParams, *,
                         f_s: npt.ArrayLike | None = None,
                         t_min: float | None = None, f_min: float | None = None) -> np.ndarray:
    """Lower bound on each commanded force, eq (65), (..., N+1) N.

    lb_i = max(t_min + (2/pi) arctan(c_s theta_dot_d_i) f_s(i) + (R/r_d) I_a theta_ddot_d_i, f_min)

    with the *desired* motor speeds theta_dot_d (rad/s) and accelerations theta_ddot_d (rad/s^2),
    as the paper does to avoid force jumps.  ``f_s`` (N+1,) N is the friction the controller
    believes in; None leaves friction out (control law 1).  ``t_min``/``f_min`` default to
    ``params.actuation``.
    """
    act = params.actuation
    n1 = params.n_cables
    td = check_cables(theta_dot_d, n1, "theta_dot_d")
    tdd = check_cables(theta_ddot_d, n1, "theta_ddot_d")
    t_min = act.t_min if t_min is None else float(t_min)
    f_min = act.f_min if f_min is None else float(f_min)
    bound = t_min + (act.R / act.r_d) * act.I_a * tdd
    if f_s is not None:
        fs = check_cables(f_s, n1, "f_s")
        bound = bound + arctan_friction(td, params.friction.c_s, fs)
    return np.maximum(bound, f_min)


def distribute_tensions(Z: npt.ArrayLike, gamma: npt.ArrayLike, lower: npt.ArrayLike,
                        f_max: float) -> TensionDistribution:
    """Cable forces producing ``gamma`` with every force at least ``lower`` (eqs 63-65), batched.

    Z (..., N, N+1) m, gamma (..., N) N m, lower (..., N+1) N, f_max N.  Raises
    :class:`TensionInfeasibleError` naming the first offending sample when Z1 is singular or some
    entry of -Z1^{-1} Z2 is not positive.
    """
    Z = np.asarray(Z, dtype=float)
    if Z.ndim < 2 or Z.shape[-1] != Z.shape[-2] + 1:
        raise ValueError(f"Z: expected shape (..., N, N+1), got {Z.shape}")
    n = Z.shape[-2]
    gamma = np.asarray(gamma, dtype=float)
    if gamma.ndim == 0 or gamma.shape[-1] != n:
        raise ValueError(f"gamma: expected shape (..., {n}) (one torque per joint), got {gamma.shape}")
    lower = check_cables(lower, n + 1, "lower")
    for name, arr in (("Z", Z), ("gamma", gamma)):
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name}: contains NaN or infinity")
    if not (np.isfinite(f_max) and f_max > 0):
        raise ValueError(f"f_max: must be finite and positive, got {f_max}")
    batch = np.broadcast_shapes(Z.shape[:-2], gamma.shape[:-1], lower.shape[:-1])
    rows = int(np.prod(batch))

    def flat(x, shape):
        return np.ascontiguousarray(np.broadcast_to(x, batch + shape)).reshape((rows,) + shape)

    forces, requested = np.empty((rows, n + 1)), np.empty((rows, n + 1))
    saturated = np.empty((rows, n + 1), dtype=np.bool_)
    binding = np.empty(rows, dtype=np.int64)
    row, status = _distribute_rows(flat(Z, (n, n + 1)), flat(gamma, (n,)), flat(lower, (n + 1,)), float(f_max),
                                   forces, requested, saturated, binding)
    if status != 0:
        raise TensionInfeasibleError(infeasible_message(status, np.unravel_index(row, batch) if batch else ()))
    return TensionDistribution(forces.reshape(batch + (n + 1,)), requested.reshape(batch + (n + 1,)),
                               saturated.reshape(batch + (n + 1,)), binding.reshape(batch))


def infeasible_message(status: int, sample) -> str:
    """The error of :func:`distribute_kernel`'s status (1: Z1 singular, 2 + j: cable j's direction)."""
    where = tuple(int(i) for i in sample)
    if status == 1:
        return f"Z1 (right cables) is singular at sample {where}: pose outside the workspace"
    return (f"-Z1^-1 Z2 has a non-positive entry for cable c{status - 1} at sample {where}: no positive "
            "cable forces produce every torque there (pose outside the workspace)")


@kernel
def distribute_kernel(Z, gamma, lower, f_max, forces, requested, saturated) -> tuple:
    """Eqs (63)-(65) for one sample; returns (status, binding cable).

    Writes forces, requested (N+1,) N and saturated (N+1,) bool.  status 0: done; 1: Z1 singular;
    2 + j: -Z1^-1 Z2 is not positive for cable j (0-based), nothing written.
    """
    n = Z.shape[0]
    Z1 = np.empty((n, n))
    sol = np.empty((n, 2))
    for i in range(n):
        for j in range(n):
            Z1[i, j] = Z[i, j]
        sol[i, 0] = gamma[i]
        sol[i, 1] = -Z[i, n]
    if not solve_in_place(Z1, sol):
        return 1, 0
    for j in range(n):                      # v = (-Z1^-1 Z2, 1) must point into positive forces
        if not (sol[j, 1] > 0.0 and np.isfinite(sol[j, 1])):
            return 2 + j, 0
    binding, s = 0, -np.inf                 # the largest candidate, the first one on ties
    for j in range(n + 1):
        cand = (lower[j] - sol[j, 0]) / sol[j, 1] if j < n else lower[n]   # eq (65) met with equality
        if cand > s:
            s = cand
            binding = j
    for j in range(n + 1):
        f = sol[j, 0] + sol[j, 1] * s if j < n else s
        requested[j] = f
        saturated[j] = f > f_max
        forces[j] = min(f, f_max)
    return 0, binding


@kernel
def _distribute_rows(Z, gamma, lower, f_max, forces, requested, saturated, binding):
    for r in range(Z.shape[0]):
        status, binding[r] = distribute_kernel(Z[r], gamma[r], lower[r], f_max, forces[r], requested[r],
                                               saturated[r])
        if status != 0:
            return r, status
    return -1, 0
