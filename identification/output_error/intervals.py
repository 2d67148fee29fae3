"""Confidence intervals from the Jacobian of the weighted residuals at the optimum.

Gauss-Newton's covariance: C = s^2 (J^T J)^-1 with s^2 = |r|^2 / (n - p), the residual variance
per weighted sample (eq 50's form on the output-error residuals; 1 when the weights are the true
noise).  sigma_i = sqrt(C_ii); the 95 % interval is value +- 1.96 sigma_i.  Coverage over
camera-noise seeds is measured in ``tests/test_output_error.py`` (short logs) and in the docs.
"""

from __future__ import annotations

import numpy as np

__all__ = ["Z95", "jacobian_covariance"]

Z95 = 1.959963984540054


def jacobian_covariance(J, r) -> tuple[np.ndarray, float]:
    """(C (p, p), s^2) for the Jacobian J (n, p) and residuals r (n,) of the weighted problem.

    The columns are scaled to unit norm before inverting (their units differ by 1e4); a
    parameter the data do not move (zero column) gets an infinite sigma."""
    J, r = np.asarray(J, dtype=float), np.asarray(r, dtype=float)
    n, p = J.shape
    if n <= p:
        raise ValueError(f"intervals: {n} residuals for {p} parameters; need more samples than parameters")
    s2 = float(r @ r) / (n - p)
    norms = np.linalg.norm(J, axis=0)
    ok = norms > 0
    cov = np.full((p, p), np.nan)
    Js = J[:, ok] / norms[ok]
    inner = np.linalg.pinv(Js.T @ Js)
    cov[np.ix_(ok, ok)] = s2 * inner / np.outer(norms[ok], norms[ok])
    cov[~ok, ~ok] = np.inf
    return cov, s2
