"""What a log cannot identify, and what to record instead (one line per gap).

A parameter counts as identified when its calibrated sigma (:mod:`identification.uncertainty`) is
below a third of its value, ``|value| >= MIN_SIGNIFICANCE sigma``: the data then fix it to within
a third, and its sign beyond doubt.  Otherwise the JSON marks it not identified and ``gap_lines``
says what the log lacks, from the signals that excite the parameter's column of the regressors:

* lambda(i) (eq 54's x_c t column) and k(i): the tension range of cable i over its taut samples
  (lambda is told from k only by how the stiffness changes with tension);
* c_a(i): the elongation rate of cable i (eq 54's x_c_dot column);
* f_s(i): the speed of motor i and its reversals (the arctan of eq 37 saturates at speed).
"""

from __future__ import annotations

import numpy as np

__all__ = ["MIN_SIGNIFICANCE", "not_identified", "gap_lines"]

#: |value| / sigma below which a parameter is reported as not identified.
MIN_SIGNIFICANCE = 3.0


def not_identified(value, sigma) -> np.ndarray:
    """Mask (p,): True where |value| < MIN_SIGNIFICANCE sigma or either is not finite."""
    v, s = np.asarray(value, dtype=float), np.asarray(sigma, dtype=float)
    with np.errstate(invalid="ignore"):
        return ~(np.isfinite(v) & np.isfinite(s) & (np.abs(v) >= MIN_SIGNIFICANCE * s))


def _cable(name: str) -> int:
    return int(name.split("(")[1].rstrip(")")) - 1


def gap_lines(model: str, names, value, sigma, mask, *, tension, x_c_dot, theta_dot, taut) -> list[str]:
    """One line per parameter of ``names`` with ``mask`` True: what is missing, what to record.

    ``tension`` (S, N+1) N of eq (55), ``x_c_dot`` (S, N+1) m/s, ``theta_dot`` (S, N+1) rad/s on
    the slow grid, ``taut`` (S, N+1) bool; ``model`` names the fit ("variable", "elastic", ...).
    """
    lines = []
    for j in np.flatnonzero(mask):
        name = names[j]
        sym, i = name.split("(")[0], _cable(name)
        rel = 100.0 * sigma[j] / abs(value[j]) if value[j] != 0 else np.inf
        known = f"{value[j]:.4g} ± {sigma[j]:.2g} ({rel:.0f} %)"
        t = tension[taut[:, i], i] if taut[:, i].any() else np.zeros(1)
        lo, hi = (float(x) for x in np.percentile(t, [5, 95]))
        if sym in ("lambda", "k"):
            other = "k" if sym == "lambda" else "lambda"
            what = (f"cable {i + 1}'s tension spans only {lo:.0f}-{hi:.0f} N over its taut samples: {name} cannot be "
                    f"separated from {other}({i + 1}) ({model} model: {known}); record moves that pull it to "
                    f"{max(2 * hi, 60.0):.0f} N and let it fall below {max(lo / 2, 2.0):.0f} N")
            if model == "elastic":
                what = (f"{name} ({model} model: {known}): cable {i + 1} is taut on {100 * taut[:, i].mean():.0f} % of "
                        f"the samples, tension {lo:.0f}-{hi:.0f} N; record moves that keep it taut and stretch it")
        elif sym == "c_a":
            v = np.abs(x_c_dot[taut[:, i], i]) if taut[:, i].any() else np.zeros(1)
            what = (f"cable {i + 1}'s elongation rate stays below {1e3 * np.percentile(v, 95):.1f} mm/s: {name} is not "
                    f"excited ({model} model: {known}); record faster tension changes on it")
        else:
            w = theta_dot[:, i]
            rev = int(np.count_nonzero(np.diff(np.sign(w[np.abs(w) > 0.05 * np.abs(w).max()])) != 0))
            what = (f"motor {i + 1} turns at up to {np.abs(w).max():.1f} rad/s with {rev} reversals: {name} is not "
                    f"identified ({model} model: {known}); record moves that run it both ways")
        lines.append(what)
    return lines
