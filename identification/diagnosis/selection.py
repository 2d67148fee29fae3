"""Forward selection, one step: every candidate, the encompassing test between look-alikes, the decision."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

from identification.diagnosis.candidates import FitState, MeasuredData, ModelSpec, Term, fit_model
from neck_sim import effects as effect_registry
from identification.diagnosis.candidate import CandidateScore, evaluate_candidate
from identification.diagnosis.columns import MotorColumns
from identification.diagnosis.fitting import Evaluated, StepContext, fit_baseline
from identification.diagnosis.settings import DiagnosisSettings
from identification.diagnosis.split import Split
from identification.diagnosis.statistics import Comparison, clearly_nonzero, encompassing_outcome


@dataclass(frozen=True, eq=False)
class Step:
    """One forward-selection step: its baseline, every candidate, the decision."""

    base: Evaluated
    scales: np.ndarray
    candidates: tuple
    verdict: object                # effect name, list of names (ambiguous), or "none"
    chosen: CandidateScore | None
    pairwise: tuple = ()           # EncompassingTest between the leader and the other significant ones

    @property
    def look_alike_where(self) -> str:
        """" on cable i" when the step's look-alikes were compared on one cable (``EncompassingTest.cable``)."""
        cables = {t.cable for t in self.pairwise if t.cable is not None}
        return f" on cable {cables.pop()}" if len(cables) == 1 else ""

    @property
    def separation(self) -> "EncompassingTest | None":
        """The one-cable test whose two laws were not separated and whose columns' angle was
        measured (:func:`separating_angle`), None otherwise."""
        return next((t for t in self.pairwise if t.angle_deg is not None), None)

    @property
    def extended(self) -> Evaluated | None:
        return None if self.chosen is None else self.chosen.model

    def to_dict(self, index: int) -> dict:
        """JSON of step ``index`` (0-based): its model, verdict, candidates (best first), tests."""
        model = self.base.fit.model
        return {"step": index + 1, "model": model.to_list(), "description": model.describe(), "verdict": self.verdict,
                "candidates": [c.to_dict() for c in sorted(self.candidates, key=lambda c: -c.improvement)],
                "pairwise": [t.to_dict() for t in self.pairwise]}


@dataclass(frozen=True)
class EncompassingTest:
    """Leader ``a`` and look-alike ``b`` fitted together: does each add significantly to the other?
    ``error`` says why the joint fit failed (then neither adds); ``cable`` (1-based) the cable both
    were compared on in their one-cable forms (:func:`one_cable_pair`), None: as searched.  When
    two such forms do not separate: ``angle_deg``, the angle between their magnitudes' columns after
    the baseline's (deg, :func:`columns_angle`), and ``needed`` = (angle_deg, log_length_factor) of
    :func:`separating_angle`, what would separate them."""

    a: str
    b: str
    b_adds_to_a: Comparison | None
    a_adds_to_b: Comparison | None
    a_adds: bool
    b_adds: bool
    error: str = ""
    cable: int | None = None
    angle_deg: float | None = None
    needed: tuple = (None, None)

    def to_dict(self) -> dict:
        where = {} if self.cable is None else {"on_cable": self.cable}
        if self.angle_deg is not None:
            where.update(columns_angle_deg=self.angle_deg, separating_angle_deg=self.needed[0],
                         separating_log_length_factor=self.needed[1])
        if self.error:
            return {"a": self.a, "b": self.b, **where, "error": self.error, "a_adds": self.a_adds, "b_adds": self.b_adds}

        def side(c: Comparison, adds: bool) -> dict:
            return {"improvement": c.improvement, "p_holdout": c.p_holdout, "p_train": c.p_train, "significant": adds}

        return {"a": self.a, "b": self.b, **where, "b_adds_to_a": side(self.b_adds_to_a, self.b_adds),
                "a_adds_to_b": side(self.a_adds_to_b, self.a_adds), "a_adds": self.a_adds, "b_adds": self.b_adds}

    def separating_text(self) -> str:
        """The report's clause on what would separate the two laws (:func:`separating_angle`): their
        columns' angle after the baseline, the angle that would do and the log length that would at
        today's angle.  When one law is on the tension and the other not (pulley against dry
        friction) the angle's tangent is about the cable's tension CV while it moves, and it says so."""
        if self.angle_deg is None:
            return ""
        from identification.diagnosis.columns import get

        tension = get(self.a).uses_tension != get(self.b).uses_tension
        a = self.angle_deg
        text = f"; their columns are {a:.1f} deg apart after the baseline"
        if tension:
            text += (f" (about the coefficient of variation of cable {self.cable}'s tension while it moves: "
                     f"tan {a:.1f} deg = {math.tan(math.radians(a)):.2f})")
        angle, length = self.needed
        adds = self.a_adds_to_b
        if angle is None and adds is not None and adds.improvement > 0 and max(adds.p_holdout, adds.p_train) < 0.5:
            return text + ", and no recording on that cable would separate them at this friction and noise"
        if angle is None:
            return text + f"; {self.a} adds nothing to {self.b} here, so this log does not say what would separate them"
        if tension:
            text += (f"; a recording where that tension varies by a CV of about {math.tan(math.radians(angle)):.2f} "
                     f"(columns {angle:.0f} deg apart) would separate them")
        else:
            text += f"; a recording where they are {angle:.0f} deg apart would separate them"
        return text + (f", or a log about {length:.1f} times as long" if length is not None else "")


@dataclass(frozen=True, eq=False)
class _Form:
    """What the encompassing test needs of one side: its term, its evaluated model, its added
    parameters against the step's baseline (columns and shape keys)."""

    term: Term
    model: Evaluated
    added_params: int

    @property
    def fit(self):
        return self.model.fit


def leader_cable(cand: CandidateScore, n_cables: int) -> int | None:
    """The one cable (1-based) a motor-side candidate with per-cable magnitudes rests on: the cable
    of its one-cable form, or the only cable whose fitted magnitude is clearly > 0 in its
    every-cable form; None otherwise (several cables, none, or not a per-cable motor-side effect)."""
    ident = cand.term.identification
    col = ident.columns[0] if ident.columns else None
    if cand.fit is None or not issubclass(ident, MotorColumns) or col is None or col.per != "cable":
        return None
    located = ident.cable_of(dict(cand.term.shape))
    if located is not None:
        return located
    v, sg = cand.fit.group(col.symbol), cand.fit.group_sigma(col.symbol)
    if len(v) != n_cables:
        return None
    on = np.nonzero(clearly_nonzero(v, sg) & (v > 0))[0]
    return int(on[0]) + 1 if on.size == 1 else None


def one_cable_pair(ctx: StepContext, a: CandidateScore, b: CandidateScore):
    """(a, b, cable): two motor-side look-alikes in their forms on the one cable the leader ``a``
    rests on (:func:`leader_cable`), each at its searched shape, when ``b``'s term can be put on
    one cable (``EffectColumns.cable_of`` reads its ``cable`` key); else (a, b, None) unchanged.

    Why: their every-cable forms carry C - 1 columns each on cables without the effect, where they
    fit whatever else those cables' residuals hold (on the 10-joint, 4-cable neck |f_s(2)| up to
    1.7 N, 9 sigma, with nothing hidden there), and those columns' held-out cost is charged to the
    comparison of the two laws; on one cable both laws are compared on the same data with one
    magnitude each (the constant force of eq 37 against the tension-proportional one)."""
    cable = leader_cable(a, ctx.data.C)

    def located(cand: CandidateScore) -> Term | None:
        shape = {k: v for k, v in cand.term.shape if k != "cable"}
        term = Term(cand.term.name, tuple({**shape, "cable": float(cable)}.items()))
        return term if term.identification.cable_of(dict(term.shape)) == cable else None

    if cable is None or b.fit is None:
        return a, b, None
    ta, tb = located(a), located(b)
    if ta is None or tb is None:
        return a, b, None

    def form(cand: CandidateScore, term: Term) -> _Form:
        if term == cand.term:
            return _Form(cand.term, cand.model, cand.added_params)
        ev = ctx.evaluate(ctx.base.fit.model.plus(term))
        return _Form(term, ev, ctx.added_params(ev.fit.n_params, term))

    try:
        return form(a, ta), form(b, tb), cable
    except ValueError:            # a form that cannot be fitted on that cable: compared as searched
        return a, b, None


def columns_angle(ctx: StepContext, both: Evaluated, a: Term, b: Term) -> float | None:
    """Angle (deg) between the magnitude columns of terms ``a`` and ``b`` (one each: their
    one-cable forms) after projecting out the step's baseline columns, on the weighted training rows
    of ``both`` (baseline + a + b, its last pass); None when either has not exactly one column.

    For dry and pulley friction on one cable the two columns differ by the cable's tension (eq 37's
    constant force against one proportional to it), so the angle is about arctan of the tension's
    coefficient of variation while the cable moves, as far as the baseline leaves it."""
    try:
        full = fit_model(ctx.data, both.fit.model, ctx.split.train, ctx.scales, both.fit.state, iterations=1,
                         keep_rows=True)
    except ValueError:
        return None
    W, _ = full.rows
    base = set(ctx.base.fit.names)

    def column(term: Term) -> np.ndarray | None:
        sym = term.identification.columns[0].symbol if term.identification.columns else None
        idx = [i for i, n in enumerate(full.names) if n not in base and n.split("(")[0] == sym]
        return W[:, idx[0]] if len(idx) == 1 else None

    ca, cb = column(a), column(b)
    if ca is None or cb is None:
        return None
    B = W[:, [i for i, n in enumerate(full.names) if n in base]]
    ca, cb = (c - B @ np.linalg.lstsq(B, c, rcond=None)[0] for c in (ca, cb))
    cos = abs(float(ca @ cb)) / max(float(np.linalg.norm(ca) * np.linalg.norm(cb)), 1e-300)
    return float(np.degrees(np.arccos(min(cos, 1.0))))


def separating_angle(angle_deg: float, adds: Comparison, min_improvement: float, alpha: float
                     ) -> tuple[float | None, float | None]:
    """(angle, length factor): the angle (deg) between two look-alikes' columns at which the
    leader's comparison ``adds`` (leader added to the other: what it alone explains) would pass
    ``min_improvement`` and both p values below ``alpha``, and the factor on the log's length that
    would do so at today's angle; None where that cannot be extrapolated (the leader adds nothing,
    a p value at or above 0.5, or no angle below 90 deg suffices; the length: when the improvement
    itself is short, which a longer log does not raise).

    First order, the same friction and noise: what the leader adds is the part of its column the
    other one cannot take, sin(angle) of it, so the improvement scales with sin^2(angle); each
    test's statistic as a normal score z = Phi^-1(1 - p) with sin(angle) (the added coefficient's
    t, the Wilcoxon's mean chunk reduction over its spread) and with sqrt(length)."""
    if not adds.improvement > 0 or max(adds.p_holdout, adds.p_train) >= 0.5:
        return None, None
    z_alpha = stats.norm.isf(alpha)
    by_p = max((z_alpha / stats.norm.isf(p)) ** 2 for p in (adds.p_holdout, adds.p_train))
    by_improvement = min_improvement / adds.improvement
    s2 = max(by_p, by_improvement) * math.sin(math.radians(angle_deg)) ** 2
    angle = math.degrees(math.asin(math.sqrt(s2))) if s2 < 1.0 else None
    return angle, (by_p if by_improvement <= 1.0 else None)


def encompass(ctx: StepContext, a: CandidateScore, b: CandidateScore) -> EncompassingTest:
    """Fit base + A + B; does each add significantly to the other?  Two motor-side look-alikes
    are compared on the leader's one cable when it rests on one (:func:`one_cable_pair`); when
    neither adds there, the test carries their columns' angle and the angle that would separate
    them (:func:`columns_angle`, :func:`separating_angle`)."""
    a, b, cable = one_cable_pair(ctx, a, b)
    try:
        both = ctx.evaluate(ctx.base.fit.model.plus(a.term).plus(b.term), a.fit.state)
    except ValueError as exc:
        return EncompassingTest(a.term.name, b.term.name, None, None, False, False, str(exc), cable)
    test = _encompassing(ctx, a, b, both, cable)
    if cable is None or test.a_adds or test.b_adds:
        return test
    angle = columns_angle(ctx, both, a.term, b.term)
    if angle is None:
        return test
    needed = separating_angle(angle, test.a_adds_to_b, 0.5 * ctx.settings.min_improvement, ctx.settings.alpha)
    return dataclasses.replace(test, angle_deg=angle, needed=needed)


def _encompassing(ctx: StepContext, a, b, both: Evaluated, cable: int | None) -> EncompassingTest:
    """The encompassing test of :func:`encompass` once ``both`` (base + A + B) is fitted."""
    b_to_a = ctx.compare(a.model, both, b.added_params)
    a_to_b = ctx.compare(b.model, both, a.added_params)
    if b_to_a.improvement < 0 and a_to_b.improvement < 0:
        # fitted together they predict held-out data worse than either alone: collinear on these
        # data (many-column look-alikes such as per-spring stiffness).  The leader stands when it
        # beats the other one on held-out data by itself (improvement and Wilcoxon test)
        head = ctx.compare(b.model, a.model, 0)
        wins = head.improvement >= 0.5 * ctx.settings.min_improvement and head.p_holdout < ctx.settings.alpha
        return EncompassingTest(a.term.name, b.term.name, b_to_a, a_to_b, wins, False, cable=cable)
    half = 0.5 * ctx.settings.min_improvement
    if b_to_a.improvement < 0 <= half <= a_to_b.improvement:
        # B, with the shape it was searched with alone, makes A's held-out prediction worse: it
        # adds nothing to A (its shape absorbed A's signal), while A improves on B
        return EncompassingTest(a.term.name, b.term.name, b_to_a, a_to_b, True, False, cable=cable)
    if a_to_b.improvement < 0 <= half <= b_to_a.improvement:
        return EncompassingTest(a.term.name, b.term.name, b_to_a, a_to_b, False, True, cable=cable)
    # half the minimum improvement: the second effect only has to add to the first
    return EncompassingTest(a.term.name, b.term.name, b_to_a, a_to_b, ctx.significant(a_to_b, 0.5),
                            ctx.significant(b_to_a, 0.5), cable=cable)


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
        outcome = encompassing_outcome(test.a_adds, test.b_adds)
        if outcome == "b":
            best = other                     # the other one explains all the leader does, and more
        elif outcome == "both":
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
    names = [n for n in settings.candidates
             if not model.has(n) and all(model.has(r) for r in effect_registry.get(n).requires)]
    ctx = StepContext(data, split, settings, Evaluated(fit, np.zeros((data.S, data.n + data.C))), scales)
    ctx = StepContext(data, split, settings, Evaluated(fit, ctx.cross_validate(fit)), scales, family=len(names))
    cands = []
    for name in tqdm(names, desc=desc, unit="effect", disable=not progress, leave=False):
        cands.append(evaluate_candidate(ctx, name))
    verdict, chosen, pairwise = decide(ctx, cands)
    return Step(ctx.base, scales, tuple(cands), verdict, chosen, pairwise)
