"""Fitted parameters of a diagnosis: values with uncertainties and units, and where an effect acts."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from identification.diagnosis.candidates import Fit, Term
from identification.diagnosis.candidate import CandidateScore
from identification.diagnosis.fitting import StepContext
from identification.diagnosis.statistics import clearly_nonzero, score


#: How a linear parameter's sigma is computed: the diagnosis does not calibrate it the way
#: ``identify`` does (``identification.uncertainty``); benchmarks/bench_coverage.py measures its
#: coverage on payload logs.
EQ50_NOTE = "sigma: eq (50) of the weighted fit (independent residuals), not calibrated"
#: A magnitude corrected for the camera's angle noise (``errors_in_variables.corrected_parameters``).
SIMEX_NOTE = ("corrected for the camera's angle noise by simulation-extrapolation (errors_in_variables.py); "
              "sigma: eq (50) of the weighted fit, one noise realization's spread, the extrapolation's and its form's")
#: A hinge friction's size on a neck with fewer cables than joints (``hinge_size.hinge_interval``).
FORM_NOTE = "sigma: eq (50) of the weighted fit and the form error in quadrature"
#: How the summary labels a value by its note (:func:`note_label`).
NOTE_LABELS = {EQ50_NOTE: " (eq 50)", SIMEX_NOTE: " (SIMEX)", FORM_NOTE: " (includes form error)"}


def note_label(note: str) -> str:
    """The summary's label of a value whose note is, or ends with, one of :data:`NOTE_LABELS`'
    notes (a derived parameter's note ends with the note of the sigma it was scaled from); ""
    otherwise."""
    return next((label for known, label in NOTE_LABELS.items() if note.endswith(known)), "")


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


def _located(fit: Fit, term: Term, per: str) -> list[int] | None:
    """1-based items (``per`` = "cable" or "joint") whose magnitude (the effect's first column) is
    clearly non-zero; None when that column is not one per such item."""
    cols = term.identification.columns
    joint = term.identification.joint_of(dict(term.shape))
    if joint is not None:               # a located term: the joint its search chose
        return [joint] if per == "joint" else None
    cable = term.identification.cable_of(dict(term.shape))
    if cable is not None:               # the cable its search chose
        return [cable] if per == "cable" else None
    # per-spring magnitudes (2 per joint: left, right) locate joints
    items_per = {per: 1, "spring": 2} if per == "joint" else {per: 1}
    if not cols or cols[0].per not in items_per or not fit.has(cols[0].symbol):
        return None
    keep = clearly_nonzero(fit.group(cols[0].symbol), fit.group_sigma(cols[0].symbol))
    return sorted({int(i) // items_per[cols[0].per] + 1 for i in np.nonzero(keep)[0]})


def _per_cable_keys(term: Term) -> dict[str, tuple]:
    """Shape key -> (Shape, 1-based cable) for the per-cable shapes of ``term`` (rest elongations)."""
    out = {}
    for sh in term.identification.shapes:
        if sh.per_cable:
            out.update({k: (sh, int(k[len(sh.name) + 1:])) for k, _ in term.shape if k.startswith(sh.name + "_")})
    return out


def cables_of(fit: Fit, term: Term) -> list[int] | None:
    """1-based cables the effect concerns: per-cable magnitudes clearly non-zero
    (:func:`identification.diagnosis.statistics.clearly_nonzero`), the cables of a per-cable shape (pretension); None
    for effects not per cable."""
    keys = _per_cable_keys(term)
    if keys:
        return sorted(cable for _, cable in keys.values())
    return _located(fit, term, "cable")


def shape_located(cables: list[int] | None, parameters: dict[str, Parameter], term: Term) -> list[int] | None:
    """The cables of a per-cable shape (pretension) whose fitted value stands out: >= 2 profile
    sigmas and >= 25 % of the largest; the others were searched and kept but are not told apart
    from zero.  Other effects: ``cables`` unchanged."""
    keys = _per_cable_keys(term)
    if not keys or cables is None:
        return cables
    vals = {cable: parameters.get(f"{sh.name}({cable})") for sh, cable in keys.values()}
    known = {c: (p.value, p.sigma) for c, p in vals.items() if p is not None and p.sigma is not None}
    if len(known) != len(vals):                  # a value or its sigma missing: nothing told apart
        return cables
    order = sorted(known)
    v = np.abs([known[c][0] for c in order])
    # the profile sigma of a searched offset is wide (0.3-1 mm on a 12 s log): 2 sigma, and at
    # least a quarter of the largest offset
    keep = (v >= 2 * np.array([known[c][1] for c in order])) & (v >= 0.25 * v.max(initial=0.0))
    return [c for c, k in zip(order, keep) if k] or cables


def joints_of(fit: Fit, term: Term) -> list[int] | None:
    """1-based joints of an effect fitted per joint or per side spring (spring errors: the
    parameter names say which side, ``dk(2L)``), as :func:`cables_of`."""
    return _located(fit, term, "joint")


def profile_sigma(ctx: StepContext, term: Term, key: str, h: float, fit_score: float) -> float | None:
    """Standard deviation of a searched shape parameter from the curvature of the training score:
    S(v) ~ S* (1 + (v - v*)^2 / (n_eff sigma^2)), i.e. a unit change of chi^2."""
    v0 = term.get(key)
    if v0 is None:
        raise ValueError(f"profile_sigma: effect {term.name} has no shape parameter {key!r}")
    vals = []
    for v in (v0 - h, v0 + h):
        shape = tuple((k, (v if k == key else x)) for k, x in term.shape)
        try:
            f = ctx.fit(ctx.base.fit.model.plus(Term(term.name, shape)))
        except ValueError:
            return None
        vals.append(score(f.residuals(), ctx.split.train, ctx.scales, ctx.data.n))
    curv = (vals[0] + vals[1] - 2 * fit_score) / h ** 2
    if not curv > 0:
        return None
    return float(math.sqrt(2 * fit_score / (ctx.n_eff * curv)))


def term_parameters(ctx: StepContext, cand: CandidateScore) -> dict[str, Parameter]:
    """Fitted parameters of the candidate's term by name; shape parameters from the grid search
    have sigma None, except those with a ``Shape.profile_step`` (the delay, the rest elongations:
    profile of the training score)."""
    fit, term = chosen_fit(cand), cand.term
    sym = {col.symbol for col in term.identification.columns}
    out = {}
    for n, u, v, s in zip(fit.names, fit.units, fit.value, fit.sigma):
        if n.split("(")[0] in sym:
            out[n] = Parameter(float(v), float(s), u, EQ50_NOTE)
    per_cable = _per_cable_keys(term)
    shapes = {sh.name: sh for sh in term.identification.shapes}
    for k, v in term.shape:
        sh, name = (per_cable[k][0], f"{per_cable[k][0].name}({per_cable[k][1]})") if k in per_cable \
            else (shapes.get(k), k)
        if sh is not None and sh.profile_step is not None:
            out[name] = Parameter(float(v), profile_sigma(ctx, term, k, sh.profile_step, cand.train_score), sh.unit)
        else:
            out[name] = Parameter(float(v), None, sh.unit if sh else "", "shape parameter, grid search")
    fitted = {n: (p.value, p.sigma) for n, p in out.items()}
    derived = term.identification.derived_parameters(ctx.data.theta_dot_fast, fitted, dict(term.shape))
    for n, (value, sigma, unit, note) in derived.items():     # e.g. dry friction's f_travel
        # its sigma is scaled from the fitted ones: their note says how those were made
        out[n] = Parameter(float(value), None if sigma is None else float(sigma), unit,
                           note if sigma is None else f"{note}; {EQ50_NOTE}")
    return out


def chosen_fit(cand: CandidateScore) -> Fit:
    """The fit of a candidate that was fitted (a chosen one always is)."""
    if cand.fit is None:
        raise ValueError(f"candidate {cand.term.name}: no fitted model (its fit failed)")
    return cand.fit


def all_parameters(fit: Fit) -> dict[str, Parameter]:
    """Every parameter of a fitted model by name: the linear ones with their sigma, then the
    shape parameters as ``effect.key``."""
    out = {n: Parameter(float(v), float(s), u, EQ50_NOTE)
           for n, u, v, s in zip(fit.names, fit.units, fit.value, fit.sigma)}
    for t in fit.model.terms:
        for k, v in t.shape:
            out[f"{t.name}.{k}"] = Parameter(float(v), None, "", "shape parameter")
    return out
