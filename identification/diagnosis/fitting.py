"""Model fitting of one step: the baseline, cross-validated residuals, the comparison of two models."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.diagnosis.candidates import Fit, FitState, MeasuredData, ModelSpec, fit_model
from identification.diagnosis.settings import DiagnosisSettings
from identification.diagnosis.split import Split
from identification.diagnosis.statistics import (Comparison, chunk_reductions, effective_samples, f_test_p,
                                                 improvement, mean_square, score, wilcoxon_p)


@dataclass(frozen=True, eq=False)
class Evaluated:
    """A model fitted on the primary training folds (``fit``) and its cross-validated residuals
    ``cv`` (S, N + C): each block predicted by the model fitted on the other folds."""

    fit: Fit
    cv: np.ndarray


class StepContext:
    """Everything one step of the search shares: data, split, scales, the step's baseline."""

    def __init__(self, data: MeasuredData, split: Split, settings: DiagnosisSettings, base: Evaluated,
                 scales: np.ndarray, family: int = 1):
        self.data, self.split, self.settings, self.base, self.scales = data, split, settings, base, scales
        # the candidates of a step are ``family`` tests of one question ("is anything missing?"):
        # each is held to alpha / family (Bonferroni), the step's false-alarm level stays alpha
        self.family = max(int(family), 1)
        self.alpha_candidate = settings.alpha / self.family
        # effective samples of the training folds, over every channel (the residuals are low-passed)
        n = effective_samples(int(split.train.sum()), data.prep.cutoffs["common"].hz, data.prep.rate_hz)
        self.n_eff = max(n * len(scales), 10)

    def fit(self, model: ModelSpec, state: FitState | None = None, train: np.ndarray | None = None) -> Fit:
        return fit_model(self.data, model, self.split.train if train is None else train, self.scales,
                         state or self.base.fit.state, iterations=self.settings.iterations)

    def cross_validate(self, fit: Fit) -> np.ndarray:
        """Residuals (S, N + C) with each fold predicted by the model fitted on the others."""
        res = fit.residuals().copy()
        for f in range(self.split.n_folds):
            if f == 1:
                continue                      # the primary fit already holds fold 1 out
            other = fit_model(self.data, fit.model, self.split.fold != f, self.scales, fit.state,
                              iterations=self.settings.iterations)
            sel = self.split.fold == f
            res[sel] = other.residuals()[sel]
        return res

    def evaluate(self, model: ModelSpec, state: FitState | None = None) -> Evaluated:
        fit = self.fit(model, state)
        return Evaluated(fit, self.cross_validate(fit))

    def added_params(self, n_params: int, term) -> int:
        """Parameters a term adds over this step's baseline: the columns of a fit with ``n_params``
        beyond the baseline's, and the term's shape keys (searched, so counted)."""
        return n_params - self.base.fit.n_params + len(term.shape)

    def compare(self, ref: Evaluated, cand: Evaluated, added: int) -> Comparison:
        """``cand`` against ``ref`` (both of this step's split), ``added`` parameters more."""
        sc, split, n = self.scales, self.split, self.data.n
        every = np.ones(self.data.S, bool)
        dof = max(self.n_eff - cand.fit.n_params - added, 1)
        return Comparison(
            improvement=improvement(score(ref.cv, every, sc, n), score(cand.cv, every, sc, n)),
            holdout_improvement=improvement(score(ref.cv, split.holdout, sc, n), score(cand.cv, split.holdout, sc, n)),
            p_holdout=wilcoxon_p(chunk_reductions(ref.cv, cand.cv, split, sc, n)),
            p_train=f_test_p(score(ref.fit.residuals(), split.train, sc, n), score(cand.fit.residuals(), split.train, sc, n),
                             added, dof))

    def significant(self, comparison: Comparison, factor: float = 1.0) -> bool:
        """The comparison passes this diagnosis' tests at level alpha (one targeted test, as the
        encompassing tests between two candidates; ``factor`` scales the minimum improvement)."""
        return comparison.significant(self.settings.alpha, factor * self.settings.min_improvement)

    def candidate_significant(self, comparison: Comparison) -> bool:
        """A candidate against the step's baseline: the tests at ``alpha / family``."""
        return comparison.significant(self.alpha_candidate, self.settings.min_improvement)

    def candidate_margins(self, comparison: Comparison) -> dict:
        """The candidate's margins to the thresholds it is held to (:meth:`Comparison.margins`)."""
        return comparison.margins(self.alpha_candidate, self.settings.min_improvement)


def channel_scales(data: MeasuredData, res: np.ndarray, train: np.ndarray) -> np.ndarray:
    """(N + C,) training RMS per channel of residuals (S, N + C), floored at 1e-4 N m and 1e-6 m."""
    rms = np.sqrt(mean_square(res, train))
    floor = np.concatenate([np.full(data.n, 1e-4), np.full(data.C, 1e-6)])   # N m, m
    return np.maximum(rms, floor)


def fit_baseline(data: MeasuredData, model: ModelSpec, split: Split, settings: DiagnosisSettings,
                 state: FitState | None) -> tuple[Fit, np.ndarray]:
    """Fit the step's baseline twice: the second pass weights channels by the first's RMS."""
    y = data.observations()[1]
    first = np.concatenate([data.torque_observation(y), np.where(data.taut, data.x, np.nan)], axis=1)
    scales = np.maximum(np.nan_to_num(np.sqrt(mean_square(first, split.train)), nan=1.0), 1e-6)
    fit = fit_model(data, model, split.train, scales, state, iterations=settings.iterations)
    scales = channel_scales(data, fit.residuals(), split.train)
    fit = fit_model(data, model, split.train, scales, fit.state, iterations=settings.iterations)
    return fit, channel_scales(data, fit.residuals(), split.train)
