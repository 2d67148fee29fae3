"""Shape search: grids, one-dimensional refinement, the rest elongation per cable, re-tuning."""

from __future__ import annotations

import math
from itertools import product

import numpy as np
from scipy import stats

from identification.candidates import SHAPE_GRIDS, FitState, MeasuredData, ModelSpec, Term, fit_model
from identification.diagnosis.fitting import StepContext, fit_baseline
from identification.diagnosis.settings import DiagnosisSettings
from identification.diagnosis.split import Split
from identification.diagnosis.statistics import score
from neck_sim.analytic.dynamics import cable_stiffness


def shape_grid(name: str) -> list[tuple]:
    grid = SHAPE_GRIDS.get(name)
    if not grid:
        return [()]
    keys = sorted(grid)
    return [tuple(zip(keys, vals)) for vals in product(*(grid[k] for k in keys))]


#: Shape parameters refined by golden-section search between the best grid point's neighbours
#: (log scale for rates, linear for the delay).
REFINE = {"dry_friction": ("c_s", True), "pulley_friction": ("c", True), "actuation_delay": ("delay", False)}


def golden_section(f, lo: float, hi: float, iterations: int = 10) -> float:
    """Minimiser of a 1-D function on [lo, hi] by golden-section search."""
    g = (math.sqrt(5) - 1) / 2
    a, b = lo, hi
    c, d = b - g * (b - a), a + g * (b - a)
    fc, fd = f(c), f(d)
    for _ in range(iterations):
        if fc < fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            fd = f(d)
    return c if fc < fd else d


#: Search range of the rest elongation of each cable (m).
PRETENSION_RANGE = (-1e-3, 5e-3)


def _cable_law_score(ctx: StepContext, j: int, x0: float) -> float:
    """Training mean square elongation error of cable j's law alone (eq 54 with x + x0; k, lambda,
    c_a refitted with the weights 1 / (k + lambda t) iterated, the base's motor forces fixed),
    normalised by the cable's scale."""
    data, base = ctx.data, ctx.base.fit
    sel = data.taut[:, j] & ctx.split.train
    t = base.state.tension[sel, j]
    x = data.x[sel, j] + x0
    cols = [x, data.x_dot[sel, j]]
    stiffening = base.model.has("tension_stiffening")
    if stiffening:
        cols.append(x * t)
    A = np.stack(cols, 1)
    k, lam = max(base.state.k[j], 1.0), max(base.state.lam[j], 0.0)
    for _ in range(3):
        w = 1.0 / cable_stiffness(t, k, lam)
        v, *_ = np.linalg.lstsq(A * w[:, None], t * w, rcond=None)
        k = max(v[0], 1.0)
        lam = max(v[2], 0.0) if stiffening else 0.0
    r = (t - A @ v) / cable_stiffness(t, k, lam)
    return float(np.mean(r ** 2) / ctx.scales[data.n + j] ** 2)


def search_pretension(ctx: StepContext, trial):
    """Per cable, the rest elongation x_0 that best fits that cable's law (bounded golden-section
    search on the training folds); the term keeps the cables whose offset passes an F-test at 1 %
    on that cable's rows, else the best single cable."""
    data = ctx.data
    fc = data.prep.cutoffs["common"].hz
    per = min(1.0, 2.0 * fc / data.prep.rate_hz)
    found = []
    for j in range(data.C):
        x = golden_section(lambda v, j=j: _cable_law_score(ctx, j, v), *PRETENSION_RANGE, iterations=14)
        s0, s1 = _cable_law_score(ctx, j, 0.0), _cable_law_score(ctx, j, x)
        n = max(int((data.taut[:, j] & ctx.split.train).sum() * per), 5)
        F = (s0 - s1) / max(s1 / (n - 4), 1e-300)
        found.append((float(stats.f.sf(F, 1, n - 4)) if s1 < s0 else 1.0, s1 / s0, j, round(x, 7)))
    keep = [(j, x) for p, _, j, x in found if p < 0.01] or [min(found, key=lambda e: e[1])[2:]]
    return trial(Term("pretension", tuple((f"x0_{j + 1}", x) for j, x in sorted(keep))))


def retune_shapes(data: MeasuredData, model: ModelSpec, split: Split, settings: DiagnosisSettings,
            state: FitState | None, found: set) -> ModelSpec:
    """Re-search the one-parameter shapes (c_s, pulley c, delay) of the terms the diagnosis added,
    within a factor 2 (5 ms for the delay) of their values, on the primary training score."""
    _, scales = fit_baseline(data, model, split, settings, state)
    for term in model.terms:
        if term.name not in found or term.name not in REFINE:
            continue
        key, log_scale = REFINE[term.name]
        v0 = term.get(key)

        def with_value(v, term=term, key=key, model=model):
            t = Term(term.name, tuple((k, (v if k == key else x)) for k, x in term.shape))
            return ModelSpec(tuple(t if u is term else u for u in model.terms)), t

        def cost(u, with_value=with_value, log_scale=log_scale):
            v = round(float(np.exp(u)) if log_scale else u, 6)
            try:
                fit = fit_model(data, with_value(v)[0], split.train, scales, state, iterations=settings.iterations)
            except ValueError:
                return math.inf
            return score(fit.residuals(), split.train, scales)

        lo, hi = (np.log(v0 / 2), np.log(2 * v0)) if log_scale else (max(v0 - 0.005, 0.0), v0 + 0.005)
        u = golden_section(cost, lo, hi, iterations=7)
        u0 = np.log(v0) if log_scale else v0
        if cost(u) < cost(u0):
            model = with_value(round(float(np.exp(u)) if log_scale else u, 6))[0]
    return model
