"""Calibrated uncertainty of the identified parameters, beside the paper's eq (50).

Eq (50), C_X = sigma_rho^2 (W^T W)^-1, assumes independent residuals and exact regressors.  Here
neither holds: the signals are low-pass filtered and decimated (the residuals of neighbouring
samples are strongly correlated) and the regressors carry the camera's noise (x_c of eq 27 and
the joint accelerations come from the camera's angles: errors in variables, which bias the
estimate as well as spread it).  Over camera-noise seeds eq (50)'s sigmas are 2-4x smaller than
the spread of the estimates, and the noise biases k and lambda by about one spread.

Two estimates; the larger per parameter is reported, on the bias-corrected value (plus, for the
elastic model's f_s, a model-form term: see ``identification.paper.calibrated_uncertainty``):

* **Camera-noise bootstrap** (``camera_noise_bootstrap``): the log is identified again ``n``
  times with the camera's frames replaced by the filtered camera angles plus fresh Gaussian noise
  of the log's stated camera precision (``sensors.camera_noise``, rad), every other signal as
  measured, the motors' cutoff and the slack masks as chosen on the log, the camera's cutoff
  chosen again (its choice moves with the noise), and ``n // 2`` times more with noise of twice
  that variance.  The filtered angles keep the log's own noise in the band that reaches the
  regressors, so the log, the first replicates and the second stand at 1, 2 and 3 times the
  camera's noise variance: three points of the estimate as a function of the noise, the idea of
  SIMEX (Cook & Stefanski, JASA 89, 1994).  The first replicates' mean minus the log's estimate,
  b1, is the first-order bias the noise causes (errors in variables, filtering); it is
  subtracted (a linear extrapolation to no noise).  The second difference of the three points,
  d2 = m2 - 2 m1 + value_ls, is what a linear extrapolation misses when the bias grows faster
  than the noise variance (exactly so for a quadratic); its estimate is noisy (its sampling
  spread is about half the replicates' spread), so it is not applied but kept in the sigma as the
  uncertainty of the correction, with b1 (the correction is measured around the estimate and the
  filtered angles, not the truth, and removed only about half of the true bias on the benchmark's
  seeds): sigma_boot = sqrt(s^2 (1 + 1/n) + b1^2 + d2^2), s the first replicates' standard
  deviation.
* **HAC sandwich** (``hac_covariance``): (W^T W)^-1 S (W^T W)^-1 with S the Newey-West (Bartlett
  kernel) long-run covariance of the per-sample scores W_s^T rho_s, bandwidth by Andrews' AR(1)
  plug-in rule.  It needs no noise model and holds for any error source the residuals show
  (force errors, model mismatch), but not for the errors-in-variables bias.

``calibrate`` combines them with eq (50) into an :class:`Uncertainty` per model.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Collection

import numpy as np
import numpy.typing as npt

from identification import regressors as reg
from identification.least_squares import LSResult
from identification.preprocessing import Measurements, PreprocessSettings, Prepared, prepare
from identification.threads import single_thread
from neck_sim.params import NeckParams

__all__ = ["Uncertainty", "Replicates", "row_samples", "andrews_bandwidth", "hac_covariance", "camera_noise_bootstrap",
           "calibrate", "format_uncertainty", "refit", "N_BOOTSTRAP"]

#: Replicates of the camera-noise bootstrap at the log's noise (sigma known to about 1/sqrt(2 n) =
#: 11 %); half as many again run at twice its variance (``camera_noise_bootstrap``).
N_BOOTSTRAP = 40


@dataclass(frozen=True, eq=False)
class Replicates:
    """Bootstrap values of one model, (n, p) with camera noise of the log's variance added to its
    filtered angles and (n2, p) with twice that variance added (n2 = 0: first order only)."""

    at_1x: np.ndarray
    at_2x: np.ndarray


@dataclass(frozen=True, eq=False)
class Uncertainty:
    """Calibrated statistics of one model's parameters, arrays (p,) in the order of ``names``.

    ``value_ls`` the least-squares value (eq 49), ``sigma_eq50`` eq (50)'s sigma; ``bias`` the
    first-order camera-noise bias b1 (0 without bootstrap), ``value`` = value_ls - bias;
    ``bias_second_order`` the second difference d2 (module docstring; zeros without replicates at
    twice the noise); ``sigma_bootstrap`` (b1 and d2 included), ``sigma_hac``; ``sigma`` = the larger of the two
    (units of the parameter), with ``sigma_model`` in quadrature when set.  ``identified`` False where the data do not determine the
    parameter (:mod:`identification.gaps`).
    """

    names: tuple
    units: tuple
    value_ls: np.ndarray
    sigma_eq50: np.ndarray
    bias: np.ndarray
    value: np.ndarray
    sigma_bootstrap: np.ndarray
    sigma_hac: np.ndarray
    sigma: np.ndarray
    hac_bandwidth: int
    n_bootstrap: int
    camera_noise: float
    identified: np.ndarray
    sigma_model: np.ndarray | None = None     # model-form term in sigma (``with_model_term``), or None
    bias_second_order: np.ndarray | None = None   # d2 (p,), kept in sigma_bootstrap; None: not measured
    n_bootstrap_2x: int = 0                   # replicates at twice the camera's noise variance

    def group(self, attr: str, symbol: str) -> np.ndarray:
        """``attr`` (e.g. "value", "sigma") of the parameters named ``symbol(i)``, in cable order."""
        idx = [i for i, n in enumerate(self.names) if n.split("(")[0] == symbol]
        if not idx:
            raise KeyError(f"{symbol!r}: no such parameter group (parameters: {', '.join(self.names)})")
        return np.asarray(getattr(self, attr))[idx]

    def with_identified(self, identified: npt.ArrayLike) -> "Uncertainty":
        kw = {k: getattr(self, k) for k in self.__dataclass_fields__}
        kw["identified"] = np.asarray(identified, bool)
        return Uncertainty(**kw)

    def with_model_term(self, term: npt.ArrayLike) -> "Uncertainty":
        """``term`` (p,) in the parameters' units added in quadrature to ``sigma``: a bias of the
        model's form that neither the residuals (HAC) nor the camera noise (bootstrap) show."""
        kw = {k: getattr(self, k) for k in self.__dataclass_fields__}
        kw["sigma_model"] = np.abs(np.asarray(term, dtype=float))
        kw["sigma"] = np.hypot(np.maximum(self.sigma_bootstrap, self.sigma_hac), kw["sigma_model"])
        return Uncertainty(**kw)

    def to_dict(self) -> dict:
        params = {}
        for i, n in enumerate(self.names):
            params[n] = {"value": float(self.value[i]), "sigma": float(self.sigma[i]), "unit": self.units[i],
                         "identified": bool(self.identified[i]), "value_least_squares": float(self.value_ls[i]),
                         "noise_bias": float(self.bias[i]), "sigma_bootstrap": float(self.sigma_bootstrap[i]),
                         "sigma_hac": float(self.sigma_hac[i]), "sigma_eq50_paper": float(self.sigma_eq50[i])}
            if self.sigma_model is not None:
                params[n]["sigma_model_form"] = float(self.sigma_model[i])
            if self.bias_second_order is not None:
                params[n]["noise_bias_second_order"] = float(self.bias_second_order[i])
        return {"parameters": params, "hac_bandwidth_samples": self.hac_bandwidth,
                "bootstrap_replicates": self.n_bootstrap, "bootstrap_replicates_twice_noise": self.n_bootstrap_2x,
                "camera_noise_rad": self.camera_noise}


def row_samples(n_samples: int, n_joints: int, taut: np.ndarray | None = None, *, torque: bool = True,
                tension: bool = True) -> np.ndarray:
    """Slow-grid sample index of every row of a ``regressors`` model, in its row order.

    Tension rows (``tension``) come first, one per taut (sample, cable) in sample-major order
    (``taut`` (S, m) bool, needed for them); torque rows (``torque``) follow, N per sample.
    """
    parts = []
    if tension:
        if taut is None:
            raise ValueError("row_samples: the tension rows need the taut mask (S, m)")
        parts.append(np.nonzero(np.asarray(taut, bool))[0])
    if torque:
        parts.append(np.repeat(np.arange(n_samples), n_joints))
    return np.concatenate(parts)


def _scores(W, residual, rows, n_samples) -> np.ndarray:
    """Per-sample scores g_s = sum over the rows of sample s of W_r rho_r, (S, p)."""
    g = np.zeros((n_samples, W.shape[1]))
    np.add.at(g, rows, W * residual[:, None])
    return g


def andrews_bandwidth(scores: np.ndarray) -> int:
    """Bartlett-kernel bandwidth by Andrews' (1991) AR(1) plug-in rule for scores (S, p).

    L = 1.1447 (a1 S)^(1/3), a1 = sum 4 rho^2 s^4 / ((1 - rho)^6 (1 + rho)^2) / sum s^4 / (1 - rho)^4
    over the columns' AR(1) coefficients rho and innovation variances s^2; at most S / 3.
    """
    g = np.asarray(scores, dtype=float)
    S = g.shape[0]
    x0, x1 = g[:-1], g[1:]
    den = np.einsum("sj,sj->j", x0, x0)
    ok = den > 0
    rho = np.where(ok, np.einsum("sj,sj->j", x0, x1) / np.where(ok, den, 1.0), 0.0)
    rho = np.clip(rho, -0.97, 0.97)
    s2 = np.mean((x1 - rho * x0) ** 2, axis=0)
    num = np.sum(4 * rho ** 2 * s2 ** 2 / ((1 - rho) ** 6 * (1 + rho) ** 2))
    dnm = np.sum(s2 ** 2 / (1 - rho) ** 4)
    a1 = num / dnm if dnm > 0 else 0.0
    return int(min(max(np.ceil(1.1447 * (a1 * S) ** (1 / 3)), 1), S // 3))


def hac_covariance(W: np.ndarray, residual: np.ndarray, rows: np.ndarray, n_samples: int,
                   bandwidth: int | None = None) -> tuple[np.ndarray, int]:
    """Newey-West covariance of the least-squares estimate of W v = Y, and the bandwidth used.

    W (r, p) and residual (r,) as solved (weights applied), ``rows`` (r,) each row's sample index
    (``row_samples``); ``bandwidth`` in samples (None: ``andrews_bandwidth``).  Returns
    ((p, p) covariance in the units of v, bandwidth).
    """
    W = np.asarray(W, dtype=float)
    g = _scores(W, np.asarray(residual, dtype=float), np.asarray(rows), n_samples)
    L = andrews_bandwidth(g) if bandwidth is None else int(bandwidth)
    S = g.T @ g
    for lag in range(1, L + 1):
        gl = g[lag:].T @ g[:-lag]
        S += (1.0 - lag / (L + 1.0)) * (gl + gl.T)
    r, p = W.shape
    S *= r / (r - p)
    A = np.linalg.inv(W.T @ W)
    cov = A @ S @ A
    return 0.5 * (cov + cov.T), L


def _lstsq(W, Y) -> np.ndarray:
    """Least squares by the normal equations of the column-scaled W (the solved models are
    well conditioned: scaled condition numbers below 100, so nothing is lost, and it is 20x
    faster than an SVD on two shared cores).  W (r, p), Y (r,); the values (p,).

    W^T W is formed once and scaled by its diagonal's square roots (the column norms): the same
    system as that of W's scaled copy to rounding, without the copy and the norms' passes over W."""
    A = W.T @ W
    norms = np.sqrt(np.diag(A))
    norms[norms == 0] = 1.0
    return np.linalg.solve(A / np.outer(norms, norms), (W.T @ Y) / norms) / norms


def refit(prep: Prepared, params: NeckParams, taut: np.ndarray | None, *, weight: float,
          models: Collection[str]) -> dict:
    """Values (p,) per model of :func:`identification.paper.identify`'s chain on ``prep``.

    Friction alone, then friction + elastic with ``taut`` fixed, then the variable-stiffness model
    with the elastic model's f_s (the friction model's without it); no statistics.
    """
    dyn = reg.joint_torques(prep, params)       # the rows need M alpha_ddot + c + g only, not M
    out = {"friction": _lstsq(*reg.friction_model(prep, params, dyn)[:2])}
    C = params.n_cables
    f_s = out["friction"]
    if "elastic" in models:
        out["elastic"] = _lstsq(*reg.elastic_model(prep, params, weight=weight, taut=taut, dyn=dyn)[:2])
        f_s = out["elastic"][2 * C:]
    if "variable" in models:
        out["variable"] = _lstsq(*reg.variable_stiffness_model(prep, params, f_s, taut=taut)[:2])
    return out


def camera_noise_bootstrap(prep: Prepared, params: NeckParams, taut: np.ndarray | None, *, weight: float,
                           models: Collection[str], settings: PreprocessSettings,
                           n: int = N_BOOTSTRAP, seed: int = 0, second_order: bool = True) -> dict:
    """:class:`Replicates` per model, re-identified with fresh camera noise (module docstring):
    ``n`` at the log's noise variance and, with ``second_order``, ``max(n // 2, 2)`` at twice it.

    The frames are the camera angles as filtered on the log (interpolated at the frame times)
    plus N(0, ``params.sensors.camera_noise``^2) (resp. twice that variance) per frame and joint;
    the motors' cutoff as chosen on the log, the camera's chosen again by ``settings`` (residual
    analysis unless given).
    """
    rng = np.random.default_rng(seed)
    at_1x = _replicate_values(prep, params, taut, weight=weight, models=models, settings=settings, n=n,
                              scale=1.0, rng=rng)
    at_2x = (_replicate_values(prep, params, taut, weight=weight, models=models, settings=settings,
                               n=max(n // 2, 2), scale=np.sqrt(2.0), rng=rng) if second_order
             else {k: np.zeros((0, v.shape[1])) for k, v in at_1x.items()})
    return {k: Replicates(v, at_2x[k]) for k, v in at_1x.items()}


def _replicate_values(prep: Prepared, params: NeckParams, taut: np.ndarray | None, *, weight: float,
                      models: Collection[str], settings: PreprocessSettings, n: int, scale: float,
                      rng: np.random.Generator) -> dict:
    """Values (n, p) per model of ``n`` replicates with camera noise ``scale`` times the log's sigma."""
    if prep.camera is None or prep.fast is None or prep.alpha is None:
        raise ValueError("camera noise bootstrap: needs the raw camera frames and control-rate signals")
    tc, _ = prep.camera
    alpha = prep.alpha
    clean = np.stack([np.interp(tc, prep.t, alpha[:, j]) for j in range(alpha.shape[1])], axis=1)
    # the motors' cutoff is fixed (their signals are the log's own); the camera's is chosen again
    # on every replicate when the log's was (its choice moves with the noise, and so does f_s).
    # Reusing the log's camera cutoff instead (its residual analysis is over a third of a replicate)
    # lost coverage: over 60 camera-noise seeds of the control test the variable model's c_a fell
    # from 0.63 / 0.95 within 1 / 2 sigma to 0.58 / 0.83 (benchmarks/bench_coverage.py)
    fixed = PreprocessSettings(filter_order=settings.filter_order, motor_cutoff_hz=prep.cutoffs["motors"].hz,
                               camera_cutoff_hz=settings.camera_cutoff_hz, trim_s=settings.trim_s,
                               common_bandwidth=settings.common_bandwidth)
    rate = prep.motor_rate_hz / prep.decimation
    sigma = float(params.sensors.camera_noise) * scale
    fast = prep.fast
    frames = [clean + sigma * rng.standard_normal(clean.shape) for _ in range(n)]     # drawn in order

    def one(alpha_camera: np.ndarray) -> dict:
        p = prepare(Measurements(fast.t, fast.theta, fast.force, tc, alpha_camera), params, fixed,
                    camera_rate_hz=rate, reuse=prep, transmission=True)
        if p.n_samples != prep.n_samples:
            raise RuntimeError("camera noise bootstrap: the replicate's grid differs from the log's")
        return refit(p, params, taut, weight=weight, models=models)

    # the replicates are independent and their compiled kernels and BLAS release the GIL; BLAS
    # on one thread each (threads.py: its threads would only spin on the (r, 3m) products)
    with single_thread(), ThreadPoolExecutor(max_workers=min(n, os.cpu_count() or 1)) as pool:
        values = list(pool.map(one, frames))
    return {k: np.asarray([v[k] for v in values]) for k in values[0]} if values else {}


def calibrate(ls: LSResult, W: np.ndarray, rows: np.ndarray, n_samples: int,
              replicates: Replicates | np.ndarray | None = None, *, camera_noise: float) -> Uncertainty:
    """:class:`Uncertainty` of one model: eq (50), HAC and (when given) the bootstrap replicates.

    ``W`` (r, p) the solved (weighted) observation matrix of ``ls``, ``rows`` its rows' sample
    indices; ``replicates`` from :func:`camera_noise_bootstrap` (an array (n, p): replicates at
    the log's noise only, no second-order term) or None.
    """
    cov, L = hac_covariance(W, ls.residual, rows, n_samples)
    s_hac = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    p = ls.value.size
    if isinstance(replicates, np.ndarray):
        replicates = Replicates(replicates, np.zeros((0, p)))
    d2 = None
    nb2 = 0
    if replicates is not None and len(replicates.at_1x) > 1:
        reps = np.asarray(replicates.at_1x)
        nb = reps.shape[0]
        m1 = reps.mean(axis=0)
        bias = m1 - ls.value
        d2 = np.zeros(p)
        if len(replicates.at_2x) > 1:
            nb2 = len(replicates.at_2x)
            d2 = np.asarray(replicates.at_2x).mean(axis=0) - 2.0 * m1 + ls.value
        s_boot = np.sqrt(reps.var(axis=0, ddof=1) * (1.0 + 1.0 / nb) + bias ** 2 + d2 ** 2)
    else:
        nb, bias, s_boot = 0, np.zeros(p), np.zeros(p)
    value = ls.value - bias
    return Uncertainty(ls.names, ls.units, ls.value, ls.sigma, bias, value, s_boot, s_hac,
                       np.maximum(s_boot, s_hac), L, nb, float(camera_noise), np.ones(p, bool),
                       bias_second_order=d2, n_bootstrap_2x=nb2)


def format_uncertainty(by_model: dict) -> str:
    """The calibrated table: per model and parameter, the least-squares value with eq (50)'s
    sigma (the paper's), the camera-noise bias (first order, applied; second order, in the sigma
    only), the corrected value with its calibrated sigma (and the two estimates it is the larger
    of), and whether the data identify it."""
    if not by_model:
        return ""
    head = (f"{'':10} {'least squares':>13} {'eq (50) sigma':>13} {'noise bias':>11} {'2nd order':>10} {'value':>11} "
            f"{'sigma':>10} {'rel':>7} {'HAC':>10} {'bootstrap':>10}  identified")
    lines = ["Calibrated uncertainty: value = least squares - camera-noise bias; sigma = max(HAC, bootstrap), "
             "the bootstrap's holding the bias and its second-order term, with the model-form term in quadrature "
             "where one is given; eq (50) sigma is the paper's (independent residuals, 2-4x optimistic here)"]
    for model, u in by_model.items():
        lines += [f"{model} model (HAC bandwidth {u.hac_bandwidth} samples, {u.n_bootstrap} + {u.n_bootstrap_2x} "
                  f"bootstrap replicates at camera noise {np.degrees(u.camera_noise):.2g} deg and twice its variance)",
                  head]
        d2 = u.bias_second_order if u.bias_second_order is not None else np.zeros(len(u.names))
        if u.sigma_model is not None and np.any(u.sigma_model):
            lines.append("  model-form term: " + ", ".join(f"{n} {m:.3g}" for n, m in zip(u.names, u.sigma_model) if m))
        for i, n in enumerate(u.names):
            rel = 100 * u.sigma[i] / abs(u.value[i]) if u.value[i] != 0 else np.inf
            lines.append(f"{n:10} {u.value_ls[i]:13.5g} {u.sigma_eq50[i]:13.3g} {u.bias[i]:11.3g} {d2[i]:10.3g} "
                         f"{u.value[i]:11.5g} "
                         f"{u.sigma[i]:10.3g} {rel:6.1f}% {u.sigma_hac[i]:10.3g} {u.sigma_bootstrap[i]:10.3g}  "
                         f"{'yes' if u.identified[i] else 'NO'}")
    return "\n".join(lines)
