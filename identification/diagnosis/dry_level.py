"""The level of a named dry friction read from the log's friction curve, where that curve is flat.

Eq (37)'s f_s is the asymptote of an arctan fitted over every speed of the log.  Where the friction
the encoders see is not that shape (on the 10-joint, 4-cable neck a motor dither the encoders do not
resolve makes it rise over 0.3-1 rad/s; docs/your-own-neck.md section 7) the asymptote is what the
shape extrapolates.  This module reads the friction as a curve instead: cable i's arctan column is
replaced by speed-binned columns, sign(theta_dot) x the indicator of |theta_dot| in bin k
(:func:`bin_columns`, octave bins over the cable's encoder speeds, each taken through the
observations' filter chain as the candidate's column is: ``data.to_slow``), fitted to the step's
residual with the candidate's own part added back (the other columns at their fit, rows weighted as
the diagnosis' score weighs them: :func:`friction_curve`).  If the top bins agree within their
sigmas (:func:`plateau`: chi-square of constancy, p >= :data:`FLAT_P`, at least
:data:`MIN_PLATEAU` bins), f_s is reported as their weighted level, its sigma the level's and half
the plateau bins' range (form error) in quadrature, labelled ``parameters.FORM_NOTE``; else f_s stays
the fit's asymptote and its note says the log's curve does not flatten.  The fit's f_s and c_s stay
what the extended model and the re-simulation use.

Measured and NOT adopted (docs/your-own-neck.md section 7; not called by the pipeline): on the nine
blind dry logs of the 10-joint, 4-cable neck (seeds 1-3 at 15.6, 30.8, 59.3 s) neighbouring octave
bins trade against each other after the observations' 2.75 Hz chain (59.3 s: 1-2 and 2-4 rad/s read
1.32 and 0.89 F on seed 1; 2-4 and 4-8 read 1.50 and 0.72 F on seed 2), so the chi-square either
rejects the top bins (seed 3 at 30.8 and 59.3 s: f_s kept, +30 and +27 %) or accepts two or three
bins that happen to agree, whose level misses by -23 to +15 % (within 10 % on 2 of 7 logs, against
6 of 9 for the fit's f_s).

    >>> from identification.diagnosis.dry_level import dry_level
    >>> parameters = dry_level(ctx, cand, parameters)        # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
from scipy import stats

from identification.diagnosis.statistics import channel_weights, effective_samples

__all__ = ["FLAT_P", "MIN_PLATEAU", "MIN_SHARE", "Curve", "speed_edges", "bin_columns", "level_fit", "plateau",
           "friction_curve", "dry_level"]

#: Constancy of the top bins is accepted above this chi-square p value.
FLAT_P = 0.05
#: Bins a plateau needs (octave bins: a speed range of at least 4x).
MIN_PLATEAU = 2
#: Share of the control-rate samples a bin needs; thinner bins are merged into the one below.
MIN_SHARE = 0.02


@dataclasses.dataclass(frozen=True)
class Curve:
    """A friction curve: ``edges`` (K + 1,) rad/s, ``level`` and ``sigma`` (K,) N per bin."""

    edges: np.ndarray
    level: np.ndarray
    sigma: np.ndarray


def speed_edges(theta_dot: np.ndarray, min_share: float = MIN_SHARE) -> np.ndarray:
    """Bin edges (rad/s) over the speeds |``theta_dot``| (T,) of one cable: 0, then octaves (powers
    of 2 rad/s) from the 1st percentile to the largest speed, the top edge infinite; a bin holding
    less than ``min_share`` of the samples is merged into the one below it."""
    v = np.abs(np.asarray(theta_dot, dtype=float))
    lo, hi = np.percentile(v, 1.0), v.max()
    if not hi > 0:
        raise ValueError("dry_level: the cable never moves")
    k0, k1 = math.floor(math.log2(max(lo, 1e-3))), math.ceil(math.log2(hi))
    edges = [0.0] + [2.0 ** k for k in range(k0 + 1, k1)] + [math.inf]
    counts = list(np.histogram(v, bins=edges)[0])
    k = len(counts) - 1
    while k > 0:                      # from the top: a thin bin joins the one below
        if counts[k] < min_share * v.size:
            counts[k - 1] += counts.pop(k)
            edges.pop(k)
        k -= 1
    return np.asarray(edges)


def bin_columns(theta_dot: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """(T, K): sign(theta_dot) x the indicator of |theta_dot| in [edges[k], edges[k + 1])."""
    v = np.asarray(theta_dot, dtype=float)
    a = np.abs(v)
    return np.stack([np.sign(v) * ((a >= lo) & (a < hi)) for lo, hi in zip(edges[:-1], edges[1:])], axis=1)


def level_fit(W: np.ndarray, Y: np.ndarray, correlation: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """(levels, sigmas) of the least squares of ``Y`` (r,) on ``W`` (r, K): eq (50)'s sigma with
    its covariance times ``correlation`` (rows per independent row, >= 1: the residuals are
    low-passed, eq 50 counts them as independent)."""
    beta, *_ = np.linalg.lstsq(W, Y, rcond=None)
    res = Y - W @ beta
    s2 = float(res @ res) / max(len(Y) - W.shape[1], 1)
    cov = s2 * max(correlation, 1.0) * np.linalg.pinv(W.T @ W)
    return beta, np.sqrt(np.diag(cov))


def plateau(level: np.ndarray, sigma: np.ndarray, flat_p: float = FLAT_P,
            min_bins: int = MIN_PLATEAU) -> tuple[int, float, float, float] | None:
    """The flat top of a friction curve: (first bin, weighted level N, its sigma N, chi-square p)
    of the longest run of top bins (at least ``min_bins``) whose levels agree within their sigmas
    (chi-square of constancy about their weighted mean, p >= ``flat_p``); None when the top
    ``min_bins`` bins already disagree (the curve still changes at the top of the log's speeds)."""
    best = None
    K = len(level)
    for first in range(K - min_bins, -1, -1):
        x, s = np.asarray(level[first:], float), np.asarray(sigma[first:], float)
        w = 1.0 / s ** 2
        mean = float(np.sum(w * x) / np.sum(w))
        p = float(stats.chi2.sf(np.sum(w * (x - mean) ** 2), x.size - 1))
        if p < flat_p:
            break
        best = (first, mean, float(1.0 / math.sqrt(np.sum(w))), p)
    return best


def friction_curve(ctx, cand, cable: int, f_s: float) -> Curve:
    """Cable ``cable`` (1-based)'s friction per speed bin (:func:`speed_edges`) in the step's fit:
    the binned columns through the observations' chain and Z (eq 51) and in the cable's own row
    (eq 42/54, in elongation units as the fit's residual), fitted to the candidate's residual with
    its column times ``f_s`` (N) added back, the other columns at their fit; rows weighted as the
    score weighs channels (``statistics.channel_weights`` over each channel's RMS); sigmas eq (50)'s
    counted over the effective samples (``statistics.effective_samples``)."""
    data, fit, split = ctx.data, cand.fit, ctx.split
    i = cable - 1
    v = data.theta_dot_fast[:, i]
    edges = speed_edges(v)
    bins = data.to_slow(bin_columns(v, edges))                                       # (S, K)
    own = cand.term.identification.basis(data, dict(cand.term.shape))[1][:, i]      # the fitted column (S,)
    n, C, train = data.n, data.C, split.train
    w = np.sqrt(channel_weights(n + C, n)) / ctx.scales
    Z = data.Z[:, :, i]                                                              # (S, N)
    wT = w[:n] / math.sqrt(max(int(train.sum()), 1))
    rows = [((Z[:, :, None] * bins[:, None, :])[train] * wT[None, :, None]).reshape(-1, bins.shape[1])]
    Y = [((fit.torque + f_s * Z * own[:, None])[train] * wT).reshape(-1)]
    if fit.tension is not None:           # elastic cables: the cable's row, elongation = tension / stiffness
        with np.errstate(invalid="ignore", divide="ignore"):
            stiff = fit.tension[:, i] / fit.cable[:, i]
        ok = train & np.isfinite(stiff)
        wc = w[n + i] / math.sqrt(max(int(ok.sum()), 1))
        rows.append(bins[ok] / stiff[ok, None] * wc)
        Y.append((fit.cable[ok, i] + f_s * own[ok] / stiff[ok]) * wc)
    n_train = int(train.sum())
    eff = max(effective_samples(n_train, data.prep.cutoffs["common"].hz, data.prep.rate_hz), 1)
    level, sigma = level_fit(np.concatenate(rows), np.concatenate(Y), n_train / eff)
    return Curve(edges, level, sigma)


def _bins_text(curve: Curve) -> str:
    return ", ".join(f"{lo:g}-{hi:g} rad/s {x:.3g} +- {s:.2g}" for lo, hi, x, s in
                     zip(curve.edges[:-1], curve.edges[1:], curve.level, curve.sigma))


def dry_level(ctx, cand, parameters: dict) -> dict:
    """``parameters`` of a named dry friction with each located cable's f_s read from its friction
    curve (module docstring): the plateau's weighted level with the form error where the curve's top
    bins agree, else the fit's asymptote with a note saying the curve does not flatten.  Other
    effects: ``parameters`` itself.  ``ctx`` the step's ``fitting.StepContext``, ``cand`` the named
    candidate (its fit and term)."""
    from identification.diagnosis.columns.dry_friction import DryFrictionColumns
    from identification.diagnosis.parameters import EQ50_NOTE, FORM_NOTE, cables_of

    if cand.term.name != DryFrictionColumns.effect or cand.fit is None:
        return parameters
    symbol = DryFrictionColumns.columns[0].symbol
    located = set(cables_of(cand.fit, cand.term) or ())
    out = dict(parameters)
    for name, p in parameters.items():
        m = re.fullmatch(rf"{re.escape(symbol)}\((\d+)\)", name)
        if m is None or p.sigma is None or int(m.group(1)) not in located:
            continue
        try:
            curve = friction_curve(ctx, cand, int(m.group(1)), p.value)
        except (ValueError, np.linalg.LinAlgError):
            continue
        flat = plateau(curve.level, curve.sigma)
        if flat is None:
            note = (f"eq (37)'s asymptote: the log's friction curve ({_bins_text(curve)}; dry_level.py) is not "
                    f"flat over its top bins, so the level is the arctan's extrapolation; {EQ50_NOTE}")
            out[name] = dataclasses.replace(p, note=note)
            continue
        first, level, sigma, chi_p = flat
        spread = 0.5 * float(np.ptp(curve.level[first:]))
        note = (f"the friction's level above {curve.edges[first]:g} rad/s, where the log's "
                f"friction is flat (chi-square p {chi_p:.2g}; {_bins_text(curve)}; dry_level.py); eq (37)'s "
                f"asymptote {p.value:.4g} +- {p.sigma:.2g} {p.unit}; form error {spread:.2g} {p.unit} (half the "
                f"plateau's range); {FORM_NOTE}")
        out[name] = dataclasses.replace(p, value=float(level), sigma=float(math.hypot(sigma, spread)), note=note)
    return out
