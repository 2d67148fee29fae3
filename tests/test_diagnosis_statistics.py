"""The diagnosis' statistics as pure functions, each against an independent computation."""

from itertools import product

import numpy as np
import pytest
from scipy.stats import rankdata

from identification.diagnosis.search import minimise_bounded
from identification.diagnosis.split import Split
from identification.diagnosis.statistics import (Comparison, channel_wilcoxon_p, chunk_reductions, clearly_nonzero,
                                                 effective_samples,
                                                 encompassing_outcome, f_test_p, improvement, score, wilcoxon_p)


def _exact_signed_rank_p(r: np.ndarray) -> float:
    """One-sided p of the signed-rank statistic W+ by enumerating every sign pattern."""
    ranks = rankdata(np.abs(r))
    w = ranks[r > 0].sum()
    null = [ranks[np.array(signs, bool)].sum() for signs in product((0, 1), repeat=r.size)]
    return float(np.mean(np.array(null) >= w - 1e-9))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_wilcoxon_p_is_the_exact_signed_rank_p(seed):
    rng = np.random.default_rng(seed)
    r = rng.normal(0.4, 1.0, size=12)
    assert wilcoxon_p(r) == pytest.approx(_exact_signed_rank_p(r), rel=1e-9)
    # exact zeros carry no sign and are dropped; fewer than 5 left: no evidence
    assert wilcoxon_p(np.concatenate([r, np.zeros(4)])) == pytest.approx(_exact_signed_rank_p(r), rel=1e-9)
    assert wilcoxon_p(r[:4]) == 1.0


def _nested_ols(rng, n: int, effect: float) -> tuple[float, float, int, int]:
    """Mean squares of y on [1, x1] and on [1, x1, x2], y = 1 + x1 + effect x2 + noise."""
    X = np.column_stack([np.ones(n), rng.normal(size=n), rng.normal(size=n)])
    y = X @ np.array([1.0, 1.0, effect]) + rng.normal(size=n)

    def ms(cols):
        beta, *_ = np.linalg.lstsq(X[:, cols], y, rcond=None)
        return float(np.mean((y - X[:, cols] @ beta) ** 2))

    return ms([0, 1]), ms([0, 1, 2]), 1, n - 3


def test_f_test_p_is_uniform_under_the_null_and_small_under_an_effect():
    rng = np.random.default_rng(7)
    p_null = np.array([f_test_p(*_nested_ols(rng, 12, 0.0)) for _ in range(2000)])   # 9 dof
    # an irrelevant regressor: P(p < a) = a (binomial sd at 2000 draws: 0.5 % at a = 0.05)
    for a in (0.01, 0.05, 0.2, 0.5):
        assert abs(np.mean(p_null < a) - a) < 3.5 * np.sqrt(a * (1 - a) / 2000) + 1e-3, a
    p_effect = [f_test_p(*_nested_ols(rng, 40, 1.0)) for _ in range(50)]
    assert np.median(p_effect) < 1e-6
    assert f_test_p(1.0, 1.2, 2, 30) == 1.0 and f_test_p(1.0, 0.5, 0, 30) == 1.0


def test_channel_wilcoxon_p_finds_a_one_channel_gain_the_pooled_test_dilutes():
    """One channel of seven improves (its residual halved), the others change by noise: on that
    channel the per-chunk reductions are the exact signed-rank test's, while pooled with the others
    (each weighted by its share of S) the gain sinks in their noise."""
    rng = np.random.default_rng(5)
    S, n_chunks = 320, 16
    chunk = np.repeat(np.arange(n_chunks), S // n_chunks)
    split = type("Chunks", (), {"chunk": chunk})()
    base = rng.normal(size=(S, 7))
    cand = 0.8 * base + rng.normal(scale=0.6, size=base.shape)     # the same variance: noise
    cand[:, 1] = 0.5 * base[:, 1]
    cand[::7, 4] = np.nan                       # slack samples of a cable: left out of its sums
    p = channel_wilcoxon_p(base, cand, split)
    for k in (1, 3):
        d = np.nan_to_num(base[:, k]) ** 2 - np.nan_to_num(cand[:, k]) ** 2
        red = np.array([d[chunk == c].sum() for c in range(n_chunks)])
        assert p[k] == pytest.approx(_exact_signed_rank_p(red), rel=1e-9)
    assert int(np.argmin(p)) == 1 and 7 * p[1] < 1e-3
    pooled = wilcoxon_p(chunk_reductions(base, cand, split, np.ones(7), 3))
    assert pooled > 7 * p[1]


def test_chunk_reductions_sum_to_the_score_difference():
    rng = np.random.default_rng(3)
    S, n = 300, 2
    base = rng.normal(size=(S, 2 * n + 1))
    cand = 0.8 * base + 0.1 * rng.normal(size=base.shape)
    slack = rng.random(S) < 0.1
    base[slack, n + 1] = cand[slack, n + 1] = np.nan          # a slack cable in both models
    scales = rng.uniform(0.5, 2.0, size=2 * n + 1)
    chunk = np.repeat(np.arange(S // 10), 10)
    split = Split(np.zeros(S, int), np.zeros(S, int), 3, chunk, (), "test")
    every = np.ones(S, bool)
    red = chunk_reductions(base, cand, split, scales, n)
    assert red.shape == (S // 10,)
    assert red.sum() == pytest.approx(score(base, every, scales, n) - score(cand, every, scales, n), rel=1e-12)
    assert improvement(score(base, every, scales, n), score(cand, every, scales, n)) == pytest.approx(
        red.sum() / score(base, every, scales, n), rel=1e-12)


def test_small_rules():
    assert improvement(2.0, 1.5) == pytest.approx(0.25) and improvement(0.0, 1.0) == 0.0
    # 31.25 Hz samples low-passed at 2 Hz: one independent sample per 0.25 s
    assert effective_samples(1000, 2.0, 31.25) == 128 and effective_samples(1000, 40.0, 31.25) == 1000
    v = np.array([10.0, -3.0, 2.8, 0.5])
    s = np.array([1.0, 0.5, 1.0, 0.01])
    # 2.8 is at z = 2.8; 0.5 is below a quarter of the largest; -3 is clear
    assert clearly_nonzero(v, s).tolist() == [True, True, False, False]
    c = Comparison(improvement=0.05, holdout_improvement=0.04, p_holdout=1e-3, p_train=1e-4)
    assert c.significant(alpha=0.01, min_improvement=0.02)
    assert not c.significant(alpha=1e-3, min_improvement=0.02)            # p_holdout not below alpha
    assert not c.significant(alpha=0.01, min_improvement=0.06)
    assert [encompassing_outcome(a, b) for a, b in ((True, False), (False, True), (False, False), (True, True))] == \
        ["a", "b", "both", "a"]


@pytest.mark.parametrize("x_min", [-0.7, 0.1, 2.9])
def test_minimise_bounded(x_min):
    calls = []

    def f(x):
        calls.append(x)
        return np.log1p((x - x_min) ** 2)

    x = minimise_bounded(f, -1.0, 3.0, xatol=1e-3)
    assert abs(x - x_min) < 2e-3 and all(-1.0 <= c <= 3.0 for c in calls)
    assert minimise_bounded(lambda x: x, 0.0, 1.0, xatol=1e-4) < 1e-3          # minimum at the bound


def test_a_held_out_note_quotes_the_p_the_decision_reports():
    """A candidate whose best channel (cable 2, p 1e-5 times 14 channels and 2 places) beat its
    pooled held-out p: without own channels it reports that p and the note quotes it; a one-joint
    term held to the whole score reports it times the 2 comparisons
    (``materiality.candidate_decision``), and the note quotes that, with the factors counted the
    same; held to its own channel, the note names no best channel (its p is the channel's)."""
    import re
    from types import SimpleNamespace

    from identification.diagnosis.candidate import BestChannel, held_out_note
    from identification.diagnosis.materiality import candidate_decision

    alpha_c = 0.01 / 10
    settings = SimpleNamespace(min_improvement=0.02, borderline=0.1, borderline_decades=0.3)
    ctx = SimpleNamespace(settings=settings, alpha_candidate=alpha_c,
                          candidate_margins=lambda c: c.margins(alpha_c, 0.02),
                          candidate_significant=lambda c: c.significant(alpha_c, 0.02))
    channel = BestChannel("cable 2", 28, 0.004)
    whole = Comparison(0.05, 0.05, 28 * 1e-5, 1e-6)

    def quoted(note):
        found = re.fullmatch(r"held out on its best channel \(cable 2\): Wilcoxon p (\S+) with (\d+) places "
                             r"\(pooled (\S+)\)", note)
        return found.group(1), int(found.group(2)), found.group(3)

    _, held, _, note = candidate_decision(ctx, whole, None)
    assert quoted(held_out_note(channel, held, None, note)) == (f"{held.p_holdout:.2g}", 28, "0.004")
    weak = Comparison(0.01, 0.01, 0.5, 0.5)                         # its own channel: nothing there
    _, held, _, note = candidate_decision(ctx, whole, weak)
    assert held.p_holdout == pytest.approx(2 * 28e-5)
    assert quoted(held_out_note(channel, held, weak, note)) == (f"{held.p_holdout:.2g}", 56, "0.008")
    strong = Comparison(0.4, 0.4, 1e-9, 1e-9)                       # its own channel: a clear gain
    _, held, _, note = candidate_decision(ctx, whole, strong)
    assert held.p_holdout == pytest.approx(2e-9) and held_out_note(channel, held, strong, note) == ""


def test_the_method_says_which_test_the_held_out_p_is():
    """The method text (JSON ``method``, the report's Method list) names the tests a candidate's
    held-out p may be, the best channel only when the settings read it."""
    from identification.diagnosis import DiagnosisSettings, method_text

    on, off = method_text(DiagnosisSettings()), method_text(DiagnosisSettings(channel_holdout=False))
    assert "best residual channel" in on["held_out_p"] and "best residual channel" not in off["held_out_p"]
    assert all("own channel" in m["held_out_p"] and "places" in m["held_out_p"] for m in (on, off))
