"""One candidate effect at one step: its best shape, cross-validated, and the evidence for it."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from identification.candidates import SHAPE_GRIDS, Fit, Term
from identification.diagnosis.fitting import Evaluated, StepContext
from identification.diagnosis.search import REFINE, golden_section, search_pretension, shape_grid
from identification.diagnosis.statistics import block_scores, score


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

    @property
    def fit(self) -> Fit | None:
        return None if self.model is None else self.model.fit

    def evidence(self) -> dict:
        return {"holdout_improvement": self.improvement, "holdout_score_ratio": 1.0 - self.improvement,
                "primary_holdout_improvement": self.holdout_improvement,
                "holdout_ratio_by_block": self.block_ratio, "p_holdout_wilcoxon": self.p_holdout,
                "p_train_F": self.p_train, "added_parameters": self.added_params, "physical_sign": self.valid,
                "significant": self.significant, "shape": dict(self.term.shape), "note": self.note}


#: Magnitude parameters whose physical sign is fixed (a friction cannot push, a stiffness is > 0).
SIGNED = {"dry_friction": "f_s", "viscous_friction": "c_v", "stribeck_friction": "df", "pulley_friction": "mu",
           "cable_elasticity": "k", "tension_stiffening": "lambda", "payload": "payload"}


def sign_ok(fit: Fit, term: Term) -> tuple[bool, str]:
    """False when a clearly non-zero magnitude of ``term`` (|z| >= 4, at least 25 % of the largest)
    has the unphysical sign: the candidate then only reshapes another effect."""
    sym = SIGNED.get(term.name)
    if sym is None or not fit.has(sym):
        return True, ""
    v, s = fit.group(sym), fit.group_sigma(sym)
    strong = (np.abs(v) >= 4 * s) & (np.abs(v) >= 0.25 * np.abs(v).max())
    bad = strong & (v < 0)
    if bad.any():
        idx = ", ".join(str(i + 1) for i in np.nonzero(bad)[0])
        return False, f"fitted {sym} < 0 on {'cable' if v.size > 1 else 'the head'} {idx}: not a {term.name}"
    return True, ""


def evaluate_candidate(ctx: StepContext, name: str) -> CandidateScore:
    """Fit base + ``name`` with its shape parameters chosen on the primary training folds (a grid,
    refined by golden-section search for one-parameter shapes; a bounded search per cable of the
    pretension), cross-validate it and test it against the base."""
    notes: list[str] = []
    cache: dict = {}

    def trial(term: Term):
        if term.shape not in cache:
            try:
                f = ctx.fit(ctx.base.fit.model.plus(term))
                cache[term.shape] = (score(f.residuals(), ctx.split.train, ctx.scales), term, f)
            except ValueError as exc:
                notes.append(str(exc))
                cache[term.shape] = None
        return cache[term.shape]

    if name == "pretension":
        best = search_pretension(ctx, trial)
    else:
        for shape in shape_grid(name):
            trial(Term(name, shape))
        done = [v for v in cache.values() if v is not None]
        best = min(done, key=_value) if done else None
        if name in REFINE and best is not None:
            key, log_scale = REFINE[name]
            grid = sorted(SHAPE_GRIDS[name][key])
            i = grid.index(best[1].get(key))
            lo = grid[i - 1] if i > 0 else (0.0 if not log_scale else grid[0] / 2)
            hi = grid[i + 1] if i + 1 < len(grid) else 2 * grid[-1]
            to = (lambda u: float(np.exp(u))) if log_scale else (lambda u: u)
            a, b = (np.log(lo), np.log(hi)) if log_scale else (lo, hi)
            u = golden_section(lambda u: _value(trial(Term(name, ((key, round(to(u), 6)),)))), a, b, iterations=6)
            best = min([best, trial(Term(name, ((key, round(to(u), 6)),)))], key=_value)
    if best is None:
        return CandidateScore(Term(name, shape_grid(name)[0]), None, 0, math.nan, math.nan, 0.0, 0.0, {}, 1.0, 1.0,
                              False, False, "not identifiable: " + (notes[0] if notes else "no fit"))
    _, term, fit = best
    ev = Evaluated(fit, ctx.cross_validate(fit))
    added = fit.n_params - ctx.base.fit.n_params + len(term.shape)
    imp, imp_ho, p_cv, p_tr = ctx.compare(ctx.base, ev, added)
    every = np.ones(ctx.data.S, bool)
    bb = block_scores(ctx.base.cv, every, ctx.scales, ctx.data.n)
    bc = block_scores(ev.cv, every, ctx.scales, ctx.data.n)
    ratio = {k: (bc[k] / bb[k] if bb[k] > 0 else 1.0) for k in bb}
    valid, why = sign_ok(fit, term)
    return CandidateScore(term, ev, added, best[0], score(ev.cv, every, ctx.scales), imp, imp_ho, ratio, p_cv, p_tr,
                          valid, valid and ctx.passes(imp, p_cv, p_tr), why)


def _value(entry) -> float:
    return math.inf if entry is None else entry[0]
