"""Shape search: grids, one-dimensional refinement, the rest elongation per cable, re-tuning."""

from __future__ import annotations

import math
from itertools import product

import numpy as np
from scipy import optimize

from identification.diagnosis.candidates import FitState, MeasuredData, ModelSpec, Term, fit_model, grid_of
from identification.diagnosis.fitting import StepContext, fit_baseline
from identification.diagnosis.materiality import own_train_ms, p_times
from identification.diagnosis.settings import DiagnosisSettings
from identification.diagnosis.split import Split
from identification.diagnosis import columns as effect_columns
from identification.diagnosis.columns import Shape
from identification.diagnosis.statistics import Comparison, effective_samples, f_test_p, score
from neck_sim.analytic.dynamics import cable_stiffness


def shape_grid(name: str) -> list[tuple]:
    """Every shape of candidate ``name`` on its grid (the product of its shape parameters' grids)."""
    grid = grid_of(name)
    if not grid:
        return [()]
    keys = sorted(grid)
    return [tuple(zip(keys, vals)) for vals in product(*(grid[k] for k in keys))]


def refined_shape(name: str) -> Shape | None:
    """The shape parameter of effect ``name`` refined by a bounded search between the best grid
    point's neighbours (``Shape.refine``: log scale for rates, linear for the delay), if any."""
    return next((sh for sh in effect_columns.get(name).shapes if sh.refine), None)


def minimise_bounded(f, lo: float, hi: float, xatol: float) -> float:
    """Minimiser of a 1-D function on [lo, hi] to about ``xatol`` (scipy's bounded Brent search)."""
    return float(optimize.minimize_scalar(f, bounds=(lo, hi), method="bounded", options={"xatol": xatol}).x)


def search_shape(ctx: StepContext, name: str, trial):
    """Best ``trial`` entry (score, term, fit) of candidate ``name``: per cable on a per-cable shape
    (:func:`search_per_cable_offset`), else over its shape grid with the refined shape
    (``Shape.refine``) then searched between the best grid point's neighbours (bounded, to 2 % of
    that interval on the shape's scale); None when nothing fits."""
    per_cable = next((sh for sh in effect_columns.get(name).shapes if sh.per_cable), None)
    if per_cable is not None and per_cable.search == "cable_law":
        return search_per_cable_offset(ctx, trial, name, per_cable)
    entries = [trial(Term(name, shape)) for shape in shape_grid(name)]
    done = [e for e in entries if e is not None]
    best = min(done, key=trial_score) if done else None
    refine = refined_shape(name)
    if refine is not None and best is not None:
        best = _refine_between(trial, name, refine, refine.name, best)
    if per_cable is not None:           # the shape on one cable at a time, kept when it fits better
        one = search_one_cable(ctx, trial, name, per_cable)
        done = [e for e in (best, one) if e is not None]
        best = min(done, key=trial_score) if done else None
    if effect_columns.get(name).locates_joint and best is not None \
            and not located_train_p(ctx, best) < ctx.alpha_candidate:
        # every joint at once does not pass: one joint alone, which does not spread the evidence
        # over N - 1 joints' noise.  Nested models, so not by training score (every joint's
        # columns always fit better) but by the training F-test, each p times its tests (places)
        one = search_one_joint(ctx, trial, name, best)
        if one is not None and located_train_p(ctx, one, bound=False) < located_train_p(ctx, best, bound=False):
            best = one
    return best


def _refine_between(trial, name: str, shape: Shape, key: str, best):
    """``best`` (a ``trial`` entry whose term sets ``key``) or the minimiser of the training score
    between the grid points on either side of its value (the term's other shape keys kept),
    whichever scores lower.  The value need not be on the grid: a one-cable search starts from the
    every-cable form's refined shape."""
    log_scale = shape.refine == "log"
    grid = sorted(shape.grid)
    v = best[1].get(key)
    below, above = [g for g in grid if g < v], [g for g in grid if g > v]
    lo = below[-1] if below else (0.0 if not log_scale else grid[0] / 2)
    hi = above[0] if above else 2 * grid[-1]
    to = (lambda u: float(np.exp(u))) if log_scale else (lambda u: u)
    a, b = (np.log(lo), np.log(hi)) if log_scale else (lo, hi)
    rest = tuple((k, v) for k, v in best[1].shape if k != key)

    def at(u):
        return trial(Term(name, rest + ((key, round(to(u), 6)),)))

    u = minimise_bounded(lambda u: trial_score(at(u)), a, b, 0.02 * (b - a))
    return min([best, at(u)], key=trial_score)


def search_one_joint(ctx: StepContext, trial, name: str, every):
    """Best ``trial`` entry of candidate ``name`` located on one joint (shape key ``joint``,
    ``EffectColumns.locates_joint``): the joint whose columns alone, at the shape of ``every`` (the
    every-joint entry), lower that joint's torque channel most in its band on the training folds
    (``materiality.own_train_ms``), then at that joint the refined shape (``Shape.refine``) on its
    grid and between the best grid point's neighbours (by training score); None when nothing fits."""
    rest = tuple((k, v) for k, v in every[1].shape if k != "joint")
    done = [e for e in (trial(Term(name, rest + (("joint", j + 1),))) for j in range(ctx.data.n)) if e is not None]
    if not done:
        return None
    # by the statistic the one-joint form is tested on (materiality.own_comparison), not by the
    # whole score, where the term's own channel is one of N + C (seed 3's 15.6 s hinge log of the
    # 10x4 neck: joint 10 by the whole score, the hidden joint 4 by its channel)
    best = min(done, key=lambda e: own_train_ms(ctx, e[2], [int(e[1].get("joint")) - 1])
               / max(own_train_ms(ctx, ctx.base.fit, [int(e[1].get("joint")) - 1]), 1e-300))
    refine = refined_shape(name)
    if refine is None:
        return best
    at = (("joint", best[1].get("joint")),)
    grid = [e for e in (trial(Term(name, at + ((refine.name, v),))) for v in refine.grid) if e is not None]
    if not grid:
        return best
    return min([best, _refine_between(trial, name, refine, refine.name, min(grid, key=trial_score))], key=trial_score)


def located_train_p(ctx: StepContext, entry, bound: bool = True) -> float:
    """The training F-test p of a ``trial`` entry against the step's baseline, as the candidate's
    comparison computes it (its shape keys counted as parameters), times the tests its term
    stands for (:func:`located_comparison`); ``bound=False``: not capped at 1 (two forms that both
    fail are still ordered)."""
    s, term, fit = entry
    p = training_p(ctx, s, fit.n_params, term)
    return min(1.0, p) if bound else p


def training_p(ctx: StepContext, train_score: float, n_params: int, term: Term) -> float:
    """The training F-test p against the step's baseline of a fit of ``term`` with ``n_params``
    parameters and training score ``train_score``, times the tests ``term`` stands for
    (``EffectColumns.places``); not capped at 1."""
    added = ctx.added_params(n_params, term)
    p = f_test_p(score(ctx.base.fit.residuals(), ctx.split.train, ctx.scales, ctx.data.n), train_score, added,
                 max(ctx.n_eff - n_params - added, 1))
    return p * term.identification.places(dict(term.shape), ctx.data.n, ctx.data.C)


def located_comparison(comparison: Comparison, term: Term, n_joints: int, n_cables: int) -> Comparison:
    """``comparison`` of a term against the step's baseline with both p values multiplied by the
    tests the term stands for (``EffectColumns.places``: Bonferroni over the two forms of an effect
    searched joint by joint and the N joints of its one-joint form, the same over cables for a
    motor-side term on one cable; unchanged for other terms):
    the best of N joints would pass a test at alpha about N times as often as one joint named in
    advance."""
    places = term.identification.places(dict(term.shape), n_joints, n_cables)
    return comparison if places == 1 else p_times(comparison, places)


def search_one_cable(ctx: StepContext, trial, name: str, shape: Shape):
    """Best ``trial`` entry of candidate ``name`` with its per-cable ``shape`` (``search="fit"``)
    non-zero on one cable only (key ``<shape.name>_<i>``): whole fits on ``shape.grid`` cable by
    cable, then refined linearly between the best grid point's neighbours; None when nothing fits."""
    entries = [trial(Term(name, ((f"{shape.name}_{j + 1}", v),))) for j in range(ctx.data.C) for v in shape.grid]
    done = [e for e in entries if e is not None]
    if not done:
        return None
    best = min(done, key=trial_score)
    key = best[1].shape[0][0]
    return _refine_between(trial, name, Shape(shape.name, shape.unit, grid=shape.grid, refine="linear"), key, best)


def trial_score(entry) -> float:
    """The training score of a ``trial`` entry (score, term, fit); inf for a failed fit (None)."""
    return math.inf if entry is None else entry[0]


def _cable_law_score(ctx: StepContext, j: int, offset) -> float:
    """Training mean square elongation error of cable j's law alone (eq 54 with x + offset, a
    scalar or (S,) m; k, lambda, c_a refitted with the weights 1 / (k + lambda t) iterated, the
    base's motor forces fixed), normalised by the cable's scale."""
    data, base = ctx.data, ctx.base.fit
    sel = data.taut[:, j] & ctx.split.train
    t = base.state.tension[sel, j]
    off = np.asarray(offset, dtype=float)
    x = data.x[sel, j] + (off[sel] if off.ndim else off)
    cols = [x, data.x_dot[sel, j]]
    stiffening = base.has("lambda")              # the model's cable law has eq (54)'s lambda
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


def search_per_cable_offset(ctx: StepContext, trial, name: str, shape: Shape):
    """Per cable, the shape value (``shape``, keys ``<shape.name>_<i>``, of effect ``name``: a rest
    elongation x_0, a dead band) whose elongation offset (``fit_cable_offset``) best fits that
    cable's law (bounded search on ``shape.bounds`` on the training folds);
    the term keeps the cables whose offset passes an F-test at 1 % on that cable's rows, else the
    best single cable; with ``shape.every_cable``, when that term passes its training F-test, also
    every cable at its value, the form with the smaller training F-test p kept (a play on every
    motor passes on no cable's law alone at 1 %)."""
    data = ctx.data
    offset = effect_columns.get(name).fit_cable_offset      # the trial offset of a shape value
    found = []
    for j in range(data.C):
        x = minimise_bounded(lambda v, j=j: _cable_law_score(ctx, j, offset(data, j, v)), *shape.bounds, xatol=1e-7)
        s0, s1 = _cable_law_score(ctx, j, 0.0), _cable_law_score(ctx, j, offset(data, j, x))
        n = max(effective_samples(int((data.taut[:, j] & ctx.split.train).sum()), data.prep.cutoffs["common"].hz,
                                  data.prep.rate_hz), 5)
        found.append((f_test_p(s0, s1, 1, n - 4), s1 / s0, j, round(x, 7)))
    keep = [(j, x) for p, _, j, x in found if p < 0.01] or [min(found, key=lambda e: e[1])[2:]]
    entry = trial(Term(name, tuple((f"{shape.name}_{j + 1}", x) for j, x in sorted(keep))))
    if shape.every_cable and len(keep) < data.C and entry is not None \
            and located_train_p(ctx, entry) < ctx.alpha_candidate:
        # every cable at its value, tried only once the kept cables pass their training F-test
        # (which bounds the false-alarm level whatever form is scored); nested forms, so kept by
        # that test's p (its shape keys counted), not by the training score
        every = trial(Term(name, tuple((f"{shape.name}_{j + 1}", x) for _, _, j, x in found)))
        if every is not None and located_train_p(ctx, every, bound=False) < located_train_p(ctx, entry, bound=False):
            entry = every
    return entry


def retune_shapes(data: MeasuredData, model: ModelSpec, split: Split, settings: DiagnosisSettings,
                  state: FitState | None, found: set) -> ModelSpec:
    """Re-search the refined shapes (``Shape.refine``: c_s, pulley c, delay) of the terms the
    diagnosis added, within ``Shape.span`` of their values (a factor on log scale, +- on linear),
    on the primary training score."""
    _, scales = fit_baseline(data, model, split, settings, state)
    for term in model.terms:
        shape = refined_shape(term.name)
        if term.name not in found or shape is None:
            continue
        key, log_scale, span = shape.name, shape.refine == "log", shape.span
        v0 = term.get(key)
        if v0 is None:              # the term uses another of its shapes (a delay on one motor)
            continue

        def with_value(v, term=term, key=key, model=model):
            t = Term(term.name, tuple((k, (v if k == key else x)) for k, x in term.shape))
            return ModelSpec(tuple(t if u is term else u for u in model.terms)), t

        def cost(u, with_value=with_value, log_scale=log_scale):
            v = round(float(np.exp(u)) if log_scale else u, 6)
            try:
                fit = fit_model(data, with_value(v)[0], split.train, scales, state, iterations=settings.iterations)
            except ValueError:
                return math.inf
            return score(fit.residuals(), split.train, scales, data.n)

        lo, hi = (np.log(v0 / span), np.log(span * v0)) if log_scale else (max(v0 - span, 0.0), v0 + span)
        u = minimise_bounded(cost, lo, hi, 0.02 * (hi - lo))
        u0 = np.log(v0) if log_scale else v0
        if cost(u) < cost(u0):
            model = with_value(round(float(np.exp(u)) if log_scale else u, 6))[0]
    return model
