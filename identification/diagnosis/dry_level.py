"""The level of a named dry friction where the log's friction is flat, and the form error of f_s.

Eq (37)'s f_s is the asymptote of an arctan fitted over every speed of the log.  On the 10-joint,
4-cable neck the friction the encoders see rises over 0.3-1 rad/s (a motor dither they do not
resolve) and is flat above (docs/your-own-neck.md section 7); the arctan fitted to the rise
overshoots the flat part and its asymptote reads high (+27 % on one seed at 59.3 s).  Even the
applied friction alone, taken through the observations' chain, reads 1.25 F by eq 37 on that seed
(the model's other columns take -0.5 %): the overshoot is the law's form, not the model's.

This module fits, to cable i's channel with the candidate's own part added back (the other columns
at their fit, rows weighted as the diagnosis' score weighs channels: :func:`cable_rows`), a law
flat above a knee, clip(c theta_dot, -1, 1) (:func:`saturating`, c searched on :data:`C_GRID`
through the same filter chain as the candidate's column): its level is the force where the friction
is flat (:func:`flat_fit`).  When the log cannot tell that law from eq (37) (its weighted residual
sum of squares at most the minimum improvement, 2 %, above eq 37's) and the flat part lies within
the log's speeds (at least :data:`MIN_FLAT_SHARE` of the cable's samples above the knee), f_s is
reported as that level, its sigma eq (50)'s and the form error, half the distance to eq 37's
asymptote, in quadrature (``parameters.FORM_NOTE``; :func:`chooses_flat`).  Otherwise (the paper's
plant, eq 37 with c_s = 0.5: the flat law's residual is 2-15 times the arctan's) f_s stays the fit's.
The fit's f_s and c_s stay what the extended model and the re-simulation use, as the hinge's do.

Measured on the blind dry logs of the 10-joint neck (docs/your-own-neck.md section 7): on 59.3 s,
seeds 1-3, -2.5, -4.7, +11 % of the hidden force (the asymptote +5.0, +0.7, +27 %); on the nine logs
of seeds 1-3 (15.6-59.3 s) within 10 % on 6, as the asymptote, the largest miss +17 % (the
asymptote's +30 %), and the hidden force within 2.72 of the sigma (eq 50's about the asymptote: up
to 18.6).  Not calibrated: where the two laws agree the form error is small and eq 50's sigma remains
(a fresh seed's cable 4: -22 %, 27 sigma, which every law reads).

    >>> from identification.diagnosis.dry_level import dry_level
    >>> parameters = dry_level(ctx, cand, parameters)        # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Callable

import numpy as np

from identification.diagnosis.statistics import channel_weights

__all__ = ["C_GRID", "MIN_FLAT_SHARE", "saturating", "cable_rows", "flat_fit", "chooses_flat", "dry_level"]

#: Slopes c (s/rad) of the flat law searched: knees 1/c from 0.03 to 20 rad/s.
C_GRID = tuple(float(c) for c in np.geomspace(0.05, 30.0, 61))
#: Share of the cable's control-rate samples that must lie above the flat law's knee: the level is
#: then read where the log has it, not extrapolated.
MIN_FLAT_SHARE = 0.10


def saturating(x: np.ndarray) -> np.ndarray:
    """The flat law's shape: x clipped to [-1, 1] (a force rising linearly to its level at the knee
    x = 1 and flat above)."""
    return np.clip(x, -1.0, 1.0)


def cable_rows(ctx, cand, cable: int, f_s: float) -> tuple[Callable[[np.ndarray], np.ndarray], np.ndarray]:
    """(rows, Y): ``rows(fast)`` the weighted training rows of a unit force on cable ``cable``
    (1-based) given at the control rate (T,), through the observations' chain (``data.to_slow``),
    Z in the torque rows (eq 51) and the cable's own row (eq 42/54, elongation = tension / stiffness,
    as the fit's residual); ``Y`` the fit's residual there with the candidate's column times ``f_s``
    (N) added back.  Rows weighted as the score weighs channels (``statistics.channel_weights``
    over each channel's RMS, ``ctx.scales``), so that the fit's own column returns f_s."""
    data, fit, train = ctx.data, cand.fit, ctx.split.train
    i = cable - 1
    n, C = data.n, data.C
    own = cand.term.identification.basis(data, dict(cand.term.shape))[1][:, i]      # the fitted column (S,)
    w = np.sqrt(channel_weights(n + C, n)) / ctx.scales
    Z = data.Z[:, :, i]                                                              # (S, N)
    wT = w[:n] / math.sqrt(max(int(train.sum()), 1))
    yT = ((fit.torque + f_s * Z * own[:, None])[train] * wT).reshape(-1)
    if fit.tension is None:                         # rigid cables: the torque rows alone
        return (lambda fast: ((Z * data.to_slow(fast[:, None]))[train] * wT).reshape(-1)), yT
    with np.errstate(invalid="ignore", divide="ignore"):
        stiff = fit.tension[:, i] / fit.cable[:, i]
    ok = train & np.isfinite(stiff) & (stiff != 0)
    wc = w[n + i] / math.sqrt(max(int(ok.sum()), 1))

    def rows(fast: np.ndarray) -> np.ndarray:
        slow = data.to_slow(fast[:, None])[:, 0]
        return np.concatenate([((Z * slow[:, None])[train] * wT).reshape(-1), slow[ok] / stiff[ok] * wc])

    return rows, np.concatenate([yT, (fit.cable[ok, i] + f_s * own[ok] / stiff[ok]) * wc])


def _ls(a: np.ndarray, Y: np.ndarray) -> tuple[float, float]:
    """(coefficient, residual sum of squares) of ``a`` fitted to ``Y``."""
    den = float(a @ a)
    b = float(a @ Y) / den if den > 0 else math.nan
    return b, float(np.sum((Y - b * a) ** 2))


def flat_fit(rows: Callable[[np.ndarray], np.ndarray], Y: np.ndarray, theta_dot: np.ndarray,
             grid=C_GRID) -> tuple[float, float, float]:
    """(level N, knee rad/s, residual sum of squares) of the flat law level x saturating(c
    theta_dot) fitted to ``Y`` through ``rows`` (:func:`cable_rows`), c at the least residual on
    ``grid`` (s/rad), then on 21 log-spaced values between the best one's neighbours (the level
    moves by about 3 % of itself per 5 % of the knee on these logs, while the residual barely
    changes); ``theta_dot`` (T,) rad/s the cable's encoder speed at the control rate."""
    def fit(c):
        level, rss = _ls(rows(saturating(c * theta_dot)), Y)
        return rss, level, 1.0 / c

    g = list(grid)
    k = min(range(len(g)), key=lambda j: fit(g[j])[0])
    fine = np.geomspace(g[max(k - 1, 0)], g[min(k + 1, len(g) - 1)], 21)
    rss, level, knee = min((fit(c) for c in fine), key=lambda r: r[0])
    return level, knee, rss


def chooses_flat(rss_flat: float, rss_eq37: float, share_above_knee: float, min_improvement: float) -> bool:
    """The flat law's level is reported when the log cannot tell it from eq (37) (its residual at
    most ``min_improvement`` above eq 37's, the diagnosis' own materiality) and its knee lies within
    the log's speeds (``share_above_knee`` >= :data:`MIN_FLAT_SHARE`)."""
    return rss_flat <= (1.0 + min_improvement) * rss_eq37 and share_above_knee >= MIN_FLAT_SHARE


def dry_level(ctx, cand, parameters: dict) -> dict:
    """``parameters`` of a named dry friction with each located cable's f_s the flat law's level
    where :func:`chooses_flat` says so, its sigma widened by the form error (half the distance to
    eq 37's asymptote, in quadrature with eq 50's); else f_s as fitted.  Other effects:
    ``parameters`` itself.  ``ctx`` the step's ``fitting.StepContext``, ``cand`` the named candidate."""
    from identification.diagnosis.columns.dry_friction import DryFrictionColumns
    from identification.diagnosis.parameters import FORM_NOTE, cables_of

    if cand.term.name != DryFrictionColumns.effect or cand.fit is None:
        return parameters
    symbol = DryFrictionColumns.columns[0].symbol
    located = set(cables_of(cand.fit, cand.term) or ())
    out = dict(parameters)
    for name, p in parameters.items():
        m = re.fullmatch(rf"{re.escape(symbol)}\((\d+)\)", name)
        if m is None or p.sigma is None or int(m.group(1)) not in located:
            continue
        cable = int(m.group(1))
        theta_dot = ctx.data.theta_dot_fast[:, cable - 1]
        rows, Y = cable_rows(ctx, cand, cable, p.value)
        own = cand.term.identification.effect_class().unit(
            cand.term.identification.without_location(dict(cand.term.shape))).regressor(theta_dot[:, None])[:, 0]
        _, rss37 = _ls(rows(own), Y)
        level, knee, rss = flat_fit(rows, Y, theta_dot)
        share = float(np.mean(np.abs(theta_dot) >= knee))
        if not (math.isfinite(level) and chooses_flat(rss, rss37, share, ctx.settings.min_improvement)):
            continue
        form = 0.5 * abs(p.value - level)
        note = (f"the friction's level above {knee:.3g} rad/s ({100 * share:.0f} % of the samples), where a law flat "
                f"above a knee, which this log cannot tell from eq (37) (residual {100 * (rss / rss37 - 1):+.2f} %), "
                f"is flat (dry_level.py); eq (37)'s asymptote {p.value:.4g} +- {p.sigma:.2g} {p.unit}; form error "
                f"{form:.2g} {p.unit} (half their distance); {FORM_NOTE}")
        out[name] = dataclasses.replace(p, value=float(level), sigma=float(math.hypot(p.sigma, form)), note=note)
    return out
