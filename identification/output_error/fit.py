"""The output-error fit: box-constrained Levenberg-Marquardt over re-simulations.

:func:`identification.output_error.solver.solve` (bounds of :class:`Layout`, parameter scales
from the start point) minimises the noise-weighted residuals of
:func:`identification.output_error.problem.residuals`.  The Jacobian is forward differences, one
batch of p rollouts per experiment (the engine may run them in parallel), taken once and then
updated by Broyden's rank-one formula after every trial step (a fresh one only when the updated
one stops describing the residuals, :mod:`identification.output_error.solver`).  Its f_s, k and
lambda columns come from rollouts on a cheaper model (``OutputErrorSettings.jacobian_timestep``:
2 ms on ``discrete``, 0.42 of a plant rollout); every residual the solver compares is the
plant's.  The integrator
is fixed once per fit (the plant's choice for the nominal constants, :func:`choose_integrator`,
or given): the model is continuous in every parameter.  A candidate whose re-simulation diverges
gets NaN residuals, which the solver treats as a rejected step (its trust radius shrinks); its
reason is kept in ``rejected``.
"""

from __future__ import annotations

import inspect
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from identification.output_error.intervals import Z95, hac_jacobian_covariance
from identification.output_error.misfit import cost_ratios, misfit_lines
from identification.output_error.settings import OutputErrorSettings
from identification.output_error.problem import SIGNALS, Layout, Measured, noise_sigmas, residual_samples, residuals
from identification.output_error import _serial, rollouts as engine, solver

__all__ = ["OutputErrorSettings", "OutputErrorResult", "fit", "cost_at", "choose_integrator"]

#: Smallest parameter scale per group (x_scale and finite-difference step), in the group's unit.
SCALE_FLOOR = {"f_s": 1.0, "k": 100.0, "lambda": 1.0, "c_a": 10.0}


@dataclass(frozen=True, eq=False)
class OutputErrorResult:
    """The fitted parameters (``value``, ``sigma``, ``ci95`` half-widths, (p,) in ``names`` order,
    units ``units``) beside the ``start``; cost ratio per signal (1 = noise floor), the misfit
    lines, rejected candidates, rollouts run, finite-difference Jacobians (``iterations``) and
    trial steps, CPU s, the integrator and the solver's stop reason."""

    names: tuple
    units: tuple
    start: np.ndarray
    value: np.ndarray
    sigma: np.ndarray
    ci95: np.ndarray
    cov: np.ndarray
    cost_ratio: dict
    n_samples: dict
    misfit: tuple
    rejected: tuple
    rollouts: int
    iterations: int
    cpu_s: float
    integrator: str
    status: str
    logs: tuple
    notes: tuple = ()
    simulated_s: float = 0.0   # s of plant time re-simulated (rollouts x their spans)
    trial_steps: int = 0       # residual evaluations of the solver's steps (each one rollout per log)
    rollout_cpu_s: float = 0.0  # of cpu_s, the rollouts' (plants built and simulated)
    coarse_rollouts: int = 0   # of rollouts, those on the Jacobian's cheaper model (OutputErrorSettings)

    @property
    def converged(self) -> bool:
        return not any(n.startswith("NOT CONVERGED") for n in self.notes)

    def group(self, symbol: str, attr: str = "value") -> np.ndarray:
        idx = [i for i, n in enumerate(self.names) if n.split("(")[0] == symbol]
        if not idx:
            raise KeyError(f"{symbol!r}: no such parameter group (parameters: {', '.join(self.names)})")
        return getattr(self, attr)[idx]

    def to_dict(self) -> dict:
        """The JSON ``output_error`` object: per-parameter-group lists of {value, ci95}."""
        groups: dict = {}
        for n, u, v, c, s0 in zip(self.names, self.units, self.value, self.ci95, self.start):
            groups.setdefault(n.split("(")[0], []).append({"value": float(v), "ci95": float(c), "unit": u,
                                                           "start": float(s0)})
        return {"parameters": groups, "names": list(self.names), "cost_ratio": self.cost_ratio,
                "samples": self.n_samples, "misfit": list(self.misfit), "rejected_steps": list(self.rejected),
                "rollouts": self.rollouts, "simulated_s": self.simulated_s, "iterations": self.iterations, "cpu_s": self.cpu_s,
                "integrator": self.integrator, "status": self.status, "converged": self.converged,
                "logs": list(self.logs),
                "notes": list(self.notes), "trial_steps": self.trial_steps, "rollout_cpu_s": self.rollout_cpu_s,
                "coarse_rollouts": self.coarse_rollouts,
                "ci95_method": "1.96 sigma, sigma from the Newey-West sandwich (J^T J)^-1 S (J^T J)^-1 at the "
                               "optimum (J of the noise-weighted residuals, Broyden-updated; S the Bartlett long-run "
                               "covariance of the per-sample scores)"}


def _scales(layout: Layout, x0) -> np.ndarray:
    floor = np.array([SCALE_FLOOR.get(n.split("(")[0], 0.0) for n in layout.names])
    sc = np.maximum(np.abs(x0), floor)
    return np.where(sc > 0, sc, 1.0)


def choose_integrator(layout: Layout, settings: OutputErrorSettings) -> str:
    """The integrator for the whole fit: the given one, else the plant's choice
    (:func:`neck_sim.mjcf.integrator_for`) for the nominal constants of ``layout`` (the log's
    neck record or the ``--model`` file), not for the start point: the least squares cannot see
    c_a, and a start above the plant's switch (60 N s/m at the default bars) would put the whole
    fit on ``discrete``, which differs from ``implicitfast`` by far more than the noise (on the
    clean 85 s identification run the truth itself costs 370 times the encoders' noise floor
    there)."""
    if settings.integrator is not None:
        return settings.integrator
    from neck_sim.mjcf import integrator_for

    return integrator_for(layout.params)


class _Evaluator:
    """Rollouts of parameter vectors over every experiment, counted, with divergences named."""

    def __init__(self, measured, layout: Layout, integrator: str, bar):
        self.measured, self.layout, self.integrator, self.bar = measured, layout, integrator, bar
        self.sigmas = noise_sigmas(layout.params)
        self.rollouts, self.simulated_s, self.cpu_s = 0, 0.0, 0.0
        self.rejected: list[str] = []
        self.coarse_rollouts = 0

    def runs(self, X, coarse: tuple | None = None) -> tuple[list, list]:
        """Per vector of X (K, p): its runs [(theta, alpha) per experiment] or None, and reasons;
        ``coarse`` (timestep s, integrator) rolls out on that cheaper model instead of the fit's
        (every run None when an effect keeps state outside MuJoCo's: the batch engine cannot)."""
        K = len(X)
        plants: list[tuple | None] = []
        reasons: list[str | None] = [None] * K
        for k, x in enumerate(X):
            try:
                plants.append(self.layout.plant(x))
            except ValueError as exc:
                plants.append(None)
                reasons[k] = f"not a valid plant: {exc}"
        m = self.layout.params.n_cables
        if coarse is not None and (not _UNQUANTISED or any(p is not None and _outside(p[1], m) for p in plants)):
            return [None] * K, ["the Jacobian's coarse model needs the batch engine"] * K
        ok = [k for k in range(K) if plants[k] is not None]
        models = [p[0] for p in plants if p is not None]
        effects = [p[1] for p in plants if p is not None]
        runs: list[list | None] = [[] if plants[k] is not None else None for k in range(K)]
        cpu0 = time.process_time()
        for meas in self.measured:
            if coarse is None:
                out = _rollout(meas.replay, models, effects, self.integrator)
            else:
                out = _coarse_rollout(meas.replay, models, effects, *coarse)
                self.coarse_rollouts += len(ok)
            self.rollouts += len(ok)
            self.simulated_s += len(ok) * meas.duration_s
            for i, k in enumerate(ok):
                run = runs[k]
                if run is None:
                    continue
                if out.diverged[i]:
                    runs[k], reasons[k] = None, f"{meas.name}: {out.reasons[i]}"
                else:
                    run.append((out.encoders[i], out.camera_alpha[i]))
        self.cpu_s += time.process_time() - cpu0
        if self.bar is not None:
            self.bar.update(len(ok) * len(self.measured))
        return runs, reasons

    def residual(self, run) -> dict:
        return residuals(self.measured, run, self.sigmas)


def cost_at(measured: Sequence[Measured], layout: Layout, x: ArrayLike, integrator: str) -> dict:
    """Cost ratio per signal (:func:`misfit.cost_ratios`) of one parameter vector; ValueError if
    its re-simulation diverges."""
    ev = _Evaluator(measured, layout, integrator, None)
    (run,), (why,) = ev.runs([np.asarray(x, dtype=float)])
    if run is None:
        raise ValueError(f"output-error: this parameter set cannot be simulated ({why})")
    return cost_ratios(ev.residual(run))


def _solve(ev: _Evaluator, layout: Layout, x0, scale, s: OutputErrorSettings):
    """The Broyden Levenberg-Marquardt solve (:mod:`solver`) over every log; ValueError when x0
    cannot be simulated."""
    n = sum(e.theta.size + e.camera_alpha.size for e in ev.measured)

    def residual_of(run):
        return np.concatenate([ev.residual(run)[k] for k in SIGNALS])

    def fun(x):
        (run,), (why,) = ev.runs([x])
        if run is None:
            ev.rejected.append(f"candidate {_short(layout, x)} rejected: {why}")
            return np.full(n, np.nan)
        r = residual_of(run)
        if ev.bar is not None:
            ev.bar.set_postfix(cost=f"{0.5 * float(r @ r):.4g}")
        return r

    coarse = [i for i, name in enumerate(layout.names) if name.split("(")[0] in s.jacobian_groups] \
        if s.jacobian_timestep is not None else []
    model = (s.jacobian_timestep, s.jacobian_integrator or ev.integrator)

    def jac(x, r):
        h = s.rel_step * scale
        J = np.empty((r.size, x.size))
        fine = list(range(x.size))
        if coarse:
            # forward differences of the cheaper model against its own rollout at x
            runs, _ = ev.runs(np.vstack([x, x[None, :] + np.diag(h)[coarse]]), model)
            if runs[0] is not None:
                base = residual_of(runs[0])
                for i, run in zip(coarse, runs[1:]):
                    if run is not None:
                        J[:, i] = (residual_of(run) - base) / h[i]
                        fine.remove(i)
        runs, reasons = ev.runs(x[None, :] + np.diag(h)[fine]) if fine else ([], [])
        for i, run, reason in zip(fine, runs, reasons):
            if run is None:                    # the forward step diverged: step back instead
                (back,), (why,) = ev.runs([x - np.diag(h)[i]])
                if back is None:
                    raise ValueError(f"output-error: the plant diverges on both sides of {layout.names[i]} "
                                     f"at {x[i]:.6g} ({reason}; {why})")
                J[:, i] = (r - residual_of(back)) / h[i]
            else:
                J[:, i] = (residual_of(run) - r) / h[i]
        return J

    r0 = fun(x0)
    if not np.all(np.isfinite(r0)):
        raise ValueError(f"output-error: the start of the fit cannot be simulated ({ev.rejected[-1]})")
    # near the noise floor (cost about n / 2) an updated Jacobian may declare convergence
    return solver.solve(fun, jac, x0, layout.lower, layout.upper, scale, max_evaluations=s.max_evaluations,
                        xtol=s.xtol, ftol=s.ftol, r0=r0, trusted_below=0.5 * n * s.misfit_ratio,
                        floor=0.5 * n)


def fit(measured: Sequence[Measured], layout: Layout, x0: ArrayLike, settings: OutputErrorSettings | None = None,
        *, progress: bool = False, notes: Sequence[str] = ()) -> OutputErrorResult:
    """Fit ``layout``'s parameters to ``measured`` (one parameter set for all) from ``x0``, in one
    solve over the whole logs.

    An open-loop re-simulation of the 85 s identification run from the least-squares start stays
    bounded (its encoders within 0.09 rad of the log's, 1187 times the noise floor) and the first
    Gauss-Newton step from there lands at 1.08 times the floor, so no continuation over growing
    spans is needed -- provided the fit runs on the plant's integrator (:func:`choose_integrator`).
    ValueError when the start cannot be simulated; later diverging candidates are rejected steps."""
    from identification.threads import single_thread

    # BLAS on one thread: the solver's and the intervals' products are (n, 16) by (16, 16), for
    # which OpenBLAS threads only spin (the sandwich took 0.44 s of CPU on two threads of a
    # loaded 2-core machine, 0.018 s on one); MuJoCo's batch threads are its own
    with single_thread():
        return _fit(measured, layout, x0, settings or OutputErrorSettings(), progress, notes)


def _fit(measured, layout: Layout, x0, s: OutputErrorSettings, progress: bool, notes) -> OutputErrorResult:
    x = np.clip(np.asarray(x0, dtype=float), layout.lower, layout.upper)
    start = x.copy()
    integrator = choose_integrator(layout, s)
    scale = _scales(layout, x)
    cpu0 = time.process_time()
    if progress:
        from tqdm.auto import tqdm

        with tqdm(desc="output-error fit", unit="rollout", leave=False) as bar:
            ev = _Evaluator(measured, layout, integrator, bar)
            sol = _solve(ev, layout, x, scale, s)
    else:
        ev = _Evaluator(measured, layout, integrator, None)
        sol = _solve(ev, layout, x, scale, s)
    x, r = sol.x, sol.r
    res = _split(r, measured)
    cov, _ = hac_jacobian_covariance(sol.jac, r, *residual_samples(measured))
    sigma = np.sqrt(np.diag(cov))
    ratios = cost_ratios(res)
    notes = list(notes)
    from neck_sim.mjcf import integrator_for

    if not sol.converged and sol.message.startswith("stopped after"):
        notes.append(f"NOT CONVERGED: the fit stopped after {s.max_evaluations} trial steps (--max-evaluations); "
                     "the values and any misfit below are those of an unfinished fit")
    elif not sol.converged:
        notes.append(f"NOT CONVERGED: {sol.message}; run `neck-sim diagnose` on the logs")
    wanted = integrator_for(layout.plant(x)[0])
    if wanted != integrator:
        notes.append(f"integrator: the fit ran on {integrator} (the plant's choice for the nominal constants); at "
                     f"the fitted values the plant would choose {wanted}: refit with --integrator {wanted} to compare")
    return OutputErrorResult(layout.names, layout.units, start, x, sigma, Z95 * sigma, cov, ratios,
                             {k: int(v.size) for k, v in res.items()},
                             tuple(misfit_lines(ratios, [e.name for e in measured], s.misfit_ratio)),
                             tuple(ev.rejected), ev.rollouts, sol.njev, time.process_time() - cpu0,
                             integrator, sol.message, tuple(e.name for e in measured), tuple(notes),
                             ev.simulated_s, sol.nfev, ev.cpu_s, ev.coarse_rollouts)


def _outside(effects, m: int) -> bool:
    """Whether these effects keep state outside MuJoCo's (a dead band or an actuation delay),
    which the batch engine does not step."""
    return effects is not None and (effects.command_delay() > 0 or bool(np.any(effects.encoder_band(m) > 0)))


def _rollout(replay, params, effects, integrator):
    """The parallel engine when it can return unquantised motor angles and step these effects,
    else the serial one."""
    m = params[0].n_cables if params else 0
    if _UNQUANTISED and not any(_outside(e, m) for e in effects):
        return engine.rollout(replay, params, effects, integrator=integrator, quantise=False)
    return _serial.rollout(replay, params, effects, integrator=integrator)


def _coarse_rollout(replay, params, effects, timestep: float, integrator: str):
    """The batch engine on the Jacobian's cheaper model (OutputErrorSettings.jacobian_timestep)."""
    try:
        return engine.rollout(replay, params, effects, integrator=integrator, timestep=timestep, quantise=False)
    except ValueError as exc:
        raise ValueError(f"jacobian_timestep: {str(exc).splitlines()[0]}") from None


_UNQUANTISED = "quantise" in inspect.signature(engine.rollout).parameters


def _split(r, measured) -> dict:
    n_enc = sum(e.theta.size for e in measured)
    return {"encoders": r[:n_enc], "camera": r[n_enc:]}


def _short(layout: Layout, x) -> str:
    return ", ".join(f"{n}={v:.4g}" for n, v in zip(layout.names, x))
