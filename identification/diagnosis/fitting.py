"""Model fitting of one step: the baseline, cross-validated residuals, the comparison of two models."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from identification.candidates import Fit, FitState, MeasuredData, ModelSpec, fit_model
from identification.diagnosis.settings import DiagnosisSettings
from identification.diagnosis.split import Split
from identification.diagnosis.statistics import chunk_reductions, mean_square, score, wilcoxon_p


@dataclass(frozen=True, eq=False)
class Evaluated:
    """A model fitted on the primary training folds (``fit``) and its cross-validated residuals
    ``cv`` (S, N + C): each block predicted by the model fitted on the other folds."""

    fit: Fit
    cv: np.ndarray


class StepContext:
    """Everything one step of the search shares: data, split, scales, the step's baseline."""

    def __init__(self, data: MeasuredData, split: Split, settings: DiagnosisSettings, base: Evaluated,
                 scales: np.ndarray):
        self.data, self.split, self.settings, self.base, self.scales = data, split, settings, base, scales
        self.base_train = score(base.fit.residuals(), split.train, scales)
        self.base_cv = score(base.cv, np.ones(data.S, bool), scales)
        self.base_ho = score(base.cv, split.holdout, scales)
        # effective samples: one per 1/(2 f_c) s and channel (the residuals are low-passed at f_c)
        fc = data.prep.cutoffs["common"].hz
        per = min(1.0, 2.0 * fc / data.prep.rate_hz)
        self.n_eff = max(int(split.train.sum() * per) * len(scales), 10)

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

    def compare(self, ref: Evaluated, cand: Evaluated, added: int) -> tuple:
        """(improvement, primary held-out improvement, p_cv, p_train) of ``cand`` over ``ref``."""
        sc = self.scales
        every = np.ones(self.data.S, bool)
        s_ref, s_c = score(ref.cv, every, sc), score(cand.cv, every, sc)
        imp = 1.0 - s_c / s_ref if s_ref > 0 else 0.0
        h_ref, h_c = score(ref.cv, self.split.holdout, sc), score(cand.cv, self.split.holdout, sc)
        imp_ho = 1.0 - h_c / h_ref if h_ref > 0 else 0.0
        p_cv = wilcoxon_p(chunk_reductions(ref.cv, cand.cv, self.split, sc))
        t_ref = score(ref.fit.residuals(), self.split.train, sc)
        t_c = score(cand.fit.residuals(), self.split.train, sc)
        dof = max(self.n_eff - cand.fit.n_params - added, 1)
        if added > 0 and t_c < t_ref:
            F = ((t_ref - t_c) / added) / (t_c / dof)
            p_tr = float(stats.f.sf(F, added, dof))
        else:
            p_tr = 1.0
        return imp, imp_ho, p_cv, p_tr

    def passes(self, imp: float, p_cv: float, p_tr: float, factor: float = 1.0) -> bool:
        s = self.settings
        return imp >= factor * s.min_improvement and p_cv < s.alpha and p_tr < s.alpha


def channel_scales(data: MeasuredData, res: np.ndarray, train: np.ndarray) -> np.ndarray:
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
