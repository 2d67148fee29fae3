"""Simulation-extrapolation (SIMEX) of a finding's magnitude for the camera's angle noise.

When the neck has fewer cables than joints (C < N) the diagnosis takes the joint angles, and
their first and second derivatives, from the camera alone (eq 35 cannot rebuild them from the
encoders).  A column that carries the head's inertia on those angles (the payload: M(alpha)
alpha_ddot, eq 30) then holds the camera's noise twice differentiated, and so does the torque
observation (the nominal neck's M(alpha) alpha_ddot): errors in variables, which bias the
least-squares magnitude towards zero and below it (the nominal term's noise correlates with the
column's).  Measured on the 10-joint, 4-cable neck: +2.4 % with a noise-free camera, -13 % at the
prototype's 1 deg (docs/your-own-neck.md, section 7).

SIMEX (Cook & Stefanski, JASA 89, 1994; Carroll et al., *Measurement Error in Nonlinear Models*,
2nd ed., 2006, ch. 5) measures that bias on the log itself.  The raw camera frames already carry
noise of the stated precision sigma (``sensors.camera_noise``, rad, per frame and joint);
replicates of them with N(0, lambda sigma^2) more carry (1 + lambda) sigma^2.  Each replicate goes
through the preprocessing with the cutoffs chosen on the log (the same filter chain, so the noise
reaches the columns the same way and the estimate is a smooth function of lambda; with the
camera's cutoff chosen again the estimate barely moves past lambda = 0.5, the cutoff falling with
the noise, and cannot be extrapolated), and through the step's estimator: the baseline fitted
again (its channel weights from its own residuals), then the named model; the log's training
folds.  The replicates come in antithetic pairs (+u, -u), whose mean cancels the estimate's
first-order response to the added noise and keeps the bias.  The mean estimate at lambda = 0
(the log), 0.5, 1 and 2 is extrapolated to lambda = -1 (no noise) by a straight line in lambda.
The quadratic, the classical extrapolant, moved by -0.4 to +12.5 % of the payload with the
replicates' seed on one 15.6 s log (its extrapolation multiplies the means' errors several
times), and a rational one, exact for one regressor, put its pole near -1 and swung by tens of
percent; the straight line moved by 2 %, and under-corrects a convex curve (it keeps 2-8 % of the
payload's bias on these logs).  The sigma keeps the log's own realization of the noise, which the
extrapolation does not remove (the replicates' spread per unit lambda), and the extrapolant's
form (|quadratic - straight line|; :func:`simex_extrapolate`).

    from identification.diagnosis.errors_in_variables import simex_estimates, simex_extrapolate, step_refit
    refit = step_refit(base_model, base_model.plus(term), split, settings, None, ["payload"])
    estimates = simex_estimates(data, refit)                       # LAMBDAS x (2 REPLICATES, 1)
    value, sigma, detail = simex_extrapolate(LAMBDAS, [e[:, 0] for e in estimates], naive, naive_sigma)

Applied by :func:`corrected_parameters` to the magnitudes of a named finding whose columns ask for
it (``EffectColumns.camera_noise_bias``), only when C < N: with C >= N the diagnosis is unchanged.
The detection statistics (F-test, Wilcoxon, cross-validated improvement) are not corrected.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from identification.diagnosis.parameters import SIMEX_NOTE
from identification.preprocessing import Measurements

__all__ = ["LAMBDAS", "REPLICATES", "SimexDetail", "simex_extrapolate", "noisier", "step_refit", "simex_estimates",
           "corrected_parameters"]

#: Extra camera-noise variance, in multiples of the stated sigma^2, of the SIMEX replicates.
LAMBDAS = (0.5, 1.0, 2.0)
#: Antithetic pairs per lambda (each replicate refits the step's baseline and the named model).
REPLICATES = 10



@dataclasses.dataclass(frozen=True)
class SimexDetail:
    """The SIMEX of one magnitude: ``naive`` the log's estimate, ``means`` (L,) and ``stderr`` (L,)
    of the antithetic pairs' means at ``lambdas``, ``quadratic`` the quadratic's extrapolation
    (for comparison), and the sigma's parts (added in quadrature): ``sigma_naive`` (the fit's
    own), ``sigma_realization`` (the spread of single replicates scaled to the stated noise: how
    far one camera-noise realization, the log's own, moves the estimate), ``sigma_spread`` (the
    means' standard errors through the extrapolant), ``sigma_extrapolant`` (|quadratic - straight line|:
    how much the extrapolant's form moves it)."""

    lambdas: tuple
    naive: float
    means: tuple
    stderr: tuple
    quadratic: float
    sigma_naive: float
    sigma_realization: float
    sigma_spread: float
    sigma_extrapolant: float


def _polynomial_at_minus_one(lam: np.ndarray, m: np.ndarray, w: np.ndarray, degree: int) -> float:
    """The weighted polynomial of ``degree`` in lambda through the points (lam, m), at lambda = -1."""
    A = np.vander(lam, degree + 1, increasing=True) * w[:, None]
    coef, *_ = np.linalg.lstsq(A, m * w, rcond=None)
    return float(np.polynomial.polynomial.polyval(-1.0, coef))


def simex_extrapolate(lambdas, estimates, naive: float, naive_sigma: float) -> tuple[float, float, SimexDetail]:
    """(value, sigma, detail) of one magnitude from its SIMEX replicates.

    ``lambdas`` (L >= 2,) extra noise variances (multiples of the stated one), ``estimates`` L
    arrays of replicate estimates in antithetic pairs (:func:`simex_estimates`: rows 2i, 2i + 1),
    ``naive`` the estimate on the data as measured (lambda = 0) and ``naive_sigma`` its fit's sigma.
    value: the straight line in lambda through the log's point and the pairs' means (weighted by
    their standard errors), at lambda = -1.  sigma, in quadrature: ``naive_sigma``; the single
    replicates' variance per unit lambda, pooled over the lambdas (one realization of the stated
    noise: the log's own error, which no extrapolation removes); the means' standard errors
    propagated to the extrapolation (one at a time, by their effect on it); the difference of the
    quadratic and the straight line's extrapolations (the extrapolant's form, which the data do
    not fix: on the unit test's regression the straight line leaves -2.4 % of a -9.6 % attenuation,
    the quadratic -0.2 %).
    """
    lam = np.concatenate([[0.0], np.asarray(lambdas, dtype=float)])
    reps = [np.asarray(e, dtype=float).ravel() for e in estimates]
    if lam.size < 3 or len(reps) != lam.size - 1 or any(r.size < 4 or r.size % 2 for r in reps):
        raise ValueError(f"simex_extrapolate: expected at least 2 lambdas with at least 2 antithetic pairs each, "
                         f"got {lam.size - 1} lambdas, sizes {[r.size for r in reps]}")
    if np.any(lam[1:] <= 0) or np.unique(lam).size != lam.size:
        raise ValueError(f"simex_extrapolate: extra noise multiples must be distinct and > 0, got {list(lambdas)}")
    pairs = [r.reshape(-1, 2).mean(axis=1) for r in reps]
    means = np.concatenate([[naive], [p.mean() for p in pairs]])
    se = np.concatenate([[0.0], [p.std(ddof=1) / math.sqrt(p.size) for p in pairs]])
    # the log's own point has no replicate error; the others weigh by their standard error,
    # floored so that no point takes every weight
    floor = max(float(se[1:].mean()), 1e-12 * max(abs(naive), 1.0))
    w = 1.0 / np.maximum(se, floor)
    value = _polynomial_at_minus_one(lam, means, w, 1)
    parts = []
    for k in range(1, lam.size):
        m = means.copy()
        m[k] += se[k]
        parts.append(_polynomial_at_minus_one(lam, m, w, 1) - value)
    spread = float(math.sqrt(sum(p * p for p in parts)))
    # first order in the added noise's amplitude: a replicate's variance grows as lambda
    realization = float(math.sqrt(np.mean([r.var(ddof=1) / lam_k for r, lam_k in zip(reps, lam[1:])])))
    quadratic = _polynomial_at_minus_one(lam, means, w, 2)
    sigma = float(math.sqrt(naive_sigma ** 2 + realization ** 2 + spread ** 2 + (quadratic - value) ** 2))
    detail = SimexDetail(tuple(float(x) for x in lam[1:]), float(naive), tuple(float(x) for x in means[1:]),
                         tuple(float(x) for x in se[1:]), quadratic, float(naive_sigma), realization, spread,
                         abs(quadratic - value))
    return value, sigma, detail


def noisier(data, noise: np.ndarray, fixed_chain: bool = True):
    """A :class:`~identification.diagnosis.measured.MeasuredData` of the same log with ``noise``
    (K, N) rad added to its raw camera frames, prepared with the motor and camera cutoffs chosen on
    ``data``'s log (``fixed_chain``; False: chosen again on the noisier frames); the motor signals
    as measured."""
    from identification.diagnosis.measured import MeasuredData

    prep = data.prep
    if prep.camera is None or prep.fast is None:
        raise ValueError("simex: the data keep no raw camera frames")
    tc, ac = prep.camera
    if noise.shape != ac.shape:
        raise ValueError(f"simex: noise of shape {noise.shape} for camera frames of shape {ac.shape}")
    fast = prep.fast
    settings = data.settings
    if fixed_chain:
        settings = dataclasses.replace(settings, motor_cutoff_hz=prep.cutoffs["motors"].hz,
                                       camera_cutoff_hz=prep.cutoffs["camera"].hz)
    # the motor arrays are the log's own: their filtered and decimated signals are taken from its
    # preparation (prepare's reuse, bit for bit the same), only the camera side is prepared again
    out = MeasuredData(Measurements(fast.t, fast.theta, fast.force, tc, ac + noise), data.params, settings,
                       reuse=prep)
    if out.S != data.S or not np.array_equal(out.t, data.t):
        raise RuntimeError("simex: a replicate's slow grid differs from the log's")
    return out


def step_refit(base_model, model, split, settings, state, names):
    """The estimator a SIMEX replicate repeats: the step's baseline ``base_model`` fitted as the
    diagnosis fits it (:func:`identification.diagnosis.fitting.fit_baseline` from ``state``, its
    channel scales from its own residuals), then ``model`` from that baseline's state; returns
    ``refit(data) -> values (len(names),)`` of the parameters ``names``."""
    from identification.diagnosis.candidates import fit_model
    from identification.diagnosis.fitting import fit_baseline

    def refit(rep) -> np.ndarray:
        base, scales = fit_baseline(rep, base_model, split, settings, state)
        fit = fit_model(rep, model, split.train, scales, base.state, iterations=settings.iterations)
        return np.array([fit.value[list(fit.names).index(n)] for n in names])

    return refit


def simex_estimates(data, refit, *, lambdas=LAMBDAS, replicates: int = REPLICATES,
                    seed: int = 0, fixed_chain: bool = True) -> list[np.ndarray]:
    """Per lambda, the (2 ``replicates``, p) values ``refit(rep)`` on replicates of ``data`` with
    extra camera noise of variance lambda ``sensors.camera_noise``^2 (:func:`noisier`), in
    antithetic pairs (rows 2i and 2i + 1 add +u and -u: the estimate's first-order response to
    the added noise is odd in it and cancels in the pair's mean, the bias is even and stays).
    Seeded: the same call gives the same values."""
    sigma = float(data.params.sensors.camera_noise)
    if not sigma > 0:
        raise ValueError("simex: sensors.camera_noise is 0: a noise-free camera needs no correction")
    rng = np.random.default_rng(seed)
    shape = data.prep.camera[1].shape
    out = []
    for lam in lambdas:
        vals = []
        for _ in range(replicates):
            u = math.sqrt(lam) * sigma * rng.standard_normal(shape)
            vals += [refit(noisier(data, u, fixed_chain)), refit(noisier(data, -u, fixed_chain))]
        out.append(np.asarray(vals))
    return out


def corrected_parameters(ctx, cand, parameters: dict, state=None) -> dict:
    """``parameters`` of a named candidate (:func:`identification.diagnosis.parameters.term_parameters`)
    with the magnitudes of its term SIMEX-corrected for the camera's noise when its columns ask for
    it (``camera_noise_bias``) and the neck has fewer cables than joints; else ``parameters``
    itself.  ``ctx`` the step's :class:`~identification.diagnosis.fitting.StepContext`, ``state``
    the fit state its baseline was fitted from (None at step 1)."""
    term, data = cand.term, ctx.data
    if not term.identification.camera_noise_bias or data.C >= data.n:
        return parameters
    if not data.params.sensors.camera_noise > 0:
        return parameters
    symbols = {col.symbol for col in term.identification.columns}
    names = [n for n in cand.fit.names if n.split("(")[0] in symbols and n in parameters]
    if not names:
        return parameters
    base = ctx.base.fit.model
    refit = step_refit(base, base.plus(term), ctx.split, ctx.settings, state, names)
    est = simex_estimates(data, refit)
    out = dict(parameters)
    for i, n in enumerate(names):
        p = parameters[n]
        value, sigma, _ = simex_extrapolate(LAMBDAS, [e[:, i] for e in est], p.value, p.sigma or 0.0)
        out[n] = dataclasses.replace(p, value=value, sigma=sigma, note=SIMEX_NOTE)
    return out
