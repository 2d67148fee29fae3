"""The diagnosis from end to end: split, forward selection, gains, result."""

from __future__ import annotations

import dataclasses
import os
import time
from typing import TYPE_CHECKING, Sequence

import numpy as np

from identification.diagnosis.candidates import MeasuredData, plant_model
from identification.diagnosis.fitting import StepContext, fit_baseline
from identification.diagnosis.errors_in_variables import corrected_parameters
from identification.diagnosis.gains import AlphaHatErrors, alpha_hat_errors, residual_rms
from identification.diagnosis.dry_level import dry_level
from identification.diagnosis.hinge_size import hinge_interval
from identification.diagnosis.parameters import (all_parameters, cables_of, chosen_fit, joints_of, shape_located,
                                                  term_parameters)
from identification.diagnosis.resimulation import resimulate
from identification.diagnosis.result import Diagnosis, ExtendedModel, Finding, Gain, ModelSummary
from identification.diagnosis.search import retune_shapes
from identification.diagnosis.selection import Step, run_step
from identification.diagnosis.settled import settled_candidate, settled_fit
from identification.diagnosis.settings import DiagnosisSettings, ModelLike, parse_model
from identification.diagnosis.split import split_samples
from identification.diagnosis.structure import borrowed_names, leftover_structure
from identification.diagnosis.support import blocked_candidates, log_support, short_log_gap
from identification.preprocessing import Measurements
from identification.threads import single_thread
from neck_sim.analytic import UnreachableError
from neck_sim.params import NeckParams

if TYPE_CHECKING:
    from neck_sim.logs import Log


def diagnose(data: MeasuredData, model: ModelLike = None, settings: DiagnosisSettings | None = None, *,
             progress: bool = False, source: str = "") -> Diagnosis:
    """Diagnose prepared measured data from the baseline ``model`` (default: the paper's)."""
    with single_thread():
        return _diagnose(data, model, settings, progress=progress, source=source)


def _diagnose(data: MeasuredData, model: ModelLike, settings: DiagnosisSettings | None, *, progress: bool,
              source: str) -> Diagnosis:
    s = settings or DiagnosisSettings()
    spec = parse_model(model)
    timings: dict[str, float] = {}
    notes: list[str] = []
    t0 = time.perf_counter()
    summary, gaps = log_support(data, s.support)
    fatal = any(g.fatal for g in gaps)
    blocked = {} if fatal else blocked_candidates(gaps, data.C, data.n)
    if fatal:                  # the log cannot support a verdict: the baseline only, no candidate
        s = dataclasses.replace(s, candidates=(), max_steps=1)
        try:
            fit_baseline(data, spec, split_samples(data.t, data.activity, s), s, None)
        except ValueError as exc:    # too little for even the baseline: the gaps say why, no model
            return Diagnosis.without_fit(source, spec, s, gaps, summary, notes=(f"baseline not fitted: {exc}",),
                                         data=data)
    elif blocked:
        s = dataclasses.replace(s, candidates=tuple(c for c in s.candidates if c not in blocked))
        notes += [f"{name} not tried: {why}" for name, why in blocked.items()]
    split = split_samples(data.t, data.activity, s)
    steps: list[Step] = []
    current, state = spec, None
    for i in range(max(s.max_steps, 1)):
        if i > 0:
            # shapes searched at an earlier step were chosen without the effects found since
            current = retune_shapes(data, current, split, s, state,
                                   {st.chosen.term.name for st in steps if st.chosen is not None})
        step = run_step(data, current, split, s, state, progress=progress, desc=f"step {i + 1}: candidates")
        steps.append(step)
        if step.chosen is None:
            break
        fit = chosen_fit(step.chosen)
        current, state = fit.model, fit.state
    timings["search"] = time.perf_counter() - t0
    # candidates whose tests pass on parameters the data cannot separate: not named, and why; then
    # those that failed their tests on such parameters: the log could not show them
    candidates = [c for st in steps for c in st.candidates]
    for c, unseen in [(c, False) for c in candidates if c.refused] + [(c, True) for c in candidates]:
        # in turn: a refusal reads the gaps the ones before it added
        note, more = c.unseen(summary, s.support) if unseen else c.refusal(gaps, summary, s.support)
        if note:
            notes.append(note)
            gaps = gaps + tuple(g for g in more if g not in gaps)
    # models compared: each step's baseline and the last extension (if the last step found one)
    evaluated = [st.base for st in steps] + ([steps[-1].extended] if steps[-1].extended is not None else [])
    fits = [e.fit for e in evaluated]
    t1 = time.perf_counter()
    alpha: Sequence[AlphaHatErrors | None] = [None] * len(fits)
    if s.alpha_hat and data.C < data.n:
        notes.append(f"alpha_hat not evaluated: eq (35) needs at least as many cables as joints "
                     f"(this neck: {data.C} cables, {data.n} joints)")
    elif s.alpha_hat:
        try:
            alpha = alpha_hat_errors(data, fits, split.holdout)
        except UnreachableError as exc:        # the motors reach no pose: reported, not fatal
            notes.append(f"alpha_hat not evaluated: {exc}")
    timings["alpha_hat"] = time.perf_counter() - t1
    t1 = time.perf_counter()
    resim = {}
    if s.resimulate:
        for idx in sorted({0, len(fits) - 1}):
            p, e, rigid = plant_model(fits[idx], data.params)
            resim[idx] = resimulate(data, p, e, rigid, split, progress=progress)
    timings["resimulation"] = time.perf_counter() - t1
    every = np.ones(data.S, bool)
    summaries = [ModelSummary(ev.fit.model, all_parameters(ev.fit), residual_rms(data, ev.fit, ev.cv, every),
                              residual_rms(data, ev.fit, ev.fit.residuals(), split.holdout),
                              residual_rms(data, ev.fit, ev.fit.residuals(), split.train),
                              alpha[i], resim.get(i), ev.cv) for i, ev in enumerate(evaluated)]
    t1 = time.perf_counter()
    leftover = None if fatal else leftover_structure(data, fits[-1], evaluated[-1].cv, alpha[-1], s.structure,
                                                     named=any(st.chosen is not None for st in steps), band=s.borderline,
                                                     base_cv=evaluated[0].cv)
    if leftover is not None and leftover.significant:
        # a name beside the leftover must keep its gain without the leftover's structure
        lent, retests = borrowed_names(data, split, s, steps, leftover)
        leftover = dataclasses.replace(leftover, borrowed=lent, retests=retests)
    timings["structure"] = time.perf_counter() - t1
    findings = []
    for i, st in enumerate(steps):
        c = st.chosen
        if c is None:
            continue
        before = steps[i - 1].chosen if i > 0 else None       # the step's baseline started from its fit
        params = _finding_parameters(StepContext(data, split, s, st.base, st.scales), c,
                                     None if before is None else chosen_fit(before).state)
        findings.append(Finding(i + 1, st.verdict if isinstance(st.verdict, list) else c.term.name,
                                shape_located(cables_of(chosen_fit(c), c.term), params, c.term),
                                joints_of(chosen_fit(c), c.term), params, c,
                                Gain(summaries[i], summaries[i + 1]), () if leftover is None else leftover.found))
    # the extended model at the fixed point of its named terms, as their findings are read
    named = [st.chosen.term for st in steps if st.chosen is not None]
    final = settled_fit(StepContext(data, split, s, steps[-1].base, steps[-1].scales), fits[-1], named)
    return Diagnosis(source, spec, split, tuple(steps), tuple(findings), tuple(summaries),
                     ExtendedModel.of(final, data.params), timings, s, data, leftover, tuple(notes), gaps, summary)


def _finding_parameters(ctx: StepContext, cand, state) -> dict:
    """A named candidate's parameters read on its fit settled
    (:func:`identification.diagnosis.settled.settled_candidate`: its tension/stiffness iteration run
    until its own parameters stop moving; the verdict and the next step's baseline keep the fit as
    made, the extended model is settled alike), its magnitudes corrected for the camera's noise where its columns
    need it (:func:`identification.diagnosis.errors_in_variables.corrected_parameters`; ``state``
    the fit state the step's baseline started from; its replicates are refitted as the candidate
    was, with its passes, so the correction it extrapolates for the fit as made is added to the
    settled value: :func:`_simex_on_settled`), and a hinge friction's size on a neck with fewer
    cables than joints the middle of its estimates with their form error
    (:func:`identification.diagnosis.hinge_size.hinge_interval`), and a dry friction's f_s the level
    where the log's friction is flat when the log cannot tell that law from eq (37)
    (:func:`identification.diagnosis.dry_level.dry_level`), both on the settled fit."""
    settled = settled_candidate(ctx, cand)
    parameters = _simex_on_settled(ctx, cand, settled.fit, term_parameters(ctx, settled), state)
    return dry_level(ctx, settled, hinge_interval(ctx, settled, parameters))


def _simex_on_settled(ctx: StepContext, cand, settled, parameters: dict, state) -> dict:
    """``parameters`` (read on the fit ``settled``) with each magnitude SIMEX corrects
    (:func:`corrected_parameters` on ``cand``'s fit as made, whose estimator its replicates repeat)
    its corrected value plus the settling's move (settled minus as made); the others unchanged."""
    made = chosen_fit(cand)
    index = {n: k for k, n in enumerate(made.names)}
    as_made = {n: (dataclasses.replace(p, value=float(made.value[index[n]]), sigma=float(made.sigma[index[n]]))
                   if n in index else p) for n, p in parameters.items()}
    corrected = corrected_parameters(ctx, cand, as_made, state)
    out = dict(parameters)
    for n, p in corrected.items():
        if p is not as_made[n] and n in index:
            out[n] = dataclasses.replace(p, value=p.value + float(settled.value[index[n]] - made.value[index[n]]))
    return out


def diagnose_log(log: Log | str | os.PathLike, model: ModelLike = None, settings: DiagnosisSettings | None = None, *,
                 params: NeckParams | None = None,
                 progress: bool = False) -> Diagnosis:
    """:func:`diagnose` on a :class:`neck_sim.logs.Log` or a path: measured topics and the ``neck``
    record only (``/neck/truth``, ``/neck/reference``, ``/neck/estimate`` and the ``run`` record are
    never read)."""
    from neck_sim.logs import Log, read_log

    s = settings or DiagnosisSettings()
    if not isinstance(log, Log):
        log = read_log(log, topics=("motors", "camera"), require=("motors", "camera"))
    span = short_log_gap(log, s.support)
    if span is not None:        # too short to filter: no verdict, and why
        return Diagnosis.without_fit(os.fspath(log.path), parse_model(model), s, (span,), None,
                                     notes=tuple(f"input: {w}" for w in log.warnings))
    t0 = time.perf_counter()
    with single_thread():
        data = MeasuredData(Measurements.from_log(log), params or log.params, s.preprocess)
    t_prep = time.perf_counter() - t0
    diag = diagnose(data, model, s, progress=progress, source=os.fspath(log.path))
    diag.timings["preprocessing"] = t_prep
    if log.warnings:      # what the reader accepted on request travels with every output of the diagnosis
        diag = dataclasses.replace(diag, notes=tuple(f"input: {w}" for w in log.warnings) + diag.notes)
    return diag
