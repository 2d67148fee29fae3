"""The result of a diagnosis: findings, parameters with uncertainties, the extended model, JSON."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from identification.candidates import Fit, MeasuredData, ModelSpec, Term, plant_model
from identification.diagnosis.candidate import CandidateScore
from identification.diagnosis.fitting import StepContext
from identification.diagnosis.selection import Step
from identification.diagnosis.settings import DiagnosisSettings
from identification.diagnosis.split import Split
from identification.diagnosis.statistics import score
from neck_sim.atomic import atomic_write_json
from neck_sim.atomic import jsonable as _jsonable
from neck_sim.params import NeckParams, to_dict


MAGNITUDE = {"dry_friction": "f_s", "viscous_friction": "c_v", "stribeck_friction": "df", "pulley_friction": "mu",
              "cable_elasticity": "k", "tension_stiffening": "lambda"}


def cables_of(fit: Fit, term: Term) -> list[int] | None:
    """1-based cables the effect concerns: per-cable magnitudes clearly non-zero (|z| >= 4 and at
    least 25 % of the largest), the cables of a pretension; None for effects not per cable."""
    if term.name == "pretension":
        return sorted(int(k[3:]) for k, _ in term.shape if k.startswith("x0_"))
    sym = MAGNITUDE.get(term.name)
    if sym is None or not fit.has(sym):
        return None
    v, s = fit.group(sym), fit.group_sigma(sym)
    keep = (np.abs(v) >= 4 * s) & (np.abs(v) >= 0.25 * np.abs(v).max())
    return [int(i) + 1 for i in np.nonzero(keep)[0]]


def joints_of(fit: Fit, term: Term) -> list[int] | None:
    if term.name != "spring_error" or not fit.has("dk"):
        return None
    v, s = fit.group("dk"), fit.group_sigma("dk")
    keep = (np.abs(v) >= 4 * s) & (np.abs(v) >= 0.25 * np.abs(v).max())
    return [int(i) + 1 for i in np.nonzero(keep)[0]]


def _profile_sigma(ctx: StepContext, term: Term, key: str, h: float, fit_score: float) -> float | None:
    """Standard deviation of a searched shape parameter from the curvature of the training score:
    S(v) ~ S* (1 + (v - v*)^2 / (n_eff sigma^2)), i.e. a unit change of chi^2."""
    v0 = term.get(key)
    vals = []
    for v in (v0 - h, v0 + h):
        shape = tuple((k, (v if k == key else x)) for k, x in term.shape)
        try:
            f = ctx.fit(ctx.base.fit.model.plus(Term(term.name, shape)))
        except ValueError:
            return None
        vals.append(score(f.residuals(), ctx.split.train, ctx.scales))
    curv = (vals[0] + vals[1] - 2 * fit_score) / h ** 2
    if not curv > 0:
        return None
    return float(math.sqrt(2 * fit_score / (ctx.n_eff * curv)))


def term_parameters(ctx: StepContext, cand: CandidateScore) -> dict:
    """Fitted parameters of the candidate's term: name -> {value, sigma, unit}; shape parameters
    from the grid search have sigma None, except the delay and the rest elongations (profile)."""
    fit, term = cand.fit, cand.term
    sym = {"dry_friction": ("f_s",), "viscous_friction": ("c_v",), "stribeck_friction": ("df",),
           "pulley_friction": ("mu",), "cable_elasticity": ("k", "c_a"), "tension_stiffening": ("lambda",),
           "payload": ("payload",), "spring_error": ("dk",)}.get(term.name, ())
    out = {}
    for n, u, v, s in zip(fit.names, fit.units, fit.value, fit.sigma):
        if n.split("(")[0] in sym:
            out[n] = {"value": float(v), "sigma": float(s), "unit": u}
    for k, v in term.shape:
        if k == "delay":
            out["delay"] = {"value": float(v), "sigma": _profile_sigma(ctx, term, k, 5e-4, cand.train_score),
                            "unit": "s"}
        elif k.startswith("x0_"):
            out[f"x0({k[3:]})"] = {"value": float(v), "sigma": _profile_sigma(ctx, term, k, 1e-4, cand.train_score),
                                   "unit": "m"}
        else:
            unit = {"c_s": "s/rad", "c": "s/rad", "speed": "rad/s", "smoothing": "rad/s"}.get(k, "")
            out[k] = {"value": float(v), "sigma": None, "unit": unit, "note": "shape parameter, grid search"}
    return out


def all_parameters(fit: Fit) -> dict:
    out = {n: {"value": float(v), "sigma": float(s), "unit": u}
           for n, u, v, s in zip(fit.names, fit.units, fit.value, fit.sigma)}
    for t in fit.model.terms:
        for k, v in t.shape:
            out[f"{t.name}.{k}"] = {"value": float(v), "sigma": None, "unit": "", "note": "shape parameter"}
    return out


@dataclass(frozen=True, eq=False)
class Diagnosis:
    """The whole diagnosis of one log (see :meth:`to_dict` for the stable JSON fields).

    ``steps``: the forward-selection steps; ``findings``: one dict per accepted effect;
    ``baseline``/``final``: summaries (parameters, residual RMS, alpha_hat and re-simulation
    errors) of the starting and the final model; ``extended``: the final model as terms, plant
    parameters and effects; ``series``: arrays for the plots.
    """

    source: str
    model: ModelSpec
    split: Split
    steps: tuple
    findings: tuple
    baseline: dict
    final: dict
    extended: dict
    timings: dict
    data: MeasuredData | None = None
    series: dict = field(default_factory=dict)
    settings: DiagnosisSettings | None = None

    @property
    def verdict(self):
        return self.steps[0].verdict if self.steps else "none"

    def to_dict(self) -> dict:
        return _jsonable({"verdict": self.verdict, "findings": list(self.findings), "baseline": self.baseline,
                          "final": self.final, "extended_model": self.extended,
                          "steps": [step_dict(s, i) for i, s in enumerate(self.steps)],
                          "split": self.split.to_dict(), "source": self.source, "timings_s": self.timings,
                          "method": METHOD})

    def write_json(self, path) -> None:
        atomic_write_json(path, self.to_dict())

    def write_model(self, path) -> None:
        """The final model (terms, plant parameters, effects) as JSON; ``--model`` reads it back."""
        atomic_write_json(path, self.extended)


METHOD = {
    "split": "contiguous blocks of about 3 moves cut in holds, assigned to 3 folds in turn; residuals "
             "cross-validated (each block predicted by the model fitted on the other folds); the primary "
             "split trains on folds 0 and 2 and holds fold 1 out (alpha_hat, re-simulation, written model)",
    "score": "S = per channel (N torque, N+1 elongation) mean square residual / (primary baseline training "
             "RMS)^2, averaged within each residual type, then over the two types",
    "significance": "cross-validated improvement 1 - S_cand/S_base >= min_improvement (0.02), one-sided "
                    "Wilcoxon signed-rank test over 0.25 s chunks p < alpha (0.01), training F-test counting the "
                    "added linear and searched shape parameters (one effective sample per 1/(2 f_c) s per "
                    "channel) p < alpha, fitted magnitudes of physical sign",
    "look_alikes": "encompassing test between the leader and every other significant candidate: fitted "
                   "together, the one that adds nothing significant to the other is dropped; if neither adds, "
                   "the verdict lists both (ambiguous)",
}


def step_dict(step: Step, i: int) -> dict:
    return {"step": i + 1, "model": step.base.fit.model.to_list(), "description": step.base.fit.model.describe(),
            "verdict": step.verdict,
            "candidates": [{"effect": c.term.name, **c.evidence()} for c in
                           sorted(step.candidates, key=lambda c: -c.improvement)],
            "pairwise": list(step.pairwise)}


def extended_dict(fit: Fit, nominal: NeckParams) -> dict:
    params, effects, rigid = plant_model(fit, nominal)
    return {"model": fit.model.to_list(), "description": fit.model.describe(), "rigid_cables": rigid,
            "params": to_dict(params), "effects": effects.to_dict(), "parameters": all_parameters(fit)}
