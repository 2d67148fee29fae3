"""One candidate effect at one step: its best shape, cross-validated, and the evidence for it."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from identification.diagnosis.candidates import Fit, Term
from identification.diagnosis.fitting import Evaluated, StepContext
from identification.diagnosis.search import located_comparison, search_shape, shape_grid
from identification.diagnosis.statistics import block_scores, in_band, score


@dataclass(frozen=True, eq=False)
class CandidateScore:
    """One candidate at one step: its best-shape model and the evidence for it."""

    term: Term
    model: Evaluated | None
    added_params: int
    train_score: float            # primary training S
    cv_score: float               # cross-validated S over all samples
    improvement: float            # 1 - S_cv(candidate) / S_cv(base)
    holdout_improvement: float    # the same on the primary held-out fold only
    block_ratio: dict             # cross-validated S_cand / S_base per block (torque, cable)
    p_holdout: float              # Wilcoxon over chunks of the cross-validated residuals
    p_train: float                # F-test on the primary training folds
    valid: bool                   # physical sign of the fitted magnitudes
    significant: bool
    note: str = ""
    margins: dict = None           # distance to each threshold (statistics.Comparison.margins)
    margin: float = float("nan")   # the decision's margin in borderline bands (statistics.in_band)
    alpha: float = float("nan")    # the level its p values are held to (alpha / candidates of the step)

    @property
    def fit(self) -> Fit | None:
        return None if self.model is None else self.model.fit

    def to_dict(self) -> dict:
        return {"effect": self.term.name, **self.evidence()}

    def evidence(self) -> dict:
        """The JSON evidence: held-out (cross-validated) improvement, p values, sign, shape."""
        return {"holdout_improvement": self.improvement, "holdout_score_ratio": 1.0 - self.improvement,
                "primary_holdout_improvement": self.holdout_improvement,
                "holdout_ratio_by_block": self.block_ratio, "p_holdout_wilcoxon": self.p_holdout,
                "p_train_F": self.p_train, "added_parameters": self.added_params, "physical_sign": self.valid,
                "significant": self.significant, "shape": dict(self.term.shape), "note": self.note,
                "alpha": self.alpha, "margins": self.margins or {}, "margin_in_bands": self.margin,
                "borderline": self.borderline}

    @property
    def borderline(self) -> bool:
        """Within one borderline band of its decision (either side)."""
        return bool(abs(self.margin) < 1.0)


def sign_ok(fit: Fit, term: Term) -> tuple[bool, str]:
    """False when a clearly non-zero magnitude of ``term`` has the unphysical sign (the effect's
    ``sign_violation``): the candidate then only reshapes another effect."""
    symbols = [col.symbol for col in term.identification.columns if fit.has(col.symbol)]
    why = term.identification.sign_violation({s: fit.group(s) for s in symbols}, {s: fit.group_sigma(s) for s in symbols})
    why = why or term.identification.shape_violation(dict(term.shape))
    return not why, why


def evaluate_candidate(ctx: StepContext, name: str) -> CandidateScore:
    """Fit base + ``name`` with its shape parameters chosen on the primary training folds
    (:func:`~identification.diagnosis.search.search_shape`, or a bounded search per cable for the
    pretension), cross-validate it and test it against the base."""
    notes: list[str] = []
    cache: dict = {}

    def trial(term: Term):
        if term.shape not in cache:
            try:
                f = ctx.fit(ctx.base.fit.model.plus(term))
                cache[term.shape] = (score(f.residuals(), ctx.split.train, ctx.scales, ctx.data.n), term, f)
            except ValueError as exc:
                notes.append(str(exc))
                cache[term.shape] = None
        return cache[term.shape]

    best = search_shape(ctx, name, trial)
    if best is None:
        return CandidateScore(Term(name, shape_grid(name)[0]), None, 0, math.nan, math.nan, 0.0, 0.0, {}, 1.0, 1.0,
                              False, False, "not identifiable: " + (notes[0] if notes else "no fit"),
                              {}, -math.inf, ctx.alpha_candidate)
    _, term, fit = best
    ev = Evaluated(fit, ctx.cross_validate(fit))
    added = fit.n_params - ctx.base.fit.n_params + len(term.shape)
    cmp = located_comparison(ctx.compare(ctx.base, ev, added), term, ctx.data.n)
    every = np.ones(ctx.data.S, bool)
    bb = block_scores(ctx.base.cv, every, ctx.scales, ctx.data.n)
    bc = block_scores(ev.cv, every, ctx.scales, ctx.data.n)
    ratio = {k: (bc[k] / bb[k] if bb[k] > 0 else 1.0) for k in bb}
    valid, why = sign_ok(fit, term)
    margins = ctx.candidate_margins(cmp)
    s = ctx.settings
    return CandidateScore(term, ev, added, best[0], score(ev.cv, every, ctx.scales, ctx.data.n), cmp.improvement,
                          cmp.holdout_improvement, ratio, cmp.p_holdout, cmp.p_train, valid,
                          valid and ctx.candidate_significant(cmp), why, margins,
                          in_band(margins, s.borderline, s.borderline_decades) if valid else -np.inf,
                          ctx.alpha_candidate)

