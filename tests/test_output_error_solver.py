"""The output-error solver (``identification.output_error.solver``) on small synthetic problems
whose answers are known: when it takes a fresh Jacobian, how it steps after a diverging trial,
and that a stop above the noise floor is not called a convergence.

The problems are noise-weighted residuals r = (model(x) - y) / sigma of a decaying exponential
plus a sine (4 parameters, 400 samples), so the cost at the truth is about n / 2 (the floor).
"""

from __future__ import annotations

import numpy as np
import pytest

from identification.output_error import solver

T = np.linspace(0.0, 5.0, 400)
TRUTH = np.array([1.0, 2.0, 0.5, 3.0])
SIGMA = 0.01
N = T.size


def _model(x):
    return x[1] * np.exp(-x[0] * T) + x[2] * np.sin(x[3] * T)


Y = _model(TRUTH) + SIGMA * np.random.default_rng(0).normal(size=N)


def _fun(x):
    return (_model(x) - Y) / SIGMA


def _fd(fun, calls=None, first_at=None):
    """Forward differences; with ``first_at`` the first one is taken there instead (a Jacobian from
    far away, which Broyden's updates must then correct)."""
    def jac(x, r):
        if calls is not None:
            calls.append(np.array(x))
        at, base = x, r
        if first_at is not None and calls is not None and len(calls) == 1:
            at = np.asarray(first_at, float)
            base = fun(at)
        h = 1e-6 * np.maximum(np.abs(at), 1.0)
        return np.stack([(fun(at + np.eye(at.size)[i] * h[i]) - base) / h[i] for i in range(at.size)], axis=1)
    return jac


def _solve(fun, jac, x0, **kw):
    x0 = np.asarray(x0, float)
    return solver.solve(fun, jac, x0, np.zeros(4), np.full(4, np.inf), np.maximum(np.abs(x0), 1.0),
                        max_evaluations=kw.pop("max_evaluations", 40), trusted_below=0.75 * N, floor=0.5 * N, **kw)


def test_a_jacobian_from_far_away_is_replaced_when_it_stops_predicting():
    """The first Jacobian is taken at (1.51, 1.43, 0.42, 4.22), far from the start: its updates predict
    the steps badly, the solver takes fresh ones and converges at the truth (measured: 3
    Jacobians, 8 trial steps).  With the refresh rules off (RHO_REFRESH and PROGRESS_REFRESH
    disabled) the updates crawl: 26 trial steps on the first Jacobian."""
    calls = []
    sol = _solve(_fun, _fd(_fun, calls, first_at=[1.51, 1.43, 0.42, 4.22]), [1.04, 1.68, 0.57, 2.75])
    assert sol.converged, sol.message
    assert sol.njev >= 2 and sol.nfev <= 12, (sol.njev, sol.nfev)
    reference = _solve(_fun, _fd(_fun), [1.04, 1.68, 0.57, 2.75])     # every Jacobian fresh at its point
    np.testing.assert_allclose(sol.x, reference.x, rtol=1e-3)


def test_a_diverging_trial_shrinks_the_step_along_its_direction():
    """A trial that cannot be simulated (NaN residuals) is followed by a step in the same
    direction, its largest scaled component DIVERGED_SHRINK times the diverged one's (a trust
    radius), not by a more damped step in another direction."""
    trials = []
    x0 = np.array([0.5, 1.0, 0.3, 2.8])

    def fun(x):
        trials.append(np.array(x))
        if len(trials) == 1:                 # the first trial step diverges
            return np.full(N, np.nan)
        return _fun(x)

    sol = _solve(fun, _fd(_fun), x0, max_evaluations=2, r0=_fun(x0))
    scale = np.maximum(np.abs(x0), 1.0)
    d1, d2 = (trials[0] - x0) / scale, (trials[1] - x0) / scale
    assert np.max(np.abs(d2)) == pytest.approx(solver.DIVERGED_SHRINK * np.max(np.abs(d1)), rel=1e-9)
    np.testing.assert_allclose(d2 / np.linalg.norm(d2), d1 / np.linalg.norm(d1), atol=1e-9)
    assert np.isnan(sol.history[0][2]) and np.isfinite(sol.history[1][2])


def test_a_stop_far_above_the_floor_is_stalled_not_converged():
    """Data the model cannot explain (a step in the middle of the run, 50 sigma) leave the cost at
    many times the floor: the solver stops at that local optimum and says it stalled; the same
    solver on the explained data says converged."""
    y_bad = Y + np.where(T > 2.5, 0.5, 0.0)

    def misfit(x):
        return (_model(x) - y_bad) / SIGMA

    bad = _solve(misfit, _fd(misfit), [0.9, 1.9, 0.45, 2.95])
    assert not bad.converged and bad.message.startswith("stalled"), bad.message
    assert 0.5 * float(bad.r @ bad.r) > 0.75 * N
    good = _solve(_fun, _fd(_fun), [0.9, 1.9, 0.45, 2.95])
    assert good.converged and good.message.startswith("converged"), good.message
