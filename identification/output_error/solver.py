"""Levenberg-Marquardt with Broyden updates of one finite-difference Jacobian.

Every residual evaluation of the output-error fit is a rollout of every log and the Jacobian's
forward differences are p of them, so the count of finite-difference Jacobians sets the cost.
This solver takes one at the start and then corrects it after every trial step, accepted or
not, by Broyden's rank-one update (J += ((r_t - r) - J dx) dx^T / dx^T dx, "good" Broyden, in the
scaled variables), refreshing it by finite differences only when the updated one stops
describing the residuals (a step on it rejected, a step achieving less than
:data:`RHO_REFRESH` of its predicted decrease, or, above the trusted cost, its Gauss-Newton
step no longer seeing the floor: :data:`PROGRESS_REFRESH`).  Steps solve (J^T J + mu
diag(J^T J)) dx = -J^T r in variables scaled by ``scale`` and are clipped to the box; a trial
whose residuals are not finite (a diverging rollout) is a rejected step that shrinks a trust
radius along its direction (:data:`DIVERGED_SHRINK`).  The cost is 0.5 |r|^2 of noise-weighted
residuals (half a chi-square), so its tolerance ``ftol`` is absolute: the solver stops when the
Gauss-Newton step of a trusted Jacobian predicts a decrease below ``ftol`` (0.01: the optimum
within about 0.14 sigma along that step), when an accepted step lowers the cost by less than
``ftol`` or moves every scaled parameter by less than ``xtol`` (relative), or after
``max_evaluations`` trial steps; a stop above ``trusted_below`` (1.5 times the noise floor) is
"stalled", not converged.

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


#: An accepted step on an updated (Broyden) Jacobian that achieves less than this share of the
#: cost decrease it predicted takes a fresh finite-difference Jacobian: the updated one no longer
#: describes the residuals (from a start 3 % off in every parameter, 8 s runs, two seeds crawled
#: through 30 such steps at 20-50 % of the predicted decrease and stopped at the cap).
RHO_REFRESH = 0.5

#: Above the trusted cost, an updated Jacobian whose Gauss-Newton step predicts removing less
#: than this share of the cost's excess over the noise floor is replaced by a fresh one, when the
#: last fresh one predicted more (Broyden's updates crawl when the first Jacobian was taken far
#: from the optimum: two seeds of 8 s runs gained 10-40 % a step and stopped at the cap).
PROGRESS_REFRESH = 0.5

#: A trial whose re-simulation diverges caps the next steps' largest scaled component at this
#: share of its own (a trust radius along the same direction, doubled after each well-predicted
#: accepted step); raising the damping instead turned the Gauss-Newton direction into a gradient
#: crawl (one seed of 8 s runs took 6 % a step and stopped at the cap at 3e5 times the floor:
#: its Gauss-Newton steps sent c_a to 0 on two cables and to 440 N s/m on a third).
DIVERGED_SHRINK = 0.25


@dataclass(frozen=True, eq=False)
class Solution:
    """``x`` (p,), residuals ``r`` (n,) there, the (Broyden-updated) Jacobian ``jac`` (n, p),
    trial steps ``nfev``, finite-difference Jacobians ``njev``, ``converged``, ``message`` and
    ``history``: per trial step (cost before, predicted decrease, cost after (NaN: not
    simulated), Jacobian fresh from finite differences)."""

    x: np.ndarray
    r: np.ndarray
    jac: np.ndarray
    nfev: int
    njev: int
    converged: bool
    message: str
    history: tuple = ()


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


def _predicted(J, r, dz) -> float:
    """Cost decrease the linear model J predicts for the step dz: 0.5 |r|^2 - 0.5 |r + J dz|^2."""
    return -float(r @ (J @ dz)) - 0.5 * float(np.sum((J @ dz) ** 2))


def solve(fun, fd_jacobian, x0, lower, upper, scale, *, max_evaluations: int = 20, xtol: float = 1e-7,
          ftol: float = 0.01, mu0: float = 1e-3, r0=None, trusted_below: float = np.inf,
          floor: float = 0.0) -> Solution:
    """Minimise 0.5 |fun(x)|^2 over the box [lower, upper] from ``x0``.

    ``fun(x)`` -> residuals (n,) (NaN when x cannot be simulated); ``fd_jacobian(x, r)`` -> (n, p)
    forward differences at x whose residuals are r; ``scale`` (p,) parameter scales; ``r0``:
    fun(x0) if already evaluated; ``trusted_below``: the cost under which a stop is a convergence
    (about 1.5 times the noise floor); above it the solver may still stop at a local minimum (or
    a model that misses something), and says so with ``converged`` False; ``floor``: the cost
    expected at the optimum (half the residual count for noise-weighted residuals).

    An updated Jacobian is trusted to stop the solve (its Gauss-Newton step predicting a decrease
    below ``ftol``, or a step gaining less) only while it predicted the last accepted step well
    (at least :data:`RHO_REFRESH` of the predicted decrease achieved); a fresh finite-difference
    one is taken instead then, after a rejected step on an updated one, and above
    ``trusted_below`` when it stops seeing the way to ``floor`` (:data:`PROGRESS_REFRESH`).  A
    diverging trial shrinks a trust radius (:data:`DIVERGED_SHRINK`).  ValueError if x0 cannot be
    simulated."""
    x = np.clip(np.asarray(x0, float), lower, upper)
    scale = np.asarray(scale, float)
    r = fun(x) if r0 is None else np.asarray(r0, float)
    if not np.all(np.isfinite(r)):
        raise ValueError("the start point cannot be simulated")
    J = fd_jacobian(x, r) * scale           # scaled: columns d r / d (x / scale)
    njev, nfev, fresh, mu = 1, 0, True, mu0
    trusted = True                          # the current J predicted the last accepted step well
    cost = 0.5 * float(r @ r)
    history = []

    def done(why: str) -> Solution:
        if cost <= trusted_below:
            return Solution(x, r, J / scale, nfev, njev, True, "converged: " + why, tuple(history))
        return Solution(x, r, J / scale, nfev, njev, False,
                        f"stalled at a cost of {cost:.6g}, above {trusted_below:.6g} (about 1.5 times the noise "
                        f"floor): a local minimum, or a model that misses something ({why})", tuple(history))

    radius, reach = np.inf, True            # trust radius (scaled, max norm); a fresh J sees the floor
    while nfev < max_evaluations:
        predicted_gn = _predicted(J, r, _step(J, r, 0.0))
        if fresh:
            reach = predicted_gn >= PROGRESS_REFRESH * (cost - floor)
        if predicted_gn <= ftol:
            if fresh or (trusted and cost <= trusted_below):
                return done(f"the Gauss-Newton step predicts a cost decrease below {ftol:g}")
            J, fresh, trusted = fd_jacobian(x, r) * scale, True, True
            njev += 1
            continue
        if not fresh and reach and cost > trusted_below and predicted_gn < PROGRESS_REFRESH * (cost - floor):
            # the updated J no longer sees the way to the floor that the last fresh one saw
            J, fresh, trusted = fd_jacobian(x, r) * scale, True, True
            njev += 1
            continue
        dz = _step(J, r, mu)
        if np.max(np.abs(dz)) > radius:
            dz = dz * (radius / np.max(np.abs(dz)))
        xt = np.clip(x + dz * scale, lower, upper)
        dz = (xt - x) / scale
        if not np.any(dz):
            if not fresh:
                J, fresh, trusted = fd_jacobian(x, r) * scale, True, True
                njev += 1
                continue
            return done("the step is zero (a corner of the box)")
        predicted = _predicted(J, r, dz)
        was_fresh = fresh
        rt = fun(xt)
        nfev += 1
        if not np.all(np.isfinite(rt)):
            history.append((cost, predicted, float("nan"), was_fresh))
            radius = DIVERGED_SHRINK * np.max(np.abs(dz))
            continue
        J = J + np.outer((rt - r) - J @ dz, dz) / float(dz @ dz)
        fresh = False
        cost_t = 0.5 * float(rt @ rt)
        history.append((cost, predicted, cost_t, was_fresh))
        if cost_t < cost:
            small = cost - cost_t <= ftol or np.max(np.abs(dz)) <= xtol * (1.0 + np.max(np.abs(x / scale)))
            trusted = cost - cost_t >= RHO_REFRESH * predicted
            if trusted:
                radius *= 2.0
            x, r, cost, mu = xt, rt, cost_t, max(mu / 3.0, 1e-12)
            if small and (was_fresh or (trusted and cost <= trusted_below)):
                return done(f"the cost fell by less than {ftol:g} or the step was below xtol")
            if small or not (trusted or was_fresh):
                J, fresh, trusted = fd_jacobian(x, r) * scale, True, True
                njev += 1
            continue
        mu *= 4.0
        if not was_fresh:                   # a step on a fresh Jacobian was only too long
            J, fresh, trusted = fd_jacobian(x, r) * scale, True, True
            njev += 1
    return Solution(x, r, J / scale, nfev, njev, False, f"stopped after {max_evaluations} trial steps",
                    tuple(history))
