"""Confidence intervals from the Jacobian of the weighted residuals at the optimum.

The fit reports the Newey-West sandwich (:func:`hac_jacobian_covariance`); the plain
Gauss-Newton covariance below is its white-noise special case.

Gauss-Newton's covariance: C = s^2 (J^T J)^-1 with s^2 = |r|^2 / (n - p), the residual variance
per weighted sample (eq 50's form on the output-error residuals; 1 when the weights are the true
noise).  sigma_i = sqrt(C_ii); the 95 % interval is value +- 1.96 sigma_i.  Their coverage over
seeds of short simulated runs: ``benchmarks/bench_output_error_coverage.py`` (the table) and
``tests/test_output_error_coverage.py``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["Z95", "jacobian_covariance", "hac_jacobian_covariance", "coverage"]

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


def hac_jacobian_covariance(J, r, rows, n_samples: int) -> tuple[np.ndarray, int]:
    """(C (p, p), Bartlett bandwidth in samples): the Newey-West sandwich (J^T J)^-1 S (J^T J)^-1
    of :func:`identification.uncertainty.hac_covariance` on the Jacobian J (n, p) and residuals
    r (n,) of the weighted problem, ``rows`` (n,) each residual's sample index (0 .. n_samples-1,
    motor samples; a camera frame counts at the motor sample it falls in).  The encoder residuals
    are quantisation errors, white while a motor turns but one constant error while it rests, so
    s^2 (J^T J)^-1 counts too many independent samples; the sandwich counts what the residuals'
    autocorrelation allows.  Columns are scaled to unit norm first (their units differ by 1e4)."""
    from identification.uncertainty import hac_covariance

    J = np.asarray(J, dtype=float)
    norms = np.linalg.norm(J, axis=0)
    norms[norms == 0] = 1.0
    cov, L = hac_covariance(J / norms, np.asarray(r, dtype=float), np.asarray(rows), int(n_samples))
    return cov / np.outer(norms, norms), L


def coverage(z, names, groups=("f_s", "k", "lambda", "c_a")) -> dict:
    """{group, then "all": (share of |z| < 1, share of |z| < 1.96, count)} of the errors in sigma
    units z (S, p) (S fits of the parameters ``names``, grouped by the symbol before "(")."""
    a = np.abs(np.asarray(z, dtype=float))
    out = {}
    for g in tuple(groups) + ("all",):
        cols = [i for i, n in enumerate(names) if g == "all" or n.split("(")[0] == g]
        v = a[:, cols].ravel()
        out[g] = (float(np.mean(v < 1.0)), float(np.mean(v < Z95)), int(v.size))
    return out
