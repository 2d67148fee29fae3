"""The score S and the significance tests of the diagnosis, as pure functions of residual arrays."""

from __future__ import annotations

import numpy as np
from scipy import stats

from identification.diagnosis.split import Split


def mean_square(res: np.ndarray, mask: np.ndarray) -> np.ndarray:
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
    return float(np.sum(channel_weights(scales.size) * mean_square(res, mask) / scales ** 2))


def block_scores(res: np.ndarray, mask: np.ndarray, scales: np.ndarray, n_joints: int) -> dict:
    v = mean_square(res, mask) / scales ** 2
    return {"torque": float(v[:n_joints].mean()), "cable": float(v[n_joints:].mean())}


def chunk_reductions(base: np.ndarray, cand: np.ndarray, split: Split, scales: np.ndarray) -> np.ndarray:
    """Per chunk, its share of S_base - S_cand over all samples (the shares sum to the difference)."""
    n = np.maximum(np.isfinite(base).sum(0), 1)
    d = (np.nan_to_num(base) ** 2 - np.nan_to_num(cand) ** 2) / n / scales ** 2      # (S, N + C)
    return np.bincount(split.chunk, weights=d @ channel_weights(scales.size))


def wilcoxon_p(reductions: np.ndarray) -> float:
    """One-sided p of a Wilcoxon signed-rank test that the chunk reductions are centred above 0.

    Rank-based: an effect shows in the moves and hardly in the holds, so the reductions are
    heavy-tailed and a t-test would lose its power to the few large ones."""
    r = np.asarray(reductions, dtype=float)
    r = r[np.abs(r) > 1e-15 * max(np.abs(r).max(), 1e-300)]
    if r.size < 5:
        return 1.0
    return float(stats.wilcoxon(r, alternative="greater").pvalue)
