"""The cross-validation split: contiguous blocks of moves cut in holds, dealt to K folds."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.diagnosis.settings import DiagnosisSettings


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
    def n_chunks(self) -> int:
        return int(self.chunk.max() + 1)

    @property
    def train(self) -> np.ndarray:
        return self.fold != 1

    @property
    def holdout(self) -> np.ndarray:
        return self.fold == 1

    def to_dict(self) -> dict:
        return {"method": self.method, "folds": self.n_folds, "primary_train_samples": int(self.train.sum()),
                "primary_holdout_samples": int(self.holdout.sum()), "chunks": self.n_chunks,
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
