"""One candidate effect at one step: its best shape, cross-validated, and the evidence for it."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from identification.diagnosis.candidates import Fit, Term, fit_model
from identification.diagnosis.fitting import Evaluated, StepContext
from identification.diagnosis.search import (_refine_between, located_comparison, refined_shape, search_one_joint,
                                              search_shape, shape_grid, training_p, trial_score)
from identification.diagnosis.materiality import CHANNEL_TESTS, OWN_CHANNEL, candidate_decision, own_comparison
from identification.diagnosis.support import log_support, separability_gap, unsupported_items
from identification.diagnosis.statistics import (Comparison, block_scores, channel_wilcoxon_p, clearly_nonzero,
                                                 explained_share, in_band, margin_ratio, score)


@dataclass(frozen=True)
class Separability:
    """How well the data separate one parameter of a candidate from the step's baseline: the share
    ``explained`` (R^2) of its weighted regressor column on the training folds that the baseline's
    columns already explain (:func:`~identification.diagnosis.statistics.explained_share`; for a
    searched shape parameter the column is the derivative of the weighted residuals with respect to
    it), the baseline parameters that explain most of it (``partners``), and whether it ``carries``
    the candidate (a clearly non-zero magnitude, or a searched magnitude such as a rest elongation
    or a delay: the parameters the verdict would rest on)."""

    name: str
    explained: float
    partners: tuple
    carries: bool
    where: str = "log"             # the cable or joint it acts on ("cable 3", "joint 2"), else "log"
    unsupported: bool = False      # that cable or joint has a gap that leaves the candidate without support

    @property
    def inflation(self) -> float:
        """Variance inflation against the baseline, 1 / (1 - R^2)."""
        return 1.0 / max(1.0 - self.explained, 1e-300)

    @property
    def angle_deg(self) -> float:
        """Angle between its column and the baseline's span (deg)."""
        return float(np.degrees(np.arcsin(np.sqrt(max(1.0 - self.explained, 0.0)))))

    def to_dict(self) -> dict:
        return {"parameter": self.name, "where": self.where, "explained_by_baseline": self.explained,
                "variance_inflation": self.inflation, "angle_deg": self.angle_deg, "partners": list(self.partners),
                "carries_the_candidate": self.carries, "gap_where_it_acts": self.unsupported}


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
    p_holdout: float              # held-out Wilcoxon: whole score, best or own channel (method_text)
    p_train: float                # F-test on the primary training folds
    valid: bool                   # physical sign of the fitted magnitudes
    significant: bool
    note: str = ""
    margins: dict = None           # distance to each threshold (statistics.Comparison.margins)
    margin: float = float("nan")   # the decision's margin in borderline bands (statistics.in_band)
    alpha: float = float("nan")    # the level its p values are held to (alpha / candidates of the step)
    separability: tuple = ()       # Separability of each parameter against the step's baseline
    max_explained: float = 1.0     # the share of a carrying parameter's column the baseline may explain
    passes_tests: bool = False     # improvement, both p values and the sign pass (separable or not)

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
                "borderline": self.borderline, "separability": [x.to_dict() for x in self.separability],
                "separable": self.separable, "max_explained_by_baseline": self.max_explained}

    @property
    def inseparable(self) -> tuple:
        """The parameters it rests on that the data cannot separate from the baseline: the
        baseline's columns explain them beyond ``max_explained``, or they act on a cable or joint
        whose gap leaves the candidate without support there."""
        return tuple(x for x in self.separability
                     if x.carries and (x.explained > self.max_explained or x.unsupported))

    @property
    def refused(self) -> bool:
        """It passes every test but the data cannot separate it from the baseline: not named."""
        return self.passes_tests and not self.separable

    def refusal(self, gaps, summary, support) -> tuple[str, tuple]:
        """Why a refused candidate is not named (one line) and the :class:`~identification.
        diagnosis.support.Gap` s that say what is missing and what to record: the log's gap where
        a parameter acts, else the conditioning gap of :func:`~identification.diagnosis.support.
        separability_gap`."""
        lines, out = [], []
        for x in self.inseparable:
            lines.append(f"{x.name} on {x.where}: {100 * x.explained:.1f} % of its column explained by "
                         f"{', '.join(x.partners) or 'the baseline'}" + (" (a gap there)" if x.unsupported else ""))
            here = [g for g in gaps if g.where == x.where and unsupported_items((g,), self.term.name)]
            out += here if x.unsupported and here else [
                separability_gap(self.term.name, x.name, x.where, x.explained, x.partners, summary, support)]
        note = (f"{self.term.name} passes its tests (improvement {100 * self.improvement:.1f} %) but is not named: "
                "the data cannot separate it from the baseline (" + "; ".join(lines) + ")")
        return note, tuple(out)

    def unseen(self, summary, support) -> tuple[str, tuple]:
        """What a candidate that fails its tests could not have shown: the parameters it rests on
        whose columns the baseline explains beyond ``max_explained`` (on a cable or joint without a
        gap of the log's own, which says it already) -- a note and one conditioning
        :class:`~identification.diagnosis.support.Gap` each; ("", ()) when there are none or when
        it passes its tests (then :meth:`refusal` speaks).  A rest elongation of the soft left
        cable that k(4) absorbs is not evidence of its absence: the log cannot show it."""
        if self.passes_tests:
            return "", ()
        hidden = [x for x in self.separability if x.carries and x.explained > self.max_explained and not x.unsupported]
        if not hidden:
            return "", ()
        note = (f"{self.term.name} could not be told from the baseline on these data: " + "; ".join(
            f"{x.name} on {x.where}, {100 * x.explained:.1f} % of its column explained by "
            f"{', '.join(x.partners) or 'the baseline'}" for x in hidden))
        return note, tuple(separability_gap(self.term.name, x.name, x.where, x.explained, x.partners, summary, support)
                           for x in hidden)

    @property
    def separable(self) -> bool:
        """The data separate every parameter it rests on from the baseline."""
        return not self.inseparable

    @property
    def borderline(self) -> bool:
        """Within one borderline band of its decision (either side)."""
        return bool(abs(self.margin) < 1.0)


def sign_ok(fit: Fit, term: Term, n_cables: int) -> tuple[bool, str]:
    """False when a clearly non-zero magnitude of ``term`` has the unphysical sign (the effect's
    ``sign_violation``): the candidate then only reshapes another effect.  A term on one cable is
    read with zeros on the others (the message names its cable)."""
    eff = term.identification
    cols = [col for col in eff.columns if fit.has(col.symbol)]
    cable = eff.cable_of(dict(term.shape))

    def every(col, v):
        return col.expand(v, 0, None, n_cables, cable)

    why = eff.sign_violation({c.symbol: every(c, fit.group(c.symbol)) for c in cols},
                             {c.symbol: every(c, fit.group_sigma(c.symbol)) for c in cols})
    why = why or term.identification.shape_violation(dict(term.shape))
    return not why, why


def _shape_names(term: Term) -> dict[str, tuple[str, float | None]]:
    """Shape key -> (report name, profile step) of ``term``'s shape: ``x0(3)`` for a per-cable key
    ``x0_3``, the key itself otherwise."""
    out = {}
    for key, _ in term.shape:
        sh = next((h for h in term.identification.shapes if h.per_cable and key.startswith(h.name + "_")), None)
        if sh is not None:
            out[key] = (f"{sh.name}({key[len(sh.name) + 1:]})", sh.profile_step)
        else:
            sh = next((h for h in term.identification.shapes if h.name == key), None)
            out[key] = (key, None if sh is None else sh.profile_step)
    return out


def _where(term: Term, name: str) -> str:
    """The cable or joint a parameter of ``term`` acts on: "cable 3" for ``x0(3)`` or ``c_v(3)``,
    "joint 2" for ``tau_j(2)`` or ``dk(2L)``, "log" for one acting everywhere."""
    if "(" not in name:
        return "log"
    index = name.split("(")[1].rstrip(")LR")
    col = next((c for c in term.identification.columns if c.symbol == name.split("(")[0]), None)
    return f"{'joint' if col is not None and col.per in ('joint', 'spring') else 'cable'} {index}"


def separability(ctx: StepContext, term: Term, fit: Fit) -> tuple[Separability, ...]:
    """Per parameter of ``term`` (fitted in ``fit`` on top of the step's baseline), how much of
    its column the baseline's columns explain on the training folds (:class:`Separability`).

    The linear parameters' columns are those of the candidate's last weighted pass; a searched
    shape parameter's column is the change of the weighted residuals (linear values held) over a
    small step of it (its ``profile_step``, else 1e-3 of its value), inward from a bound.  A
    candidate whose own magnitudes are linear rests on those; one without linear columns (a rest
    elongation, a delay, a dead band) rests on its searched values."""
    data, train = ctx.data, ctx.split.train
    try:
        full = fit_model(data, fit.model, train, ctx.scales, fit.state, iterations=1, keep_rows=True)
    except ValueError:
        return ()
    W, Y = full.rows
    base = set(ctx.base.fit.names)
    ib = [i for i, n in enumerate(full.names) if n in base]
    B = W[:, ib]
    base_names = [full.names[i] for i in ib]
    own = {col.symbol for col in term.identification.columns}
    cols, carries = {}, {}
    for sym in sorted(own):
        idx = [i for i, n in enumerate(full.names) if n not in base and n.split("(")[0] == sym]
        keep = clearly_nonzero(full.value[idx], full.sigma[idx]) if idx else []
        for i, k in zip(idx, keep):
            cols[full.names[i]], carries[full.names[i]] = W[:, i], bool(k)
    r0 = Y - W @ full.value
    bounds = {h.name: h.bounds for h in term.identification.shapes}
    for key, (label, step) in _shape_names(term).items():
        v = term.get(key)
        h = step or 1e-3 * max(abs(v), 1e-6)
        lo, hi = bounds.get(label.split("(")[0]) or (-np.inf, np.inf)
        h = -h if v + h > hi else h
        moved = Term(term.name, tuple((k, (x + h if k == key else x)) for k, x in term.shape))
        try:
            other = fit_model(data, fit.model.without(term.name).plus(moved), train, ctx.scales, fit.state,
                              iterations=1, keep_rows=True)
        except ValueError:
            continue
        if other.names != full.names:
            continue
        W2, Y2 = other.rows
        cols[label] = ((Y2 - W2 @ full.value) - r0) / h
        carries[label] = not own and v != 0
    _, gaps = log_support(data, ctx.settings.support)
    unsupported = unsupported_items(gaps, term.name)
    out = []
    for name, c in cols.items():
        r2, coef = explained_share(B, c)
        order = np.argsort(-np.abs(coef))[:2]
        where = _where(term, name)
        out.append(Separability(name, r2, tuple(base_names[i] for i in order if abs(coef[i]) > 0.1), carries[name],
                                where, where in unsupported))
    return tuple(out)


def channel_names(n_joints: int, n_cables: int) -> list[str]:
    """The residual channels' names in the (S, N + C) arrays' order."""
    return [f"joint torque {j + 1}" for j in range(n_joints)] + [f"cable {i + 1}" for i in range(n_cables)]


@dataclass(frozen=True)
class BestChannel:
    """The residual channel whose held-out Wilcoxon p stood in for the pooled one
    (:func:`channel_holdout`): its ``name``, the ``factor`` on its p (its N + C channels times the
    term's places) and the ``pooled`` p it beat (times the places)."""

    name: str
    factor: int
    pooled: float

    def note(self, p_holdout: float, tests: int = 1) -> str:
        """The candidate's note on its held-out test: ``p_holdout`` the p it reports, ``tests`` the
        factor applied to both p values since (:data:`~identification.diagnosis.materiality.
        CHANNEL_TESTS` for a one-joint term), counted in its places as in the pooled p."""
        return (f"held out on its best channel ({self.name}): Wilcoxon p {p_holdout:.2g} with "
                f"{tests * self.factor} places (pooled {min(1.0, tests * self.pooled):.2g})")


def channel_holdout(ctx: StepContext, ev: Evaluated, whole: Comparison, term: Term
                    ) -> tuple[Comparison, BestChannel | None]:
    """``whole`` (the candidate's comparison, p values times its places) with its held-out p the
    smaller of the pooled one and its best channel's (:func:`~identification.diagnosis.statistics.
    channel_wilcoxon_p`) times the N + C channels it may pick and its places (Bonferroni), and
    that channel (None when the pooled test stands).  An effect on one cable or joint
    shows on a few channels; pooled with the others' noise its held-out gain can fail the test its
    training F-test passes by decades (a Stribeck bump on cable 2 of a 12 s multisine: pooled p
    0.0013, joint torque 2 alone 2.5e-9).  The candidate still needs its improvement of the whole
    score and its training F-test on it, which bound its false-alarm level at alpha / K whatever
    the held-out test; a clean log's best channel is calibrated in docs/diagnosis.md."""
    if not ctx.settings.channel_holdout:
        return whole, None
    p = channel_wilcoxon_p(ctx.base.cv, ev.cv, ctx.split)
    k = int(np.argmin(p))
    factor = p.size * term.identification.places(dict(term.shape), ctx.data.n, ctx.data.C)
    p_best = min(1.0, factor * float(p[k]))
    if not p_best < whole.p_holdout:
        return whole, None
    return (dataclasses.replace(whole, p_holdout=p_best),
            BestChannel(channel_names(ctx.data.n, ctx.data.C)[k], factor, whole.p_holdout))


def held_out_note(channel: BestChannel | None, decided: Comparison, own: Comparison | None, own_note: str) -> str:
    """The note on a candidate's held-out test once :func:`~identification.diagnosis.materiality.
    candidate_decision` returned the comparison it is held to (``decided``, its note ``own_note``;
    ``own`` the own-channel comparison it was given): its best ``channel``'s sentence with the p
    ``decided`` reports, which for a one-joint term (``own`` not None) carries
    :data:`~identification.diagnosis.materiality.CHANNEL_TESTS` more; "" when the pooled test stood
    or the term is held to its own channel, whose p is then the one reported."""
    if channel is None or own_note.startswith(OWN_CHANNEL):
        return ""
    return channel.note(decided.p_holdout, 1 if own is None else CHANNEL_TESTS)


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
    cand = _scored(ctx, best)
    # every joint (cable) at once passed its training F-test but fails held out: its columns on
    # the joints without the effect fit noise there (a side spring's error on joint 2 of a 12 s
    # multisine: joint torque 2 99 % better held out, joints 1 and 3 41 % and 16 % worse; a
    # Stribeck bump on cable 2 beside a spring error: -13 % of S held out at step 2).  The one-joint
    # (one-cable) form, whose 2 N (2 C) places already pay for having tried both forms (Bonferroni:
    # alpha / 2 for every joint, alpha / 2N for each joint alone), is scored as well
    ident = best[1].identification
    for locates, key, search_one in ((ident.locates_joint, "joint", search_one_joint),
                                     (ident.locates_cable, "cable", search_one_cable_form)):
        if locates and best[1].get(key) is None and not cand.passes_tests:
            one = search_one(ctx, trial, name, best)
            if one is not None:
                alt = _scored(ctx, one)
                if (alt.passes_tests, alt.margin) > (cand.passes_tests, cand.margin):
                    cand = alt
    return cand


def one_cable_p_bound(ctx: StepContext, every) -> float:
    """A lower bound on the training F-test p (times its 2 C places: ``located_comparison``) of the
    one-cable form of the every-cable ``trial`` entry ``every``: the every-cable form's training
    gain over the step's baseline credited to one cable's parameters (the magnitudes of one cable,
    its shape keys and the cable).  One cable's columns cannot gain more than every cable's at the
    same shape, and a term passes only with that p below the candidate's level
    (:meth:`~identification.diagnosis.statistics.Comparison.significant`)."""
    s, term, fit = every
    per_cable = max(1, (fit.n_params - ctx.base.fit.n_params) // ctx.data.C)
    one = Term(term.name, tuple((dict(term.shape) | {"cable": 1.0}).items()))
    return min(1.0, training_p(ctx, s, ctx.base.fit.n_params + per_cable, one))


def search_one_cable_form(ctx: StepContext, trial, name: str, every):
    """Best ``trial`` entry of candidate ``name`` located on one cable (shape key ``cable``,
    ``EffectColumns.locates_cable``): the cable whose column alone fits best at the shape of
    ``every`` (the every-cable entry), then at that cable the shape grid and the refined shape
    (``Shape.refine``) between the best grid point's neighbours; None when nothing fits, and not
    searched (None) when that form could not pass its training F-test (:func:`one_cable_p_bound`:
    on a clean log the every-cable gain is noise and the C + grid + refine fits are spared)."""
    if not one_cable_p_bound(ctx, every) < ctx.alpha_candidate:
        return None

    def on(cable: int, shape) -> tuple:
        return tuple(sorted(tuple((k, v) for k, v in shape if k != "cable") + (("cable", cable),)))

    done = [e for e in (trial(Term(name, on(i + 1, every[1].shape))) for i in range(ctx.data.C)) if e is not None]
    if not done:
        return None
    cable = min(done, key=trial_score)[1].get("cable")
    done += [e for e in (trial(Term(name, on(cable, shape))) for shape in shape_grid(name)) if e is not None]
    best = min(done, key=trial_score)
    refine = refined_shape(name)
    return best if refine is None else min([best, _refine_between(trial, name, refine, refine.name, best)],
                                           key=trial_score)


def _scored(ctx: StepContext, best) -> CandidateScore:
    """The :class:`CandidateScore` of a searched entry ``best`` (training score, term, fit) of the
    step ``ctx``: cross-validated, tested against the step's baseline, its separability."""
    _, term, fit = best
    ev = Evaluated(fit, ctx.cross_validate(fit))
    added = ctx.added_params(fit.n_params, term)
    whole, channel = channel_holdout(ctx, ev, located_comparison(ctx.compare(ctx.base, ev, added), term,
                                                                  ctx.data.n, ctx.data.C), term)
    # a one-joint term is also measured where it acts (its joint's torque channel)
    own = own_comparison(ctx, ctx.base, ev, term, added)
    passes, cmp, margins, own_note = candidate_decision(ctx, whole, own)
    channel_note = held_out_note(channel, cmp, own, own_note)
    every = np.ones(ctx.data.S, bool)
    bb = block_scores(ctx.base.cv, every, ctx.scales, ctx.data.n)
    bc = block_scores(ev.cv, every, ctx.scales, ctx.data.n)
    ratio = {k: (bc[k] / bb[k] if bb[k] > 0 else 1.0) for k in bb}
    valid, why = sign_ok(fit, term, ctx.data.C)
    why = "; ".join(x for x in (why, own_note, channel_note) if x)
    s = ctx.settings
    sep = separability(ctx, term, fit)
    bound = s.support.max_explained
    carried = [x for x in sep if x.carries]
    if carried:
        # the share of its column the baseline leaves, against the least it must leave; a gap
        # where it acts is no matter of degree
        margins["separability"] = (-math.inf if any(x.unsupported for x in carried)
                                   else margin_ratio(1.0 - max(x.explained for x in carried), 1.0 - bound))
    separable = not any(x.explained > bound or x.unsupported for x in carried)
    passes = valid and passes
    return CandidateScore(term, ev, added, best[0], score(ev.cv, every, ctx.scales, ctx.data.n), cmp.improvement,
                          cmp.holdout_improvement, ratio, cmp.p_holdout, cmp.p_train, valid,
                          passes and separable, why, margins,
                          in_band(margins, s.borderline, s.borderline_decades) if valid else -np.inf,
                          ctx.alpha_candidate, sep, bound, passes)

