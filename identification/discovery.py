"""Discrepancy discovery: what the model gets wrong, which effect causes it, and the gain of adding it.

``diagnose_log(log)`` reads only the measured topics of a log (motors, camera) and its ``neck``
record and runs, from a baseline model (the paper's: arctan friction + variable-stiffness cables,
or any :class:`~identification.candidates.ModelSpec`, e.g. ``"rigid"`` for eq 25):

1. **Split** (:func:`split_samples`) the slow-grid samples into contiguous blocks of about three
   moves (half a §5.2.2 sequence), cut in the middle of holds found from the motor speeds, and
   deal the blocks to K = 3 folds in turn.  Never at random: neighbouring samples are correlated.
   Residuals are **cross-validated**: each block is predicted by the model fitted on the other
   folds, so every sample is held out once.  The *primary* split (train on folds 0 and 2, hold
   out fold 1) gives the parameters, the shape searches, the training F-test, the written model
   and the alpha_hat and re-simulation comparisons.
2. **Baseline**: fit the model (:func:`identification.candidates.fit_model`) and evaluate its
   residuals -- joint torque (eq 51), cable tension (eq 42/54, N) and elongation (m) --,
   alpha_hat against the camera (eq 35 with the model's elongation) and an open-loop
   re-simulation of the plant driven by the logged forces.
3. **Candidates**: every effect of the vocabulary not yet in the model (and whose prerequisite
   is: Stribeck needs dry friction, stiffening and pretension need elastic cables), added with
   its parameters per cable where it is per cable, its shape parameters chosen on the training
   folds (a grid refined by golden-section search; a bounded search per cable for the rest
   elongation), then cross-validated.
4. **Score** ``S``: the mean square residual of each channel (N joint torques, N+1 cable
   elongations) divided by the square of the baseline's primary training RMS of that channel,
   averaged within each residual type and then over the two types (each equation type counts
   one half, as the paper's weight W = 100 balances them).  A candidate is **significant** when
   all of these hold:

   * cross-validated (held-out) improvement ``1 - S_cand / S_base >= min_improvement`` (2 %);
   * a one-sided Wilcoxon signed-rank test of the per-chunk score reductions over chunks of
     ``chunk_s`` (0.25 s, within blocks) gives p < ``alpha`` (0.01);
   * a training F-test counting the added parameters (linear ones plus searched shape
     parameters), with one effective sample per 1/(2 f_c) s per channel (f_c: the common filter
     cutoff: the residuals are low-passed), gives p < ``alpha``;
   * its fitted magnitudes have the physical sign (a friction that helps the motion is a shape
     correction of another friction, not this effect).

   The verdict is the significant candidate with the largest improvement, ``none`` when there is
   none.  **Look-alikes** are settled by an encompassing test: the leader A and each other
   significant candidate B are fitted together; if B adds nothing significant to A but A adds to
   B, A stands; if A adds nothing to B but B adds to A, B replaces A; if neither adds to the other
   the data cannot tell them apart and the verdict lists both (ambiguous), never a guess.
5. **Extension and gain**: the model plus the verdict is written as plant parameters and effects
   (:func:`identification.candidates.plant_model`) and compared with the baseline on held-out
   data: cross-validated residual RMS per type, alpha_hat error against the camera, re-simulation
   error in theta and alpha.  Forward selection repeats 3-5 from the extended model until nothing
   significant remains (at most ``max_steps`` findings).

The result (:class:`Diagnosis`) has ``to_dict()`` with the stable fields ``verdict`` (an effect
name, a list of names when ambiguous, or "none"), ``findings`` (ordered; each with ``effect``,
``cables``, ``parameters``, ``evidence``, ``gain``) and ``baseline`` (plus ``final``,
``extended_model``, ``steps``, ``split``, ``method``).
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import dataclass, field
from itertools import product

import numpy as np
from scipy import stats

from neck_sim.atomic import atomic_write_json
from neck_sim.atomic import jsonable as _jsonable
from neck_sim.params import NeckParams, to_dict

from identification.candidates import (EFFECTS, PAPER_MODEL, REQUIRES, SHAPE_GRIDS, Fit, FitState, MeasuredData,
                                       ModelSpec, Term, fit_model, plant_model,
                                       pretension_offsets)
from identification.preprocessing import Measurements, PreprocessSettings

__all__ = ["DiagnosisSettings", "Split", "split_samples", "CandidateScore", "Step", "Diagnosis", "diagnose",
           "diagnose_log", "parse_model", "MODEL_SHORTCUTS", "score", "channel_weights", "resimulate", "alpha_hat_errors"]

#: ``--model`` shortcuts (any comma-separated list of effect names is also accepted).
MODEL_SHORTCUTS = {
    "paper": PAPER_MODEL,
    "rigid": (),                                   # rigid cables, no friction: eq (25)
    "rigid-frictionless": (),
    "rigid-friction": ("dry_friction",),
    "linear": ("dry_friction", "cable_elasticity"),  # Table 1's constant stiffness
}


def parse_model(spec) -> ModelSpec:
    """A model from a shortcut (:data:`MODEL_SHORTCUTS`), a comma-separated list of effect names,
    a :class:`ModelSpec`, or a model JSON file written by a previous diagnosis (``model`` list)."""
    if isinstance(spec, ModelSpec):
        return spec
    if spec is None:
        return ModelSpec.of(*PAPER_MODEL)
    s = str(spec).strip()
    if s.endswith(".json") or os.path.sep in s:
        try:
            with open(s, "rb") as fh:
                data = json.loads(fh.read())
        except OSError as exc:
            raise ValueError(f"--model {s}: cannot read ({exc.strerror})") from None
        except json.JSONDecodeError as exc:
            raise ValueError(f"--model {s}: not JSON ({exc})") from None
        if not isinstance(data, dict) or "model" not in data:
            raise ValueError(f"--model {s}: expected a model file written by 'neck-sim diagnose --extended' "
                             f"(with a 'model' list of terms)")
        return ModelSpec.from_list(data["model"])
    if s in MODEL_SHORTCUTS:
        return ModelSpec.of(*MODEL_SHORTCUTS[s])
    names = [x.strip() for x in s.split(",") if x.strip() and x.strip() != "none"]
    unknown = [x for x in names if x not in EFFECTS]
    if unknown:
        raise ValueError(f"model: unknown {', '.join(unknown)} (shortcuts: {', '.join(MODEL_SHORTCUTS)}; "
                         f"effects: {', '.join(EFFECTS)})")
    return ModelSpec.of(*names)


@dataclass(frozen=True)
class DiagnosisSettings:
    """Method settings of the diagnosis (see the module docstring)."""

    moves_per_block: int = 3
    holdout_every: int = 3
    chunk_s: float = 0.25
    min_improvement: float = 0.02
    alpha: float = 0.01
    max_steps: int = 3
    candidates: tuple = EFFECTS
    resimulate: bool = True
    alpha_hat: bool = True
    iterations: int = 3
    preprocess: PreprocessSettings = field(default_factory=PreprocessSettings)

    def __post_init__(self):
        if self.moves_per_block < 1 or self.holdout_every < 2:
            raise ValueError("moves_per_block must be >= 1 and holdout_every >= 2")
        if not (0 < self.alpha < 1 and 0 <= self.min_improvement < 1 and self.chunk_s > 0):
            raise ValueError("alpha in (0, 1), min_improvement in [0, 1), chunk_s > 0")
        unknown = [c for c in self.candidates if c not in EFFECTS]
        if unknown:
            raise ValueError(f"candidates: unknown {unknown}")


# ------------------------------------------------------------------------------------------ split

@dataclass(frozen=True, eq=False)
class Split:
    """Blocks of the slow grid for cross-validation by motion sequence.

    ``block`` (S,) int, the block of each sample; ``fold`` (S,) int = block mod K; the *primary*
    split trains on folds != 1 and holds out fold 1 (``train``, ``holdout`` (S,) bool); ``chunk``
    (S,) int numbers consecutive pieces of ``chunk_s`` within blocks for the paired test;
    ``blocks`` [(t_start, t_end, fold)].
    """

    block: np.ndarray
    fold: np.ndarray
    n_folds: int
    chunk: np.ndarray
    blocks: tuple
    method: str

    @property
    def train(self) -> np.ndarray:
        return self.fold != 1

    @property
    def holdout(self) -> np.ndarray:
        return self.fold == 1

    def to_dict(self) -> dict:
        return {"method": self.method, "folds": self.n_folds, "primary_train_samples": int(self.train.sum()),
                "primary_holdout_samples": int(self.holdout.sum()), "chunks": int(self.chunk.max() + 1),
                "blocks": [{"start_s": round(a, 3), "end_s": round(b, 3), "fold": int(f),
                            "primary_held_out": f == 1} for a, b, f in self.blocks]}


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index pairs of the True runs of a 1-D bool array."""
    d = np.diff(np.concatenate([[0], mask.astype(int), [0]]))
    return list(zip(np.nonzero(d == 1)[0], np.nonzero(d == -1)[0]))


def split_samples(t: np.ndarray, activity: np.ndarray, settings: DiagnosisSettings = DiagnosisSettings()) -> Split:
    """Contiguous blocks of ``moves_per_block`` moves (fewer if that leaves less than two blocks
    per fold) cut at the middle of holds, assigned to ``holdout_every`` folds in turn (block i ->
    fold i mod K).

    ``activity`` (S,) is the motor-speed norm; a hold is a run of at least 0.15 s below 10 % of
    its 95th percentile.  A log with too few holds for 2 K blocks is cut into 2 K equal blocks,
    each cut moved to the quietest sample nearby.
    """
    t = np.asarray(t, dtype=float)
    act = np.asarray(activity, dtype=float)
    S = t.size
    rate = 1.0 / float(np.median(np.diff(t)))
    K = settings.holdout_every
    quiet = act < 0.1 * np.percentile(act, 95)
    holds = [(a, b) for a, b in _runs(quiet) if (b - a) / rate >= 0.15]
    centres = [(a + b) // 2 for a, b in holds if a > 0 and b < S]
    # fewer moves per block when the log is short: at least two blocks per fold
    m = max(1, min(settings.moves_per_block, (len(centres) + 1) // (2 * K)))
    cuts = centres[m - 1::m]
    method = f"blocks of {m} moves cut in holds, {K} folds"
    if len(cuts) + 1 < 2 * K:
        n_blocks = 2 * K
        width = max(S // (4 * n_blocks), 1)
        cuts = []
        for k in range(1, n_blocks):
            c = int(round(k * S / n_blocks))
            lo, hi = max(c - width, 1), min(c + width, S - 1)
            cuts.append(lo + int(np.argmin(act[lo:hi])))
        method = f"{n_blocks} equal blocks cut at the quietest nearby sample, {K} folds"
    edges = [0] + sorted(set(cuts)) + [S]
    block = np.zeros(S, int)
    chunk = np.zeros(S, int)
    per_chunk = max(int(round(settings.chunk_s * rate)), 2)
    blocks = []
    c = 0
    for i, (a, b) in enumerate(zip(edges[:-1], edges[1:])):
        block[a:b] = i
        blocks.append((float(t[a]), float(t[b - 1]), i % K))
        n_chunks = max((b - a) // per_chunk, 1)
        bounds = np.linspace(a, b, n_chunks + 1).round().astype(int)
        for lo, hi in zip(bounds[:-1], bounds[1:]):
            chunk[lo:hi] = c
            c += 1
    return Split(block, block % K, K, chunk, tuple(blocks), method)


# ------------------------------------------------------------------------------------------ scores

def _ms(res: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Mean square per channel (N + C,) of residuals (S, N + C) over ``mask``, slack samples left out."""
    r = res[mask]
    ok = np.isfinite(r)
    return np.where(ok, r, 0.0).__pow__(2).sum(0) / np.maximum(ok.sum(0), 1)


def channel_weights(n_channels: int) -> np.ndarray:
    """(N + C,) weights of the channels in S: each residual type (torque, cable) counts one half,
    shared by its channels (C = N + 1), as the paper's W = 100 balances its two blocks."""
    n = (n_channels - 1) // 2
    return np.concatenate([np.full(n, 0.5 / n), np.full(n + 1, 0.5 / (n + 1))])


def score(res: np.ndarray, mask: np.ndarray, scales: np.ndarray) -> float:
    """S: over ``mask``, the mean square residual of each channel / scale^2, averaged within each
    residual type (joint torque, cable elongation) and then over the two types."""
    return float(np.sum(channel_weights(scales.size) * _ms(res, mask) / scales ** 2))


def block_scores(res: np.ndarray, mask: np.ndarray, scales: np.ndarray, n_joints: int) -> dict:
    v = _ms(res, mask) / scales ** 2
    return {"torque": float(v[:n_joints].mean()), "cable": float(v[n_joints:].mean())}


def _chunk_reductions(base: np.ndarray, cand: np.ndarray, split: Split, scales: np.ndarray) -> np.ndarray:
    """Per chunk, its share of S_base - S_cand over all samples (the shares sum to the difference)."""
    n = np.maximum(np.isfinite(base).sum(0), 1)
    d = (np.nan_to_num(base) ** 2 - np.nan_to_num(cand) ** 2) / n / scales ** 2      # (S, N + C)
    return np.bincount(split.chunk, weights=d @ channel_weights(scales.size))


def _paired_p(reductions: np.ndarray) -> float:
    """One-sided p of a Wilcoxon signed-rank test that the chunk reductions are centred above 0.

    Rank-based: an effect shows in the moves and hardly in the holds, so the reductions are
    heavy-tailed and a t-test would lose its power to the few large ones."""
    r = np.asarray(reductions, dtype=float)
    r = r[np.abs(r) > 1e-15 * max(np.abs(r).max(), 1e-300)]
    if r.size < 5:
        return 1.0
    return float(stats.wilcoxon(r, alternative="greater").pvalue)


@dataclass(frozen=True, eq=False)
class Evaluated:
    """A model fitted on the primary training folds (``fit``) and its cross-validated residuals
    ``cv`` (S, N + C): each block predicted by the model fitted on the other folds."""

    fit: Fit
    cv: np.ndarray


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


class _Context:
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
        p_cv = _paired_p(_chunk_reductions(ref.cv, cand.cv, self.split, sc))
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


def _shape_grid(name: str) -> list[tuple]:
    grid = SHAPE_GRIDS.get(name)
    if not grid:
        return [()]
    keys = sorted(grid)
    return [tuple(zip(keys, vals)) for vals in product(*(grid[k] for k in keys))]


#: Magnitude parameters whose physical sign is fixed (a friction cannot push, a stiffness is > 0).
_SIGNED = {"dry_friction": "f_s", "viscous_friction": "c_v", "stribeck_friction": "df", "pulley_friction": "mu",
           "cable_elasticity": "k", "tension_stiffening": "lambda", "payload": "payload"}


def _sign_ok(fit: Fit, term: Term) -> tuple[bool, str]:
    """False when a clearly non-zero magnitude of ``term`` (|z| >= 4, at least 25 % of the largest)
    has the unphysical sign: the candidate then only reshapes another effect."""
    sym = _SIGNED.get(term.name)
    if sym is None or not fit.has(sym):
        return True, ""
    v, s = fit.group(sym), fit.group_sigma(sym)
    strong = (np.abs(v) >= 4 * s) & (np.abs(v) >= 0.25 * np.abs(v).max())
    bad = strong & (v < 0)
    if bad.any():
        idx = ", ".join(str(i + 1) for i in np.nonzero(bad)[0])
        return False, f"fitted {sym} < 0 on {'cable' if v.size > 1 else 'the head'} {idx}: not a {term.name}"
    return True, ""


#: Shape parameters refined by golden-section search between the best grid point's neighbours
#: (log scale for rates, linear for the delay).
_REFINE = {"dry_friction": ("c_s", True), "pulley_friction": ("c", True), "actuation_delay": ("delay", False)}


def evaluate_candidate(ctx: _Context, name: str) -> CandidateScore:
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
        best = _search_pretension(ctx, trial)
    else:
        for shape in _shape_grid(name):
            trial(Term(name, shape))
        done = [v for v in cache.values() if v is not None]
        best = min(done, key=_value) if done else None
        if name in _REFINE and best is not None:
            key, log_scale = _REFINE[name]
            grid = sorted(SHAPE_GRIDS[name][key])
            i = grid.index(best[1].get(key))
            lo = grid[i - 1] if i > 0 else (0.0 if not log_scale else grid[0] / 2)
            hi = grid[i + 1] if i + 1 < len(grid) else 2 * grid[-1]
            to = (lambda u: float(np.exp(u))) if log_scale else (lambda u: u)
            a, b = (np.log(lo), np.log(hi)) if log_scale else (lo, hi)
            u = _golden(lambda u: _value(trial(Term(name, ((key, round(to(u), 6)),)))), a, b, iterations=6)
            best = min([best, trial(Term(name, ((key, round(to(u), 6)),)))], key=_value)
    if best is None:
        return CandidateScore(Term(name, _shape_grid(name)[0]), None, 0, math.nan, math.nan, 0.0, 0.0, {}, 1.0, 1.0,
                              False, False, "not identifiable: " + (notes[0] if notes else "no fit"))
    _, term, fit = best
    ev = Evaluated(fit, ctx.cross_validate(fit))
    added = fit.n_params - ctx.base.fit.n_params + len(term.shape)
    imp, imp_ho, p_cv, p_tr = ctx.compare(ctx.base, ev, added)
    every = np.ones(ctx.data.S, bool)
    bb = block_scores(ctx.base.cv, every, ctx.scales, ctx.data.n)
    bc = block_scores(ev.cv, every, ctx.scales, ctx.data.n)
    ratio = {k: (bc[k] / bb[k] if bb[k] > 0 else 1.0) for k in bb}
    valid, why = _sign_ok(fit, term)
    return CandidateScore(term, ev, added, best[0], score(ev.cv, every, ctx.scales), imp, imp_ho, ratio, p_cv, p_tr,
                          valid, valid and ctx.passes(imp, p_cv, p_tr), why)


def _value(entry) -> float:
    return math.inf if entry is None else entry[0]


def _golden(f, lo: float, hi: float, iterations: int = 10) -> float:
    """Minimiser of a 1-D function on [lo, hi] by golden-section search."""
    g = (math.sqrt(5) - 1) / 2
    a, b = lo, hi
    c, d = b - g * (b - a), a + g * (b - a)
    fc, fd = f(c), f(d)
    for _ in range(iterations):
        if fc < fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            fd = f(d)
    return c if fc < fd else d


#: Search range of the rest elongation of each cable (m).
PRETENSION_RANGE = (-1e-3, 5e-3)


def _cable_law_score(ctx: _Context, j: int, x0: float) -> float:
    """Training mean square elongation error of cable j's law alone (eq 54 with x + x0; k, lambda,
    c_a refitted with the weights 1 / (k + lambda t) iterated, the base's motor forces fixed),
    normalised by the cable's scale."""
    data, base = ctx.data, ctx.base.fit
    sel = data.taut[:, j] & ctx.split.train
    t = base.state.tension[sel, j]
    x = data.x[sel, j] + x0
    cols = [x, data.x_dot[sel, j]]
    stiffening = base.model.has("tension_stiffening")
    if stiffening:
        cols.append(x * t)
    A = np.stack(cols, 1)
    k, lam = max(base.state.k[j], 1.0), max(base.state.lam[j], 0.0)
    for _ in range(3):
        w = 1.0 / (k + lam * np.maximum(t, 0.0))
        v, *_ = np.linalg.lstsq(A * w[:, None], t * w, rcond=None)
        k = max(v[0], 1.0)
        lam = max(v[2], 0.0) if stiffening else 0.0
    r = (t - A @ v) / (k + lam * np.maximum(t, 0.0))
    return float(np.mean(r ** 2) / ctx.scales[data.n + j] ** 2)


def _search_pretension(ctx: _Context, trial):
    """Per cable, the rest elongation x_0 that best fits that cable's law (bounded golden-section
    search on the training folds); the term keeps the cables whose offset passes an F-test at 1 %
    on that cable's rows, else the best single cable."""
    data = ctx.data
    fc = data.prep.cutoffs["common"].hz
    per = min(1.0, 2.0 * fc / data.prep.rate_hz)
    found = []
    for j in range(data.C):
        x = _golden(lambda v, j=j: _cable_law_score(ctx, j, v), *PRETENSION_RANGE, iterations=14)
        s0, s1 = _cable_law_score(ctx, j, 0.0), _cable_law_score(ctx, j, x)
        n = max(int((data.taut[:, j] & ctx.split.train).sum() * per), 5)
        F = (s0 - s1) / max(s1 / (n - 4), 1e-300)
        found.append((float(stats.f.sf(F, 1, n - 4)) if s1 < s0 else 1.0, s1 / s0, j, round(x, 7)))
    keep = [(j, x) for p, _, j, x in found if p < 0.01] or [min(found, key=lambda e: e[1])[2:]]
    return trial(Term("pretension", tuple((f"x0_{j + 1}", x) for j, x in sorted(keep))))


# ------------------------------------------------------------------------------------------ steps

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


def _encompass(ctx: _Context, a: CandidateScore, b: CandidateScore) -> dict:
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


def _decide(ctx: _Context, cands) -> tuple[object, CandidateScore | None, tuple]:
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
        test = _encompass(ctx, best, other)
        pairwise.append(test)
        if test.get("b_adds") and not test.get("a_adds"):
            best = other                     # the other one explains all the leader does, and more
        elif not test.get("b_adds") and not test.get("a_adds"):
            tied.append(other)
    tied = [t for t in tied if t is not best]
    if tied:
        return [best.term.name] + [t.term.name for t in tied], best, tuple(pairwise)
    return best.term.name, best, tuple(pairwise)


def _scales(data: MeasuredData, res: np.ndarray, train: np.ndarray) -> np.ndarray:
    rms = np.sqrt(_ms(res, train))
    floor = np.concatenate([np.full(data.n, 1e-4), np.full(data.C, 1e-6)])   # N m, m
    return np.maximum(rms, floor)


def _base_fit(data: MeasuredData, model: ModelSpec, split: Split, settings: DiagnosisSettings,
              state: FitState | None) -> tuple[Fit, np.ndarray]:
    """Fit the step's baseline twice: the second pass weights channels by the first's RMS."""
    y = data.observations()[1]
    first = np.concatenate([data.torque_observation(y), np.where(data.taut, data.x, np.nan)], axis=1)
    scales = np.maximum(np.nan_to_num(np.sqrt(_ms(first, split.train)), nan=1.0), 1e-6)
    fit = fit_model(data, model, split.train, scales, state, iterations=settings.iterations)
    scales = _scales(data, fit.residuals(), split.train)
    fit = fit_model(data, model, split.train, scales, fit.state, iterations=settings.iterations)
    return fit, _scales(data, fit.residuals(), split.train)


def run_step(data: MeasuredData, model: ModelSpec, split: Split, settings: DiagnosisSettings,
             state: FitState | None = None, progress: bool = False, desc: str = "candidates") -> Step:
    """One diagnosis step from ``model``: baseline fit, every candidate, the decision."""
    from tqdm.auto import tqdm

    fit, scales = _base_fit(data, model, split, settings, state)
    ctx = _Context(data, split, settings, Evaluated(fit, np.zeros((data.S, data.n + data.C))), scales)
    ctx = _Context(data, split, settings, Evaluated(fit, ctx.cross_validate(fit)), scales)
    names = [n for n in settings.candidates if not model.has(n) and (REQUIRES.get(n) is None or model.has(REQUIRES[n]))]
    cands = []
    for name in tqdm(names, desc=desc, unit="effect", disable=not progress, leave=False):
        cands.append(evaluate_candidate(ctx, name))
    verdict, chosen, pairwise = _decide(ctx, cands)
    return Step(ctx.base, scales, tuple(cands), verdict, chosen, pairwise)


# ------------------------------------------------------------------------------------ gains

def _rms(x, axis=0):
    x = np.asarray(x, dtype=float)
    ok = np.isfinite(x)
    n = np.maximum(ok.sum(axis), 1)
    return np.sqrt(np.where(ok, x, 0.0).__pow__(2).sum(axis) / n)


def residual_rms(data: MeasuredData, fit: Fit, res: np.ndarray, mask: np.ndarray) -> dict:
    """RMS per residual type and channel over ``mask``, SI units: torque (N m, eq 51), elongation
    (m) and tension (N, eq 42/54; None for rigid models) from the residuals ``res`` (S, N + C)."""
    n = data.n
    out = {"torque_Nm": _rms(res[mask, :n]).tolist(), "elongation_m": _rms(res[mask, n:]).tolist()}
    if fit.model.elastic:
        stiff = np.maximum(fit.group("k"), 1.0) + (np.clip(fit.group("lambda"), 0, None) if fit.has("lambda") else 0) \
            * np.maximum(fit.tension_hat, 0.0)
        out["tension_N"] = _rms((res[:, n:] * stiff)[mask]).tolist()
    else:
        out["tension_N"] = None
    return out


def model_elongation(data: MeasuredData, fit: Fit) -> np.ndarray:
    """The model's elongation x_c (S, C) m from its tension estimate (eq 54 quasi-static, x_0 of
    ``pretension`` subtracted: the encoders were zeroed with the cables already stretched)."""
    if not fit.model.elastic:
        return np.zeros((data.S, data.C))
    t = np.maximum(fit.tension_hat, 0.0)
    k = np.maximum(fit.group("k"), 1.0)
    lam = np.clip(fit.group("lambda"), 0.0, None) if fit.has("lambda") else np.zeros(data.C)
    return t / (k + lam * t) - pretension_offsets(fit.model, data.C)


def alpha_hat_errors(data: MeasuredData, fits, masks: dict, step: int = 4) -> list[dict]:
    """alpha_hat by eq (35) corrected with each model's elongation, against the camera frames.

    Integrated from the first slow-grid sample (filtered camera pose) over every ``step``-th
    encoder sample; errors (deg) at the camera frames inside each mask's time span:
    ``{"mask name": {"mean_abs_deg": ..., "rms_deg": ..., "per_joint_mean_abs_deg": [...]}}``.
    Also returns the series for plots under ``"series"``.
    """
    from neck_sim.analytic import estimate_alpha_pinv

    fast_t = data.t_fast
    sel = np.nonzero((fast_t >= data.t[0]) & (fast_t <= data.t[-1]))[0][::step]
    tq = fast_t[sel]
    theta = data.prep.fast.theta[sel]
    xs = []
    for fit in fits:
        x = model_elongation(data, fit)
        xs.append(np.stack([np.interp(tq, data.t, x[:, j]) for j in range(data.C)], axis=1))
    xs = np.stack(xs)
    B = len(fits)
    alpha0 = np.broadcast_to(data.alpha[0], (B, data.n))
    a_hat = estimate_alpha_pinv(np.broadcast_to(theta, xs.shape), data.params, xs, alpha0=alpha0)
    tc, ac = data.prep.camera
    inside = (tc >= tq[0]) & (tc <= tq[-1])
    tc, ac = tc[inside], ac[inside]
    out = []
    for b in range(B):
        at = np.stack([np.interp(tc, tq, a_hat[b, :, j]) for j in range(data.n)], axis=1)
        err = np.degrees(at - ac)
        res = {"series": {"t": tc, "error_deg": err}}
        for name, mask in masks.items():
            m = np.interp(tc, data.t, mask.astype(float)) > 0.5
            e = err[m]
            res[name] = {"mean_abs_deg": float(np.mean(np.abs(e))) if e.size else math.nan,
                         "rms_deg": float(np.sqrt(np.mean(e ** 2))) if e.size else math.nan,
                         "per_joint_mean_abs_deg": np.mean(np.abs(e), 0).tolist() if e.size else []}
        out.append(res)
    return out


def resimulate(data: MeasuredData, params: NeckParams, effects, rigid: bool, split: Split, masks: dict, *,
               settle_s: float = 0.3, progress: bool = False) -> dict:
    """Re-run the plant of a model open loop with the logged commanded forces, block by block.

    Each block of ``split`` (they start in the middle of a hold) is re-simulated from rest at the
    camera pose of its first sample: an open-loop run has no feedback, so over a whole log small
    model errors (or none: a closed-loop log's forces need the loop) carry the neck away.  The
    plant starts with unstretched cables, so a pre-roll of ``settle_s`` ramps the block's first
    commanded forces up (all cables together: the light linkage must not see one cable pull
    alone) and holds them; then the logged forces drive it and the comparison runs: encoder
    increments from the block start against the logged ones (rad), simulated joint angles
    against the camera frames (deg).  Errors per mask, the series under ``"series"``; a block
    that diverges is reported and left out from there on.
    """
    import mujoco
    from tqdm.auto import tqdm

    from neck_sim.plant import Plant

    t_fast = data.t_fast
    force = data.force_fast
    theta_log = data.prep.fast.theta
    tc, ac = data.prep.camera
    T = t_fast.size
    theta_err = np.full((T, data.C), np.nan)
    alpha_sim = np.full((T, data.n), np.nan)
    plant = Plant(params, effects, seed=0, rigid_cables=rigid)
    bad_qacc = plant.data.warning[mujoco.mjtWarning.mjWARN_BADQACC]
    amax = 0.95 * params.geometry.alpha_max
    settle = int(round(settle_s / data.dt))
    diverged = []
    edges = [(a, b) for a, b, _ in split.blocks]
    for a, b in tqdm(edges, desc="re-simulation", unit="block", disable=not progress, leave=False):
        i0, i1 = np.searchsorted(t_fast, a), np.searchsorted(t_fast, b, side="right")
        if i1 - i0 <= 2:
            continue
        a0 = np.array([np.interp(a, data.t, data.alpha[:, j]) for j in range(data.n)])
        plant.reset(alpha0=np.clip(a0, -amax, amax))
        bad_qacc.number = 0
        ramp = 0.5 * (1 - np.cos(np.pi * np.minimum(np.arange(settle) / (0.7 * settle), 1.0)))
        pre = [force[i0] * w for w in ramp]
        th = np.full((i1 - i0, data.C), np.nan)
        for k in range(i0 - settle, i1):
            if k >= i0:
                th[k - i0] = plant.encoders()
                alpha_sim[k] = plant.truth().alpha
            try:
                plant.step(pre[k - i0 + settle] if k < i0 else force[k])
                bad = bad_qacc.number > 0 or not np.all(np.isfinite(plant.data.qpos))
            except RuntimeError:                 # neck_sim.plant.PlantDivergedError
                bad = True
            if bad:
                if k >= i0:
                    alpha_sim[k + 1:i1] = np.nan
                    th[k + 1 - i0:] = np.nan
                else:
                    th[:] = np.nan
                    alpha_sim[i0:i1] = np.nan
                diverged.append(f"{a:.1f}-{b:.1f} s at {t_fast[max(k, i0)]:.2f} s")
                break
        theta_err[i0:i1] = (th - th[0]) - (theta_log[i0:i1] - theta_log[i0])
    a_cam = np.stack([np.interp(tc, t_fast, alpha_sim[:, j], left=np.nan, right=np.nan) for j in range(data.n)], axis=1)
    e_alpha = np.degrees(a_cam - ac)
    status = "ok" if not diverged else (f"diverged in {len(diverged)} of {len(edges)} blocks (open loop the logged "
                                        f"forces drive this model out of its valid range): " + "; ".join(diverged))
    out = {"status": status, "series": {"t": t_fast, "theta_error": theta_err, "t_camera": tc,
                                        "alpha_error_deg": e_alpha}}
    for name, mask in masks.items():
        m_fast = np.interp(t_fast, data.t, mask.astype(float), left=0, right=0) > 0.5
        m_cam = np.interp(tc, data.t, mask.astype(float), left=0, right=0) > 0.5
        ok_f, ok_c = m_fast & np.isfinite(theta_err).all(1), m_cam & np.isfinite(e_alpha).all(1)
        out[name] = {"theta_rms_rad": _rms(theta_err[ok_f]).tolist() if ok_f.any() else None,
                     "alpha_rms_deg": _rms(e_alpha[ok_c]).tolist() if ok_c.any() else None,
                     "alpha_mean_abs_deg": float(np.mean(np.abs(e_alpha[ok_c]))) if ok_c.any() else None,
                     "covered_fraction": float(ok_f.sum() / max(m_fast.sum(), 1))}
    return out


# ------------------------------------------------------------------------------------ result

_MAGNITUDE = {"dry_friction": "f_s", "viscous_friction": "c_v", "stribeck_friction": "df", "pulley_friction": "mu",
              "cable_elasticity": "k", "tension_stiffening": "lambda"}


def _cables_of(fit: Fit, term: Term) -> list[int] | None:
    """1-based cables the effect concerns: per-cable magnitudes clearly non-zero (|z| >= 4 and at
    least 25 % of the largest), the cables of a pretension; None for effects not per cable."""
    if term.name == "pretension":
        return sorted(int(k[3:]) for k, _ in term.shape if k.startswith("x0_"))
    sym = _MAGNITUDE.get(term.name)
    if sym is None or not fit.has(sym):
        return None
    v, s = fit.group(sym), fit.group_sigma(sym)
    keep = (np.abs(v) >= 4 * s) & (np.abs(v) >= 0.25 * np.abs(v).max())
    return [int(i) + 1 for i in np.nonzero(keep)[0]]


def _joints_of(fit: Fit, term: Term) -> list[int] | None:
    if term.name != "spring_error" or not fit.has("dk"):
        return None
    v, s = fit.group("dk"), fit.group_sigma("dk")
    keep = (np.abs(v) >= 4 * s) & (np.abs(v) >= 0.25 * np.abs(v).max())
    return [int(i) + 1 for i in np.nonzero(keep)[0]]


def _profile_sigma(ctx: _Context, term: Term, key: str, h: float, fit_score: float) -> float | None:
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


def _term_parameters(ctx: _Context, cand: CandidateScore) -> dict:
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


def _all_parameters(fit: Fit) -> dict:
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
                          "steps": [_step_dict(s, i) for i, s in enumerate(self.steps)],
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


def _step_dict(step: Step, i: int) -> dict:
    return {"step": i + 1, "model": step.base.fit.model.to_list(), "description": step.base.fit.model.describe(),
            "verdict": step.verdict,
            "candidates": [{"effect": c.term.name, **c.evidence()} for c in
                           sorted(step.candidates, key=lambda c: -c.improvement)],
            "pairwise": list(step.pairwise)}


def _extended_dict(fit: Fit, nominal: NeckParams) -> dict:
    params, effects, rigid = plant_model(fit, nominal)
    return {"model": fit.model.to_list(), "description": fit.model.describe(), "rigid_cables": rigid,
            "params": to_dict(params), "effects": effects.to_dict(), "parameters": _all_parameters(fit)}


def single_thread():
    """BLAS limited to one thread: the fits are many small least-squares problems, for which
    OpenBLAS threads only cost (10x slower on a loaded 2-core machine)."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:              # pragma: no cover - threadpoolctl is a dependency
        import contextlib
        return contextlib.nullcontext()
    return threadpool_limits(1)


def diagnose(data: MeasuredData, model=None, settings: DiagnosisSettings | None = None, *,
             progress: bool = False, source: str = "") -> Diagnosis:
    """Diagnose prepared measured data from the baseline ``model`` (default: the paper's)."""
    with single_thread():
        return _diagnose(data, model, settings, progress=progress, source=source)


def _retune(data: MeasuredData, model: ModelSpec, split: Split, settings: DiagnosisSettings,
            state: FitState | None, found: set) -> ModelSpec:
    """Re-search the one-parameter shapes (c_s, pulley c, delay) of the terms the diagnosis added,
    within a factor 2 (5 ms for the delay) of their values, on the primary training score."""
    _, scales = _base_fit(data, model, split, settings, state)
    for term in model.terms:
        if term.name not in found or term.name not in _REFINE:
            continue
        key, log_scale = _REFINE[term.name]
        v0 = term.get(key)

        def with_value(v, term=term, key=key, model=model):
            t = Term(term.name, tuple((k, (v if k == key else x)) for k, x in term.shape))
            return ModelSpec(tuple(t if u is term else u for u in model.terms)), t

        def cost(u, with_value=with_value, log_scale=log_scale):
            v = round(float(np.exp(u)) if log_scale else u, 6)
            try:
                fit = fit_model(data, with_value(v)[0], split.train, scales, state, iterations=settings.iterations)
            except ValueError:
                return math.inf
            return score(fit.residuals(), split.train, scales)

        lo, hi = (np.log(v0 / 2), np.log(2 * v0)) if log_scale else (max(v0 - 0.005, 0.0), v0 + 0.005)
        u = _golden(cost, lo, hi, iterations=7)
        u0 = np.log(v0) if log_scale else v0
        if cost(u) < cost(u0):
            model = with_value(round(float(np.exp(u)) if log_scale else u, 6))[0]
    return model


def _diagnose(data: MeasuredData, model, settings: DiagnosisSettings | None, *, progress: bool,
              source: str) -> Diagnosis:
    s = settings or DiagnosisSettings()
    model = parse_model(model)
    timings = {}
    t0 = time.perf_counter()
    split = split_samples(data.t, data.activity, s)
    steps = []
    current, state = model, None
    for i in range(max(s.max_steps, 1)):
        if i > 0:
            # shapes searched at an earlier step were chosen without the effects found since
            current = _retune(data, current, split, s, state, {st.chosen.term.name for st in steps})
        step = run_step(data, current, split, s, state, progress=progress, desc=f"step {i + 1}: candidates")
        steps.append(step)
        if step.chosen is None:
            break
        current, state = step.chosen.fit.model, step.chosen.fit.state
    timings["search"] = time.perf_counter() - t0
    # models compared: each step's baseline and the last extension (if the last step found one)
    evaluated = [st.base for st in steps] + ([steps[-1].extended] if steps[-1].extended is not None else [])
    fits = [e.fit for e in evaluated]
    masks = {"holdout": split.holdout, "all": np.ones(data.S, bool)}
    t1 = time.perf_counter()
    alpha = alpha_hat_errors(data, fits, masks) if s.alpha_hat else [None] * len(fits)
    timings["alpha_hat"] = time.perf_counter() - t1
    t1 = time.perf_counter()
    resim = {}
    if s.resimulate:
        for idx in sorted({0, len(fits) - 1}):
            p, e, rigid = plant_model(fits[idx], data.params)
            resim[idx] = resimulate(data, p, e, rigid, split, masks, progress=progress)
    timings["resimulation"] = time.perf_counter() - t1

    def summary(idx: int) -> dict:
        ev = evaluated[idx]
        out = {"model": ev.fit.model.to_list(), "description": ev.fit.model.describe(),
               "parameters": _all_parameters(ev.fit),
               "residual_rms_crossvalidated": residual_rms(data, ev.fit, ev.cv, masks["all"]),
               "residual_rms_holdout": residual_rms(data, ev.fit, ev.fit.residuals(), split.holdout),
               "residual_rms_train": residual_rms(data, ev.fit, ev.fit.residuals(), split.train)}
        if alpha[idx] is not None:
            out["alpha_hat_vs_camera"] = {k: v for k, v in alpha[idx].items() if k != "series"}
        if idx in resim:
            out["resimulation"] = {k: v for k, v in resim[idx].items() if k != "series"}
        return out

    summaries = [summary(i) for i in range(len(evaluated))]
    findings = []
    for i, st in enumerate(steps):
        c = st.chosen
        if c is None:
            continue
        ctx = _Context(data, split, s, st.base, st.scales)
        before, after = summaries[i], summaries[i + 1]
        gain = {"residual_rms_crossvalidated": {"before": before["residual_rms_crossvalidated"],
                                                "after": after["residual_rms_crossvalidated"]},
                "residual_rms_holdout": {"before": before["residual_rms_holdout"],
                                         "after": after["residual_rms_holdout"]}}
        if "alpha_hat_vs_camera" in before and "alpha_hat_vs_camera" in after:
            gain["alpha_hat_vs_camera_holdout"] = {"before": before["alpha_hat_vs_camera"]["holdout"],
                                                   "after": after["alpha_hat_vs_camera"]["holdout"]}
        if "resimulation" in before and "resimulation" in after:
            gain["resimulation_holdout"] = {"before": before["resimulation"]["holdout"],
                                            "after": after["resimulation"]["holdout"]}
        findings.append({"effect": st.verdict if isinstance(st.verdict, list) else c.term.name,
                         "cables": _cables_of(c.fit, c.term), "joints": _joints_of(c.fit, c.term),
                         "parameters": _term_parameters(ctx, c), "evidence": c.evidence(), "gain": gain,
                         "step": i + 1, "model_after": c.fit.model.describe()})
    series = {"alpha_hat": [a["series"] if a else None for a in alpha],
              "resimulation": {k: v["series"] for k, v in resim.items()},
              "cv_residuals": [e.cv for e in evaluated], "labels": [f.model.describe() for f in fits]}
    return Diagnosis(source, model, split, tuple(steps), tuple(findings), summaries[0], summaries[-1],
                     _extended_dict(fits[-1], data.params), timings, data, series, s)


def diagnose_log(log, model=None, settings: DiagnosisSettings | None = None, *, params: NeckParams | None = None,
                 progress: bool = False) -> Diagnosis:
    """:func:`diagnose` on a :class:`neck_sim.logs.Log` or a path: measured topics and the ``neck``
    record only (``/neck/truth``, ``/neck/reference``, ``/neck/estimate`` and the ``run`` record are
    never read)."""
    from neck_sim.logs import Log, read_log

    s = settings or DiagnosisSettings()
    if not isinstance(log, Log):
        log = read_log(log, topics=("motors", "camera"), require=("motors", "camera"))
    t0 = time.perf_counter()
    with single_thread():
        data = MeasuredData(Measurements.from_log(log), params or log.params, s.preprocess)
    t_prep = time.perf_counter() - t0
    diag = diagnose(data, model, s, progress=progress, source=os.fspath(log.path))
    diag.timings["preprocessing"] = t_prep
    return diag
