"""Materiality of a one-joint candidate, measured on its own channel.

A term located on one joint (shape key ``joint``: one joint's side springs, one hinge's friction)
acts on that joint's torque row only (eq 51).  Its evidence sits in one of the score's N + C
channels, so the step's improvement of the whole score S shrinks with the number of joints: one
joint's torque is half of S over N channels (1/6 of S on the 3-joint neck, 1/20 on the 10-joint
one), and the 2 % minimum on S asks a one-joint effect to explain 12 % of its channel's residual on
the former, 40 % on the latter.  This module measures such a term where it acts instead: the same
three tests as :meth:`~identification.diagnosis.fitting.StepContext.compare` (cross-validated
improvement, one-sided Wilcoxon over the held-out chunks, training F-test) on the joint's torque
channel alone, with its own effective samples (one per 1 / (2 f_b) s of that channel in its band
f_b, below) and the
step's Bonferroni factors (the 2 N places of :func:`~identification.diagnosis.search.
located_comparison` and the K candidates of the step).  Materiality is the 3-joint neck's: the
channel must improve by the share of its channel that the step's minimum asks of one joint there
(:data:`REFERENCE_TORQUE_CHANNELS` x 2 x ``min_improvement``: 12 % at the default 2 %), and the
whole score must not get worse on held-out data.

The channel is compared in its band, below :data:`OWN_BAND` of the log's common cutoff: a joint's
torque row carries the camera's angle noise twice differentiated (through M(alpha) alpha_ddot), whose
power rises with frequency up to the cutoff, while a spring or a hinge acts at the poses' and the
motion's frequencies.  Baseline and candidate residuals are low-passed alike (zero-phase, the
preprocessing's Butterworth), the F-test counts that band's effective samples and the Wilcoxon
test's chunks are merged to at least 1 / (2 band) s, so both stay calibrated on the slower signal.

Such a term is held to whichever of its two comparisons (the whole score, its own channel) is
the more convincing, so both p values of both are multiplied by :data:`CHANNEL_TESTS` (Bonferroni
over the two: the better of two tests at alpha passes up to twice as often as one named in advance
under no effect; the two share the joint's channel, so the factor is an upper bound).

A term whose own channel is material but whose band F-test misses its level for lack of
effective samples is not named; its note and the summary say so in one line naming its joint and
the log length at which the same relative gain would pass (:func:`deciding_length`,
:func:`undecided_lines`), so that a short log's ``none`` is not read as "no such effect".

    >>> from identification.diagnosis.materiality import own_channels, own_comparison
    >>> own_channels(term, n_joints=10)          # doctest: +SKIP
    [4]
    >>> cmp = own_comparison(ctx, ctx.base, evaluated, term, added)      # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses

import numpy as np

from identification.filtering import lowpass
from identification.diagnosis.statistics import (Comparison, channel_chunk_reductions, effective_samples, f_test_p,
                                                 improvement, in_band, mean_square, wilcoxon_p)

__all__ = ["REFERENCE_TORQUE_CHANNELS", "CHANNEL_TESTS", "OWN_BAND", "UNDECIDED", "UNDECIDED_P", "OWN_CHANNEL",
           "own_band_hz", "in_own_band", "project_band", "p_times", "own_channels", "own_train_ms",
           "own_min_improvement", "own_comparison", "OwnComparison", "deciding_length", "undecided_note",
           "undecided_lines", "own_significant", "candidate_decision"]

#: The torque channels of the neck on which the step's minimum improvement was set (the paper's
#: 3-joint prototype): on it, one joint's channel weighs 1 / (2 x 3) of S.
REFERENCE_TORQUE_CHANNELS = 3

#: The comparisons a one-joint term may be held to (the whole score and its own channel), the
#: factor on the p values of both (:func:`candidate_decision`).
CHANNEL_TESTS = 2

#: The own channel is compared below this fraction of the log's common cutoff (:func:`own_band_hz`).
#: On the clean 10-joint, 4-cable log of seed 1, 75 % of joint 5's torque residual lies in 2-5 Hz
#: (common cutoff 3.1 Hz: the camera's 1 deg noise through the inertial and gravity terms), while a
#: hinge's friction column holds 55 % of its power below 1 Hz, where its coherence with the
#: residual is 0.6-0.8 on the log that hides it (0.1-0.2 on the clean log).
OWN_BAND = 0.5


def own_channels(term, n_joints: int) -> list[int]:
    """0-based residual channels (of the (S, N + C) arrays) a term acts on alone: the torque
    channel of its joint for a located term (``EffectColumns.joint_of``), else [] (the term is
    measured on the whole score)."""
    joint = term.identification.joint_of(dict(term.shape))
    if joint is None or not 1 <= joint <= n_joints:
        return []
    return [joint - 1]


def own_min_improvement(min_improvement: float) -> float:
    """The improvement a one-joint term's own channel must reach: the share of one joint's channel
    that ``min_improvement`` of S asks on the reference neck (2 x 3 x 2 % = 12 %)."""
    return min(2 * REFERENCE_TORQUE_CHANNELS * min_improvement, 0.99)


def _ms(res: np.ndarray, mask: np.ndarray, ch: list[int]) -> float:
    """Mean square of ``res``' channels ``ch`` (one channel: a located term acts on one joint)."""
    return float(mean_square(res[:, ch], mask).mean())


def own_comparison(ctx, ref, cand, term, added: int) -> Comparison | None:
    """``cand`` against ``ref`` (``Evaluated`` of the step ``ctx``) on ``term``'s own channels
    (:func:`own_channels`), ``added`` parameters more (its columns and shape keys), p values times
    the term's places (``EffectColumns.places``); None for a term that acts on every channel.

    The F-test's degrees of freedom are the channel's effective training samples less ``added``:
    the baseline's shared parameters are set by the other N + C - 1 channels as much as by this one,
    so none of them is charged to it."""
    ch = own_channels(term, ctx.data.n)
    if not ch:
        return None
    split, data = ctx.split, ctx.data
    rate, band = data.prep.rate_hz, own_band_hz(data.prep.cutoffs["common"].hz)
    ref_cv, cand_cv = _band(ref.cv, ch, rate, band), _band(cand.cv, ch, rate, band)
    every, kept = np.ones(data.S, bool), list(range(len(ch)))
    # the low-passed channel is correlated over 1 / (2 band) s: chunks merged to at least that long
    merge = max(1, int(np.ceil(data.prep.rate_hz / (2.0 * band) / np.bincount(split.chunk).mean())))
    reductions = channel_chunk_reductions(ref_cv, cand_cv, _Chunks(split.chunk // merge)).sum(1)
    n_eff = effective_samples(int(split.train.sum()), band, rate) * len(ch)
    places = term.identification.places(dict(term.shape), data.n)
    ms_ref, ms_cand = own_train_ms(ctx, ref.fit, ch), own_train_ms(ctx, cand.fit, ch)
    return p_times(OwnComparison(
        improvement=improvement(_ms(ref_cv, every, kept), _ms(cand_cv, every, kept)),
        holdout_improvement=improvement(_ms(ref_cv, split.holdout, kept), _ms(cand_cv, split.holdout, kept)),
        p_holdout=wilcoxon_p(reductions),
        p_train=f_test_p(ms_ref, ms_cand, added, max(n_eff - added, 1)),
        ms_ref=ms_ref, ms_cand=ms_cand, added=added, n_eff=n_eff, places=places, joint=ch[0] + 1,
        duration_s=data.S / rate), places)


def own_train_ms(ctx, fit, ch: list[int]) -> float:
    """Training mean square of ``fit``'s residual channels ``ch`` in their band (zero-phase
    low-passed at :func:`own_band_hz`): what the own channel's F-test compares."""
    prep = ctx.data.prep
    res = _band(fit.residuals(), ch, prep.rate_hz, own_band_hz(prep.cutoffs["common"].hz))
    return _ms(res, ctx.split.train, list(range(len(ch))))


@dataclasses.dataclass(frozen=True)
class OwnComparison(Comparison):
    """A :class:`Comparison` on a one-joint term's own channel (:func:`own_comparison`) with what
    its training F-test was computed from: the band's training mean squares of the baseline and
    the candidate (``ms_ref``, ``ms_cand``, (N m)^2), the parameters ``added``, the band's
    effective training samples ``n_eff``, the Bonferroni factor ``places`` already in its p
    values, the 1-based ``joint`` and the log's span ``duration_s`` (s: its slow-grid samples over
    their rate)."""

    ms_ref: float = float("nan")
    ms_cand: float = float("nan")
    added: int = 0
    n_eff: int = 0
    places: int = 1
    joint: int = 0
    duration_s: float = float("nan")


def deciding_length(own: OwnComparison, alpha: float) -> float | None:
    """The log length (s) at which ``own``'s training F-test, with the same band mean squares
    (the same relative gain) over proportionally more effective samples, would pass at ``alpha``
    with its factors (``places`` x :data:`CHANNEL_TESTS`): the least n_eff' with
    f_test_p(ms_ref, ms_cand, added, n_eff' - added) x factors < alpha, times ``duration_s`` /
    n_eff.  None when it already passes, or never would (no gain, or past 1000 times the log)."""
    factor = own.places * CHANNEL_TESTS

    def passes(n: int) -> bool:
        return factor * f_test_p(own.ms_ref, own.ms_cand, own.added, max(n - own.added, 1)) < alpha

    n = max(own.n_eff, 1)
    if passes(n) or not own.ms_cand < own.ms_ref or not passes(1000 * n):
        return None
    lo, hi = n, 2 * n
    while not passes(hi):
        lo, hi = hi, 2 * hi
    while hi - lo > 1:                  # least passing count: p falls as the samples grow
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if passes(mid) else (mid, hi)
    return own.duration_s * hi / n


#: How :func:`candidate_decision`'s note starts when it holds a one-joint term to its own channel
#: (its p values are then that channel's, not the whole score's or its best channel's).
OWN_CHANNEL = "measured on its own channel"

#: How :func:`candidate_decision` says that a one-joint term's own channel lacks samples (the
#: start of the sentence; :func:`undecided_lines` finds it in the candidates' notes).
UNDECIDED = "undecided for lack of samples"

#: The own channel's training F-test p (with its factors) below which a term the log is too short
#: to decide is reported as such: the data must lean towards it.  Set on the clean logs, where a
#: channel 19-55 % lower in its band on 5-17 effective samples is noise (the false-alarm grid's
#: 120 diagnoses of clean 3-joint logs: 13 such lines without this level, their p 0.64-1; the
#: nine clean 10x4 logs: none) against the 10-joint neck's hidden hinges (p 0.01 and 0.072 on the
#: 15.6 and 30.8 s logs that a longer log names; a third, p 1, is not reported).
UNDECIDED_P = 0.1


def undecided_note(own: OwnComparison | None, whole: Comparison, alpha: float, min_improvement: float) -> str:
    """A sentence (:data:`UNDECIDED` ...) when a one-joint term's own channel is material (at
    least :func:`own_min_improvement`, cross-validated; the whole score not worse held out) and
    its training F-test does not pass at ``alpha`` for lack of effective samples: the joint, the
    channel's improvement, the F-test's p with its factors and the log length that would decide
    (:func:`deciding_length`), when that F-test's p leans towards the term (below
    :data:`UNDECIDED_P` with its factors); "" otherwise.  ``own`` and ``whole`` carry their places' factors,
    not yet :data:`CHANNEL_TESTS`."""
    if not isinstance(own, OwnComparison) or whole.improvement < 0.0 \
            or own.improvement < own_min_improvement(min_improvement) \
            or not CHANNEL_TESTS * own.p_train < UNDECIDED_P:
        return ""
    need = deciding_length(own, alpha)
    if need is None:
        return ""
    return (f"{UNDECIDED}: joint {own.joint}'s torque channel {100 * own.improvement:.0f} % lower in its band, "
            f"F-test p {min(1.0, CHANNEL_TESTS * own.p_train):.2g} against {alpha:.2g} over {own.n_eff} "
            f"effective samples in {own.duration_s:.1f} s, about {need:.0f} s would decide")


def undecided_lines(diag) -> list[str]:
    """The summary's lines (one per candidate) on one-joint candidates of the diagnosis ``diag``
    that were not named and whose own channel lacked the samples to decide (their note's
    :data:`UNDECIDED` sentence): the effect, the joint and the log length that would decide."""
    named = {f.effect if isinstance(f.effect, str) else tuple(f.effect) for f in diag.findings}
    out = []
    for i, st in enumerate(diag.steps):
        for c in st.candidates:
            if c.significant or c.term.name in named or UNDECIDED not in (c.note or ""):
                continue
            text = c.note[c.note.index(UNDECIDED) + len(UNDECIDED) + 2:].split(";")[0]
            out.append(f"  step {i + 1}: {c.term.name} not decided: {text}: record a longer log to decide it")
    return out


def own_band_hz(common_hz: float) -> float:
    """The band (Hz) in which a one-joint term's own channel is compared: :data:`OWN_BAND` of the
    log's common cutoff ``common_hz`` (the torque row's noise, the camera's angles differentiated,
    lies mostly above it; the term's columns, which follow the poses and the joint's speed, below)."""
    return OWN_BAND * common_hz


def in_own_band(v: np.ndarray, prep) -> np.ndarray:
    """A slow-grid signal ``v`` (S, ...) projected onto the own band (:func:`own_band_hz` of the
    pre-processing ``prep``'s common cutoff, ``identification.preprocessing.Prepared``): its
    discrete Fourier components above the band set to zero.  A projection, not the Butterworth of
    the comparison: a regressor column so projected and fitted to the full-band observation has the
    coefficient of the observation's own in-band part (the part above the band is orthogonal to it),
    whereas a low-pass H with 0 < |H| < 1 in its transition band gives sum |H| |C|^2 / sum |H|^2 |C|^2
    times it (joint 10's hinge on a 59.3 s log: +56 % with the Butterworth, +0.1 % projected)."""
    return project_band(v, prep.rate_hz, own_band_hz(prep.cutoffs["common"].hz))


def project_band(v: np.ndarray, rate_hz: float, band_hz: float) -> np.ndarray:
    """A signal ``v`` (S, ...) sampled at ``rate_hz`` with its discrete Fourier components above
    ``band_hz`` (Hz) set to zero (:func:`in_own_band` at any band)."""
    x = np.asarray(v, dtype=float)
    spectrum = np.fft.rfft(x, axis=0)
    spectrum[np.fft.rfftfreq(x.shape[0], 1.0 / rate_hz) > band_hz] = 0.0
    return np.fft.irfft(spectrum, x.shape[0], axis=0)


def _band(res: np.ndarray, ch: list[int], rate_hz: float, band_hz: float) -> np.ndarray:
    """Channels ``ch`` of the residuals ``res`` (S, N + C), zero-phase low-passed at ``band_hz``
    (baseline and candidate alike, so the comparison weighs the band the same on both)."""
    return lowpass(res[:, ch], rate_hz, band_hz)


@dataclasses.dataclass(frozen=True)
class _Chunks:
    """A split's chunking (``statistics.Chunked``) with consecutive chunks merged."""

    chunk: np.ndarray


def own_significant(own: Comparison | None, whole: Comparison, alpha: float, min_improvement: float) -> bool:
    """A one-joint term passes on its own channel: ``own`` passes its tests at ``alpha`` (the
    step's per-candidate level) with the channel's minimum (:func:`own_min_improvement`), and the
    ``whole`` score does not get worse on held-out data.  False for a term without own channels."""
    return (own is not None and whole.improvement >= 0.0
            and own.significant(alpha, own_min_improvement(min_improvement)))


def candidate_decision(ctx, whole: Comparison, own: Comparison | None) -> tuple[bool, Comparison, dict, str]:
    """(passes its tests, the comparison it is held to, that comparison's margins, a note) of a
    candidate whose ``whole``-score comparison (p values times its places) and own-channel one
    (:func:`own_comparison`, None for a term acting everywhere) were measured at step ``ctx``.

    A term with own channels passes on either: the whole score (the step's rule) or its own
    channel (:func:`own_significant`), the p values of both times :data:`CHANNEL_TESTS` (the better
    of two tests is taken); the one with the larger margin in borderline bands is the one it is
    held to and reported with (its p values; the improvement stays the whole score's, which ranks
    the step's candidates).  A term without own channels is held to ``whole`` unchanged."""
    s = ctx.settings
    if own is None:
        return ctx.candidate_significant(whole), whole, ctx.candidate_margins(whole), ""
    undecided = undecided_note(own, whole, ctx.alpha_candidate, s.min_improvement)
    whole, own = p_times(whole, CHANNEL_TESTS), p_times(own, CHANNEL_TESTS)
    margins = ctx.candidate_margins(whole)
    own_min = own_min_improvement(s.min_improvement)
    own_margins = own.margins(ctx.alpha_candidate, own_min)
    if whole.improvement < 0:
        own_margins["whole_improvement"] = -np.inf
    band = (s.borderline, s.borderline_decades)
    if in_band(own_margins, *band) <= in_band(margins, *band):
        passes = ctx.candidate_significant(whole)
        return passes, whole, margins, "" if passes else undecided
    note = (f"{OWN_CHANNEL} (the joint's torque): improvement {100 * own.improvement:.1f} % "
            f"(minimum {100 * own_min:.0f} %), whole score {100 * whole.improvement:.2f} %")
    passes = own_significant(own, whole, ctx.alpha_candidate, s.min_improvement)
    return passes, dataclasses.replace(whole, p_holdout=own.p_holdout, p_train=own.p_train), own_margins, \
        "; ".join(x for x in (note, "" if passes else undecided) if x)


def p_times(cmp: Comparison, factor: int) -> Comparison:
    """``cmp`` with both p values multiplied by ``factor`` (capped at 1)."""
    return dataclasses.replace(cmp, p_holdout=min(1.0, factor * cmp.p_holdout), p_train=min(1.0, factor * cmp.p_train))
