"""What a log cannot identify, and what to record instead (one line per gap).

A parameter counts as identified when its calibrated sigma (:mod:`identification.uncertainty`) is
at most a fifth of its value, ``|value| >= MIN_SIGNIFICANCE sigma`` (known to 20 %; a weaker
rule let through lambda(3) = 130 +- 35 1/m against a true 53 on a log whose cable 3 never left
8-17 N, where the noise bias outgrows its correction).  Otherwise the JSON marks it not identified
and ``gap_lines`` says what the log lacks, from the signals that excite the parameter's column
of the regressors:

* lambda(i) (eq 54's x_c t column) and k(i): the tension range of cable i over its taut samples
  (lambda is told from k only by how the stiffness changes with tension);
* c_a(i): the elongation rate of cable i (eq 54's x_c_dot column);
* f_s(i): the speed of motor i and its reversals (the arctan of eq 37 saturates at speed).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import numpy.typing as npt

__all__ = ["MIN_SIGNIFICANCE", "not_identified", "gap_lines", "tension_to_record"]

#: |value| / sigma below which a parameter is reported as not identified (module docstring).
MIN_SIGNIFICANCE = 5.0


def not_identified(value: npt.ArrayLike, sigma: npt.ArrayLike) -> np.ndarray:
    """Mask (p,): True where |value| < MIN_SIGNIFICANCE sigma or either is not finite."""
    v, s = np.asarray(value, dtype=float), np.asarray(sigma, dtype=float)
    with np.errstate(invalid="ignore"):
        return ~(np.isfinite(v) & np.isfinite(s) & (np.abs(v) >= MIN_SIGNIFICANCE * s))


def tension_to_record(lo: float, hi: float, want: float, f_max: float = np.inf) -> str:
    """What to record (after "record moves that ...") for a cable whose taut tension spans
    ``lo``..``hi`` N when a range up to ``want`` N would separate its parameters: pull it to
    ``want``, or as far as its motor allows (95 % of ``f_max`` N); a cable that already reaches
    that is asked for lower tensions instead (a wider span from the other end)."""
    top = 0.95 * f_max
    if want <= top:
        return f"pull it to {want:.0f} N"
    if top > hi + 1.0:
        return f"pull it to {top:.0f} N (its motor's limit is {f_max:.0f} N)"
    return (f"let it relax to {max(0.5 * lo, 5.0):.0f} N between pulls (it already reaches {hi:.0f} N of its "
            f"motor's {f_max:.0f} N)")


def _cable(name: str) -> int:
    return int(name.split("(")[1].rstrip(")")) - 1


def gap_lines(fits: Sequence[tuple[str, Sequence[str], np.ndarray, np.ndarray, np.ndarray]], *,
              tension: np.ndarray, x_c_dot: np.ndarray, theta_dot: np.ndarray, taut: np.ndarray,
              f_max: float = np.inf) -> list[str]:
    """One line per parameter some model does not identify: what is missing, what to record.

    ``fits`` is a sequence of (model name, names (p,), value (p,), sigma (p,), mask (p,) True =
    not identified); a parameter missing from several models gets one line naming them all.
    ``tension`` (S, m) N of eq (55), ``x_c_dot`` (S, m) m/s, ``theta_dot`` (S, m) rad/s on the
    slow grid, ``taut`` (S, m) bool; ``f_max`` N the motors' largest force (what to record stays
    within it).
    """
    known: dict = {}
    for model, names, value, sigma, mask in fits:
        for j in map(int, np.flatnonzero(mask)):
            rel = 100.0 * sigma[j] / abs(value[j]) if value[j] != 0 else np.inf
            known.setdefault(names[j], []).append(f"{model} model: {value[j]:.4g} ± {sigma[j]:.2g} ({rel:.0f} %)")
    lines = []
    for name, models in known.items():
        sym, i = name.split("(")[0], _cable(name)
        got = "; ".join(models)
        t = tension[taut[:, i], i] if taut[:, i].any() else np.zeros(1)
        lo, hi = (float(x) for x in np.percentile(t, [5, 95]))
        if sym in ("lambda", "k"):
            why = f"cannot be separated from k({i + 1})" if sym == "lambda" else "is not identified"
            what = (f"cable {i + 1}'s tension spans only {lo:.0f}-{hi:.0f} N over its taut samples "
                    f"({100 * taut[:, i].mean():.0f} % of the log): {name} {why} "
                    f"({got}); record moves that keep it taut and {tension_to_record(lo, hi, max(2 * hi, 60.0), f_max)}")
        elif sym == "c_a":
            v = np.abs(x_c_dot[taut[:, i], i]) if taut[:, i].any() else np.zeros(1)
            what = (f"cable {i + 1}'s elongation rate stays below {1e3 * np.percentile(v, 95):.1f} mm/s: {name} is not "
                    f"excited ({got}); record faster tension changes on it")
        else:
            w = theta_dot[:, i]
            rev = int(np.count_nonzero(np.diff(np.sign(w[np.abs(w) > 0.05 * np.abs(w).max()])) != 0))
            what = (f"motor {i + 1} turns at up to {np.abs(w).max():.1f} rad/s with {rev} reversals: {name} is not "
                    f"identified ({got}); record moves that run it both ways")
        lines.append(what)
    return lines
