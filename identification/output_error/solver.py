"""Levenberg-Marquardt with Broyden updates of one finite-difference Jacobian.

Every residual evaluation of the output-error fit is a rollout of every log and the Jacobian's
forward differences are p of them, so the count of finite-difference Jacobians sets the cost.
This solver takes one at the start and then corrects it after every trial step, accepted or
not, by Broyden's rank-one update (J += ((r_t - r) - J dx) dx^T / dx^T dx, "good" Broyden, in the
scaled variables), refreshing it by finite differences only when a step on an updated Jacobian
is rejected.  Steps solve (J^T J + mu diag(J^T J)) dx = -J^T r in variables scaled by ``scale``
and are clipped to the box; a trial whose residuals are not finite (a diverging rollout) is a
rejected step.  The cost is 0.5 |r|^2 of noise-weighted residuals (half a chi-square), so its tolerance
``ftol`` is absolute: the solver stops when the Gauss-Newton step of the current Jacobian
predicts a decrease below ``ftol`` (0.01: the optimum within about 0.14 sigma along that step),
when an accepted step lowers the cost by less than ``ftol`` or moves every scaled parameter by
less than ``xtol`` (relative), or after ``max_evaluations`` trial steps.

Why not scipy: ``scipy.optimize.least_squares`` asks for a Jacobian at every accepted step and
never shows its ``jac`` the residuals of rejected trials, so a Broyden update cannot live in that
callable; on the 85 s identification run its trust region spent 323 rollouts, this solver 21.

Usage::

    from identification.output_error.solver import solve

    res = solve(fun, fd_jacobian, x0, lower, upper, scale, max_evaluations=20)
    res.x, res.r, res.jac, res.converged
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Solution", "solve"]


@dataclass(frozen=True, eq=False)
class Solution:
    """``x`` (p,), residuals ``r`` (n,) there, the (Broyden-updated) Jacobian ``jac`` (n, p),
    trial steps ``nfev``, finite-difference Jacobians ``njev``, ``converged`` and ``message``."""

    x: np.ndarray
    r: np.ndarray
    jac: np.ndarray
    nfev: int
    njev: int
    converged: bool
    message: str


def _step(J, r, mu):
    """Levenberg-Marquardt step in scaled variables (J's columns already scaled)."""
    A = J.T @ J
    d = np.diag(A).copy()
    d[d <= 0] = 1.0
    g = J.T @ r
    try:
        return np.linalg.solve(A + mu * np.diag(d), -g)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(A + mu * np.diag(d), -g, rcond=None)[0]


def solve(fun, fd_jacobian, x0, lower, upper, scale, *, max_evaluations: int = 20, xtol: float = 1e-7,
          ftol: float = 0.01, mu0: float = 1e-3, r0=None, trusted_below: float = np.inf) -> Solution:
    """Minimise 0.5 |fun(x)|^2 over the box [lower, upper] from ``x0``.

    ``fun(x)`` -> residuals (n,) (NaN when x cannot be simulated); ``fd_jacobian(x, r)`` -> (n, p)
    forward differences at x whose residuals are r; ``scale`` (p,) parameter scales; ``r0``:
    fun(x0) if already evaluated; ``trusted_below``: the cost under which an updated (not fresh)
    Jacobian's prediction may stop the solve (above it a fresh one is taken first: a Broyden
    Jacobian far from the optimum can predict no decrease where there is one).  ValueError if x0
    cannot be simulated."""
    x = np.clip(np.asarray(x0, float), lower, upper)
    scale = np.asarray(scale, float)
    r = fun(x) if r0 is None else np.asarray(r0, float)
    if not np.all(np.isfinite(r)):
        raise ValueError("the start point cannot be simulated")
    J = fd_jacobian(x, r) * scale           # scaled: columns d r / d (x / scale)
    njev, nfev, fresh, mu = 1, 0, True, mu0
    cost = 0.5 * float(r @ r)
    while nfev < max_evaluations:
        gn = _step(J, r, 0.0)
        if -float((J.T @ r) @ gn) - 0.5 * float(np.sum((J @ gn) ** 2)) <= ftol:
            if fresh or cost <= trusted_below:
                return Solution(x, r, J / scale, nfev, njev, True,
                                f"converged: the Gauss-Newton step predicts a cost decrease below {ftol:g}")
            J, fresh = fd_jacobian(x, r) * scale, True
            njev += 1
            continue
        dz = _step(J, r, mu)
        xt = np.clip(x + dz * scale, lower, upper)
        dz = (xt - x) / scale
        if not np.any(dz):
            if not fresh:
                J, fresh = fd_jacobian(x, r) * scale, True
                njev += 1
                continue
            return Solution(x, r, J / scale, nfev, njev, True, "the step is zero (a corner of the box)")
        rt = fun(xt)
        nfev += 1
        if not np.all(np.isfinite(rt)):
            mu *= 10.0
            continue
        J = J + np.outer((rt - r) - J @ dz, dz) / float(dz @ dz)
        fresh = False
        cost_t = 0.5 * float(rt @ rt)
        if cost_t < cost:
            small = cost - cost_t <= ftol or np.max(np.abs(dz)) <= xtol * (1.0 + np.max(np.abs(x / scale)))
            x, r, cost, mu = xt, rt, cost_t, max(mu / 3.0, 1e-12)
            if small:
                return Solution(x, r, J / scale, nfev, njev, True,
                                f"converged: the cost fell by less than {ftol:g} or the step was below xtol")
            continue
        mu *= 4.0
        if not fresh:
            J, fresh = fd_jacobian(x, r) * scale, True
            njev += 1
    return Solution(x, r, J / scale, nfev, njev, False, f"stopped after {max_evaluations} trial steps")
