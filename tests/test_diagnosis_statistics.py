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
