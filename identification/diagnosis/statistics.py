"""The score S and the significance tests of the diagnosis, as pure functions of residual arrays.

Residuals are (S, N + C) arrays: N joint-torque channels (N m, eq 51) then C cable
elongation channels (m); NaN marks a slack cable's sample (left out).  ``scales`` (N + C,) are
the baseline's per-channel training RMS.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from scipy import stats

__all__ = ["mean_square", "channel_weights", "score", "block_scores", "Chunked", "chunk_reductions", "wilcoxon_p",
           "improvement", "f_test_p", "effective_samples", "clearly_nonzero", "Comparison", "encompassing_outcome",
           "margin_ratio", "decades_below", "in_band", "explained_share", "channel_chunk_reductions",
           "channel_wilcoxon_p"]


def clearly_nonzero(value, sigma) -> np.ndarray:
    """Which fitted magnitudes are clearly non-zero: |z| >= 4 and at least 25 % of the largest.

    The one rule by which the diagnosis locates an effect (its cables or joints) and checks its
    physical sign.  ``value``, ``sigma`` (p,) -> (p,) bool.
    """
    v, s = np.asarray(value, dtype=float), np.asarray(sigma, dtype=float)
    return (np.abs(v) >= 4 * s) & (np.abs(v) >= 0.25 * np.abs(v).max(initial=0.0))


def mean_square(res: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Mean square per channel (N + C,) of residuals (S, N + C) over ``mask``, slack samples left out."""
    r = res[mask]
    ok = np.isfinite(r)
    return np.where(ok, r, 0.0).__pow__(2).sum(0) / np.maximum(ok.sum(0), 1)


def channel_weights(n_channels: int, n_joints: int) -> np.ndarray:
    """(N + C,) weights of the channels in S: each residual type (torque, cable) counts one half,
    shared by its channels (N joints, C = ``n_channels`` - N cables of the routing), as the paper's
    W = 100 balances its two blocks."""
    n, c = n_joints, n_channels - n_joints
    if n < 1 or c < 1:
        raise ValueError(f"channel_weights: {n_channels} channels for {n_joints} joints")
    return np.concatenate([np.full(n, 0.5 / n), np.full(c, 0.5 / c)])


def score(res: np.ndarray, mask: np.ndarray, scales: np.ndarray, n_joints: int) -> float:
    """S: over ``mask``, the mean square residual of each channel / scale^2, averaged within each
    residual type (the first ``n_joints`` channels: joint torque; the rest: cable elongation) and
    then over the two types."""
    return float(np.sum(channel_weights(scales.size, n_joints) * mean_square(res, mask) / scales ** 2))


def block_scores(res: np.ndarray, mask: np.ndarray, scales: np.ndarray, n_joints: int) -> dict:
    """Normalised mean square per residual type over ``mask``: {"torque": ..., "cable": ...}."""
    v = mean_square(res, mask) / scales ** 2
    return {"torque": float(v[:n_joints].mean()), "cable": float(v[n_joints:].mean())}


class Chunked(Protocol):
    """What :func:`chunk_reductions` reads of a split (``split.Split`` is one): ``chunk`` (S,) int,
    the chunk of each sample.  A protocol keeps this pure module free of the split, whose settings
    import the candidate models and, through their columns, this module again."""

    @property
    def chunk(self) -> np.ndarray: ...


def chunk_reductions(base: np.ndarray, cand: np.ndarray, split: Chunked, scales: np.ndarray,
                     n_joints: int) -> np.ndarray:
    """Per chunk, its share of S_base - S_cand over all samples (the shares sum to the difference)."""
    n = np.maximum(np.isfinite(base).sum(0), 1)
    d = (np.nan_to_num(base) ** 2 - np.nan_to_num(cand) ** 2) / n / scales ** 2      # (S, N + C)
    return np.bincount(split.chunk, weights=d @ channel_weights(scales.size, n_joints))


def wilcoxon_p(reductions: np.ndarray) -> float:
    """One-sided p of a Wilcoxon signed-rank test that the chunk reductions are centred above 0.

    Rank-based: an effect shows in the moves and hardly in the holds, so the reductions are
    heavy-tailed and a t-test would lose its power to the few large ones."""
    r = np.asarray(reductions, dtype=float)
    r = r[np.abs(r) > 1e-15 * max(np.abs(r).max(), 1e-300)]
    if r.size < 5:
        return 1.0
    return float(stats.wilcoxon(r, alternative="greater").pvalue)


def channel_chunk_reductions(base: np.ndarray, cand: np.ndarray, split: Chunked) -> np.ndarray:
    """(chunks, channels): per chunk, the reduction of each channel's squared residual, ``base``
    against ``cand`` ((S, channels), slack samples NaN and left out), in the channel's own units
    (unlike :func:`chunk_reductions`, not weighed into S)."""
    d = np.nan_to_num(base) ** 2 - np.nan_to_num(cand) ** 2
    n_chunks = int(split.chunk.max()) + 1 if split.chunk.size else 0
    return np.stack([np.bincount(split.chunk, weights=d[:, k], minlength=n_chunks) for k in range(d.shape[1])],
                    axis=1)


def channel_wilcoxon_p(base: np.ndarray, cand: np.ndarray, split: Chunked) -> np.ndarray:
    """(N + C,) per channel, the one-sided Wilcoxon p (:func:`wilcoxon_p`) that the chunks'
    reductions of that channel's squared residual (:func:`channel_chunk_reductions`) are centred
    above 0.  The pooled test (:func:`chunk_reductions`) weighs every channel by its share of S: an
    effect on one cable or joint is then diluted by the noise of the N + C - 1 others, while on its
    own channel it stands out."""
    r = channel_chunk_reductions(base, cand, split)
    return np.array([wilcoxon_p(r[:, k]) for k in range(r.shape[1])])


def improvement(s_ref: float, s_cand: float) -> float:
    """Relative score improvement 1 - S_cand / S_ref (0 when S_ref is 0)."""
    return 1.0 - s_cand / s_ref if s_ref > 0 else 0.0


def f_test_p(s_ref: float, s_cand: float, added: int, dof: int) -> float:
    """p of the F-test that ``added`` more parameters lower a mean square from ``s_ref`` to
    ``s_cand`` with ``dof`` residual degrees of freedom; 1 when nothing is added or gained."""
    if added <= 0 or not s_cand < s_ref:
        return 1.0
    F = ((s_ref - s_cand) / added) / max(s_cand / dof, 1e-300)
    return float(stats.f.sf(F, added, dof))


def effective_samples(n_samples: int, cutoff_hz: float, rate_hz: float) -> int:
    """Independent samples among ``n_samples`` low-passed at ``cutoff_hz`` and sampled at
    ``rate_hz``: one per 1 / (2 f_c) s (Nyquist)."""
    return int(n_samples * min(1.0, 2.0 * cutoff_hz / rate_hz))


@dataclass(frozen=True)
class Comparison:
    """A model against a reference: cross-validated improvement over all samples, the same on
    the primary held-out fold, one-sided Wilcoxon p over chunks, training F-test p."""

    improvement: float
    holdout_improvement: float
    p_holdout: float
    p_train: float

    def significant(self, alpha: float, min_improvement: float) -> bool:
        """Improves by at least ``min_improvement`` with both tests below ``alpha``."""
        return self.improvement >= min_improvement and self.p_holdout < alpha and self.p_train < alpha

    def margins(self, alpha: float, min_improvement: float) -> dict:
        """Distance of each test to its threshold, > 0 on the passing side: the improvement
        relative to ``min_improvement`` (``improvement / min_improvement - 1``) and each p value
        in decades below ``alpha`` (``log10(alpha / p)``)."""
        return {"improvement": margin_ratio(self.improvement, min_improvement),
                "p_holdout_decades": decades_below(self.p_holdout, alpha),
                "p_train_decades": decades_below(self.p_train, alpha)}


def margin_ratio(value: float, threshold: float) -> float:
    """``value / threshold - 1``: the relative distance of a value that must reach ``threshold``
    (> 0 passes)."""
    return float(value / threshold - 1.0) if threshold > 0 else float("inf")


def decades_below(p: float, alpha: float) -> float:
    """``log10(alpha / p)``: how many decades a p value lies below its level (> 0 passes)."""
    return float(np.log10(alpha / max(p, 1e-300)))


def in_band(margins: dict, band: float, decades: float) -> float:
    """The margins of one decision (see :meth:`Comparison.margins`; keys ending in ``_decades``
    are in decades of p, the rest relative) in units of the borderline band: each divided by its
    band (``band`` relative, ``decades`` for p values), the decision's margin the smallest.  > 0:
    passes every test; |margin| < 1: borderline; for a failed decision, the largest shortfall."""
    vals = [v / (decades if k.endswith("_decades") else band) for k, v in margins.items()]
    return float(min(vals)) if vals else float("inf")


def encompassing_outcome(a_adds: bool, b_adds: bool) -> str:
    """Who stands between a leader A and a look-alike B fitted together: ``"a"`` when B adds
    nothing A lacks (or both add: A leads), ``"b"`` when only B adds, ``"both"`` when neither
    adds anything to the other (the data cannot tell them apart)."""
    if b_adds and not a_adds:
        return "b"
    if not a_adds and not b_adds:
        return "both"
    return "a"


def explained_share(base: np.ndarray, column: np.ndarray) -> tuple[float, np.ndarray]:
    """How much of a regressor ``column`` (r,) the span of the ``base`` columns (r, q) already
    explains, on the same (weighted) rows: R^2 = |P c|^2 / |c|^2 with P the projection on that
    span (uncentred: the fits have no intercept), so the variance inflation of c against the base
    is 1 / (1 - R^2) and the angle between c and the span arcsin(sqrt(1 - R^2)).  Also the
    coefficients (q,) of the projection on the unit-norm base columns: which of them explain it.
    A zero column is explained by nothing (R^2 = 0)."""
    c = np.asarray(column, dtype=float)
    B = np.asarray(base, dtype=float)
    cc = float(c @ c)
    if cc <= 0 or B.shape[1] == 0:
        return 0.0, np.zeros(B.shape[1])
    norms = np.linalg.norm(B, axis=0)
    Bs = B / np.where(norms > 0, norms, 1.0)
    coef, *_ = np.linalg.lstsq(Bs, c / np.sqrt(cc), rcond=None)
    left = c / np.sqrt(cc) - Bs @ coef
    return float(np.clip(1.0 - left @ left, 0.0, 1.0)), coef
