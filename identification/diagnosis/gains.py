"""Gains of a model on held-out data: residual RMS in SI units, alpha_hat against the camera.

The open-loop re-simulation is in :mod:`identification.diagnosis.resimulation`.  Every result is
a frozen dataclass whose ``to_dict()`` gives the stable JSON fields; arrays for plots stay on the
objects (``series``) and out of the JSON.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from identification.diagnosis.candidates import Fit, MeasuredData, elongation_offsets
from neck_sim.analytic.dynamics import cable_stiffness, static_elongation


def rms(x, axis=0) -> np.ndarray:
    """Root mean square along ``axis``, NaN samples left out."""
    x = np.asarray(x, dtype=float)
    ok = np.isfinite(x)
    n = np.maximum(ok.sum(axis), 1)
    return np.sqrt(np.where(ok, x, 0.0).__pow__(2).sum(axis) / n)


@dataclass(frozen=True)
class ResidualRMS:
    """RMS per channel of a model's residuals over some samples: joint torque (N,) N m (eq 51),
    cable elongation (C,) m and tension (C,) N (eq 42/54; None for a rigid model)."""

    torque_Nm: tuple
    elongation_m: tuple
    tension_N: tuple | None

    def to_dict(self) -> dict:
        return {"torque_Nm": list(self.torque_Nm), "elongation_m": list(self.elongation_m),
                "tension_N": None if self.tension_N is None else list(self.tension_N)}


def residual_rms(data: MeasuredData, fit: Fit, res: np.ndarray, mask: np.ndarray) -> ResidualRMS:
    """RMS per residual type and channel over ``mask`` (S,) of the residuals ``res`` (S, N + C)."""
    n = data.n
    tension = None
    if fit.model.elastic:
        lam = np.clip(fit.group("lambda"), 0, None) if fit.has("lambda") else 0.0
        stiff = cable_stiffness(fit.tension_hat, np.maximum(fit.group("k"), 1.0), lam)
        tension = tuple(rms((res[:, n:] * stiff)[mask]).tolist())
    return ResidualRMS(tuple(rms(res[mask, :n]).tolist()), tuple(rms(res[mask, n:]).tolist()), tension)


def model_elongation(data: MeasuredData, fit: Fit) -> np.ndarray:
    """The model's elongation x_c (S, C) m as the encoders see it, from its tension estimate (eq 54
    quasi-static) minus the offsets its terms add to the measured elongation (x_0 of
    ``pretension``: the encoders were zeroed with the cables already stretched; a dead band's
    lead)."""
    if not fit.model.elastic:
        return np.zeros((data.S, data.C))
    k = np.maximum(fit.group("k"), 1.0)
    lam = np.clip(fit.group("lambda"), 0.0, None) if fit.has("lambda") else np.zeros(data.C)
    return static_elongation(fit.tension_hat, k, lam) - elongation_offsets(fit.model, data)


@dataclass(frozen=True)
class AngleErrors:
    """alpha_hat minus camera over some camera frames: mean |error|, RMS and per joint mean |error| (deg)."""

    mean_abs_deg: float
    rms_deg: float
    per_joint_mean_abs_deg: tuple

    @classmethod
    def of(cls, err: np.ndarray) -> "AngleErrors":
        """From errors (F, N) deg; NaN when there are no frames."""
        if not err.size:
            return cls(math.nan, math.nan, ())
        return cls(float(np.mean(np.abs(err))), float(np.sqrt(np.mean(err ** 2))),
                   tuple(np.mean(np.abs(err), 0).tolist()))

    def to_dict(self) -> dict:
        return {"mean_abs_deg": self.mean_abs_deg, "rms_deg": self.rms_deg,
                "per_joint_mean_abs_deg": list(self.per_joint_mean_abs_deg)}


@dataclass(frozen=True, eq=False)
class AlphaHatErrors:
    """alpha_hat of one model against the camera on the primary held-out fold and on every sample;
    ``t`` (F,) s and ``error_deg`` (F, N) the series for plots."""

    holdout: AngleErrors
    all: AngleErrors
    t: np.ndarray = field(repr=False)
    error_deg: np.ndarray = field(repr=False)

    def to_dict(self) -> dict:
        return {"holdout": self.holdout.to_dict(), "all": self.all.to_dict()}


def alpha_hat_errors(data: MeasuredData, fits, holdout: np.ndarray, step: int = 1) -> list[AlphaHatErrors]:
    """alpha_hat by eq (35) corrected with each model's elongation, against the camera frames.

    Integrated from the first slow-grid sample (filtered camera pose) over every ``step``-th
    encoder sample; errors (deg) at the camera frames within ``holdout`` (S,) bool and at all.
    Every sample by default: eq (35)'s forward steps err to first order in the step, and every
    4th sample drifted the top joint by 1 deg over a 42 s log (|rho| with time 0.35, a
    structure); at every sample 0.13.
    """
    from neck_sim.analytic import estimate_alpha_pinv

    fast_t = data.t_fast
    sel = np.nonzero((fast_t >= data.t[0]) & (fast_t <= data.t[-1]))[0][::step]
    tq = fast_t[sel]
    theta = data.prep.fast.theta[sel]
    xs = []
    for fit in fits:
        x = model_elongation(data, fit)
        xs.append(np.stack([np.interp(tq, data.t, x[:, j]) for j in range(data.C)], axis=1))
    xs = np.stack(xs)
    B = len(fits)
    alpha0 = np.broadcast_to(data.alpha[0], (B, data.n))
    a_hat = estimate_alpha_pinv(np.broadcast_to(theta, xs.shape), data.params, xs, alpha0=alpha0)
    tc_all, ac_all = data.prep.camera
    out = []
    for b in range(B):
        # a model with a camera delay compares the frame stamped t + delay with alpha_hat(t)
        tc = tc_all - sum(t.identification.fit_camera_shift(dict(t.shape)) for t in fits[b].model.terms)
        inside = (tc >= tq[0]) & (tc <= tq[-1])
        tc, ac = tc[inside], ac_all[inside]
        held_out = np.interp(tc, data.t, holdout.astype(float)) > 0.5
        at = np.stack([np.interp(tc, tq, a_hat[b, :, j]) for j in range(data.n)], axis=1)
        err = np.degrees(at - ac)
        out.append(AlphaHatErrors(AngleErrors.of(err[held_out]), AngleErrors.of(err), tc, err))
    return out
