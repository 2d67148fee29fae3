"""Forward selection, one step: every candidate, the encompassing test between look-alikes, the decision."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.candidates import REQUIRES, FitState, MeasuredData, ModelSpec
from identification.diagnosis.candidate import CandidateScore, evaluate_candidate
from identification.diagnosis.fitting import Evaluated, StepContext, fit_baseline
from identification.diagnosis.settings import DiagnosisSettings
from identification.diagnosis.split import Split


@dataclass(frozen=True, eq=False)
class Step:
    """One forward-selection step: its baseline, every candidate, the decision."""

    base: Evaluated
    scales: np.ndarray
    candidates: tuple
    verdict: object                # effect name, list of names (ambiguous), or "none"
    chosen: CandidateScore | None
    pairwise: tuple = ()           # encompassing tests: dicts

    @property
    def extended(self) -> Evaluated | None:
        return None if self.chosen is None else self.chosen.model


def encompass(ctx: StepContext, a: CandidateScore, b: CandidateScore) -> dict:
    """Fit base + A + B; does each add significantly to the other?"""
    try:
        both = ctx.evaluate(ctx.base.fit.model.plus(a.term).plus(b.term), a.fit.state)
    except ValueError as exc:
        return {"a": a.term.name, "b": b.term.name, "error": str(exc), "a_adds": False, "b_adds": False}
    imp_b, _, p_cv_b, p_tr_b = ctx.compare(a.model, both, b.added_params)
    imp_a, _, p_cv_a, p_tr_a = ctx.compare(b.model, both, a.added_params)
    b_adds = ctx.passes(imp_b, p_cv_b, p_tr_b, 0.5)
    a_adds = ctx.passes(imp_a, p_cv_a, p_tr_a, 0.5)
    return {"a": a.term.name, "b": b.term.name,
            "b_adds_to_a": {"improvement": imp_b, "p_holdout": p_cv_b, "p_train": p_tr_b, "significant": b_adds},
            "a_adds_to_b": {"improvement": imp_a, "p_holdout": p_cv_a, "p_train": p_tr_a, "significant": a_adds},
            "a_adds": a_adds, "b_adds": b_adds}


def decide(ctx: StepContext, cands) -> tuple[object, CandidateScore | None, tuple]:
    """(verdict, chosen candidate, pairwise tests) of one step.

    The leader is the significant candidate with the largest cross-validated improvement; every
    other significant candidate is tested against it by encompassing (see the module docstring).
    """
    sig = sorted([c for c in cands if c.significant], key=lambda c: -c.improvement)
    if not sig:
        return "none", None, ()
    best = sig[0]
    pairwise, tied = [], []
    for other in sig[1:]:
        test = encompass(ctx, best, other)
        pairwise.append(test)
        if test.get("b_adds") and not test.get("a_adds"):
            best = other                     # the other one explains all the leader does, and more
        elif not test.get("b_adds") and not test.get("a_adds"):
            tied.append(other)
    tied = [t for t in tied if t is not best]
    if tied:
        return [best.term.name] + [t.term.name for t in tied], best, tuple(pairwise)
    return best.term.name, best, tuple(pairwise)


def run_step(data: MeasuredData, model: ModelSpec, split: Split, settings: DiagnosisSettings,
             state: FitState | None = None, progress: bool = False, desc: str = "candidates") -> Step:
    """One diagnosis step from ``model``: baseline fit, every candidate, the decision."""
    from tqdm.auto import tqdm

    fit, scales = fit_baseline(data, model, split, settings, state)
    ctx = StepContext(data, split, settings, Evaluated(fit, np.zeros((data.S, data.n + data.C))), scales)
    ctx = StepContext(data, split, settings, Evaluated(fit, ctx.cross_validate(fit)), scales)
    names = [n for n in settings.candidates if not model.has(n) and (REQUIRES.get(n) is None or model.has(REQUIRES[n]))]
    cands = []
    for name in tqdm(names, desc=desc, unit="effect", disable=not progress, leave=False):
        cands.append(evaluate_candidate(ctx, name))
    verdict, chosen, pairwise = decide(ctx, cands)
    return Step(ctx.base, scales, tuple(cands), verdict, chosen, pairwise)
