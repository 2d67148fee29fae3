"""Fitted parameters of a diagnosis: values with uncertainties and units, and where an effect acts."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from identification.candidates import Fit, Term
from identification.diagnosis.candidate import CandidateScore
from identification.diagnosis.fitting import StepContext
from identification.diagnosis.statistics import clearly_nonzero, score


@dataclass(frozen=True)
class Parameter:
    """A fitted value with its standard deviation (None when not estimated), unit and a note."""

    value: float
    sigma: float | None
    unit: str
    note: str = ""

    def to_dict(self) -> dict:
        out = {"value": self.value, "sigma": self.sigma, "unit": self.unit}
        if self.note:
            out["note"] = self.note
        return out


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
    keep = clearly_nonzero(fit.group(sym), fit.group_sigma(sym))
    return [int(i) + 1 for i in np.nonzero(keep)[0]]


def joints_of(fit: Fit, term: Term) -> list[int] | None:
    """1-based joints a spring error concerns (clearly non-zero ``dk``); None for other effects."""
    if term.name != "spring_error" or not fit.has("dk"):
        return None
    keep = clearly_nonzero(fit.group("dk"), fit.group_sigma("dk"))
    return [int(i) + 1 for i in np.nonzero(keep)[0]]


def profile_sigma(ctx: StepContext, term: Term, key: str, h: float, fit_score: float) -> float | None:
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


def term_parameters(ctx: StepContext, cand: CandidateScore) -> dict[str, Parameter]:
    """Fitted parameters of the candidate's term by name; shape parameters from the grid search
    have sigma None, except the delay and the rest elongations (profile of the training score)."""
    fit, term = cand.fit, cand.term
    sym = {"dry_friction": ("f_s",), "viscous_friction": ("c_v",), "stribeck_friction": ("df",),
           "pulley_friction": ("mu",), "cable_elasticity": ("k", "c_a"), "tension_stiffening": ("lambda",),
           "payload": ("payload",), "spring_error": ("dk",)}.get(term.name, ())
    out = {}
    for n, u, v, s in zip(fit.names, fit.units, fit.value, fit.sigma):
        if n.split("(")[0] in sym:
            out[n] = Parameter(float(v), float(s), u)
    for k, v in term.shape:
        if k == "delay":
            out["delay"] = Parameter(float(v), profile_sigma(ctx, term, k, 5e-4, cand.train_score), "s")
        elif k.startswith("x0_"):
            out[f"x0({k[3:]})"] = Parameter(float(v), profile_sigma(ctx, term, k, 1e-4, cand.train_score), "m")
        else:
            unit = {"c_s": "s/rad", "c": "s/rad", "speed": "rad/s", "smoothing": "rad/s"}.get(k, "")
            out[k] = Parameter(float(v), None, unit, "shape parameter, grid search")
    return out


def all_parameters(fit: Fit) -> dict[str, Parameter]:
    """Every parameter of a fitted model by name: the linear ones with their sigma, then the
    shape parameters as ``effect.key``."""
    out = {n: Parameter(float(v), float(s), u) for n, u, v, s in zip(fit.names, fit.units, fit.value, fit.sigma)}
    for t in fit.model.terms:
        for k, v in t.shape:
            out[f"{t.name}.{k}"] = Parameter(float(v), None, "", "shape parameter")
    return out
