"""Misfit: the cost per signal against its expected value under the noise the weights assume.

With residuals weighted by the measurement noise (:func:`problem.noise_sigmas`) the mean square
weighted residual of a signal is about 1 when the model holds (measured on a clean simulated
identification run: encoders 1.00, camera 1.02).  Above ``MISFIT_RATIO`` the fit stays above
the noise floor: the model misses something, and ``neck-sim diagnose`` looks for what.
"""

from __future__ import annotations

import numpy as np

__all__ = ["MISFIT_RATIO", "cost_ratios", "misfit_lines"]

#: mean square weighted residual above which a signal counts as not explained by the model
MISFIT_RATIO = 1.5


def cost_ratios(res: dict) -> dict:
    """Mean square weighted residual per signal (cost / expected cost)."""
    return {k: float(np.mean(v ** 2)) if v.size else float("nan") for k, v in res.items()}


def misfit_lines(ratios: dict, logs, threshold: float = MISFIT_RATIO) -> list[str]:
    """One line per signal whose ratio exceeds ``threshold``, pointing to ``neck-sim diagnose``."""
    out = []
    for sig, r in ratios.items():
        if not r <= threshold:
            out.append(f"MISFIT: {sig} residuals are {r:.3g} x their noise floor (expected about 1, threshold "
                       f"{threshold:g}): the model does not explain this log; run `neck-sim diagnose "
                       f"{' '.join(str(x) for x in logs)}` to find the missing effect, then fit the extended model "
                       f"with --model")
    return out
