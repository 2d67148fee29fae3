"""Gains of a model on held-out data: residual RMS in SI units, alpha_hat against the camera, re-simulation."""

from __future__ import annotations

import math

import numpy as np

from identification.candidates import Fit, MeasuredData, pretension_offsets
from identification.diagnosis.split import Split
from neck_sim.analytic.dynamics import cable_stiffness, static_elongation
from neck_sim.params import NeckParams


def rms(x, axis=0):
    x = np.asarray(x, dtype=float)
    ok = np.isfinite(x)
    n = np.maximum(ok.sum(axis), 1)
    return np.sqrt(np.where(ok, x, 0.0).__pow__(2).sum(axis) / n)


def residual_rms(data: MeasuredData, fit: Fit, res: np.ndarray, mask: np.ndarray) -> dict:
    """RMS per residual type and channel over ``mask``, SI units: torque (N m, eq 51), elongation
    (m) and tension (N, eq 42/54; None for rigid models) from the residuals ``res`` (S, N + C)."""
    n = data.n
    out = {"torque_Nm": rms(res[mask, :n]).tolist(), "elongation_m": rms(res[mask, n:]).tolist()}
    if fit.model.elastic:
        lam = np.clip(fit.group("lambda"), 0, None) if fit.has("lambda") else 0.0
        stiff = cable_stiffness(fit.tension_hat, np.maximum(fit.group("k"), 1.0), lam)
        out["tension_N"] = rms((res[:, n:] * stiff)[mask]).tolist()
    else:
        out["tension_N"] = None
    return out


def model_elongation(data: MeasuredData, fit: Fit) -> np.ndarray:
    """The model's elongation x_c (S, C) m from its tension estimate (eq 54 quasi-static, x_0 of
    ``pretension`` subtracted: the encoders were zeroed with the cables already stretched)."""
    if not fit.model.elastic:
        return np.zeros((data.S, data.C))
    k = np.maximum(fit.group("k"), 1.0)
    lam = np.clip(fit.group("lambda"), 0.0, None) if fit.has("lambda") else np.zeros(data.C)
    return static_elongation(fit.tension_hat, k, lam) - pretension_offsets(fit.model, data.C)


def alpha_hat_errors(data: MeasuredData, fits, masks: dict, step: int = 4) -> list[dict]:
    """alpha_hat by eq (35) corrected with each model's elongation, against the camera frames.

    Integrated from the first slow-grid sample (filtered camera pose) over every ``step``-th
    encoder sample; errors (deg) at the camera frames inside each mask's time span:
    ``{"mask name": {"mean_abs_deg": ..., "rms_deg": ..., "per_joint_mean_abs_deg": [...]}}``.
    Also returns the series for plots under ``"series"``.
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
    tc, ac = data.prep.camera
    inside = (tc >= tq[0]) & (tc <= tq[-1])
    tc, ac = tc[inside], ac[inside]
    out = []
    for b in range(B):
        at = np.stack([np.interp(tc, tq, a_hat[b, :, j]) for j in range(data.n)], axis=1)
        err = np.degrees(at - ac)
        res = {"series": {"t": tc, "error_deg": err}}
        for name, mask in masks.items():
            m = np.interp(tc, data.t, mask.astype(float)) > 0.5
            e = err[m]
            res[name] = {"mean_abs_deg": float(np.mean(np.abs(e))) if e.size else math.nan,
                         "rms_deg": float(np.sqrt(np.mean(e ** 2))) if e.size else math.nan,
                         "per_joint_mean_abs_deg": np.mean(np.abs(e), 0).tolist() if e.size else []}
        out.append(res)
    return out


def resimulate(data: MeasuredData, params: NeckParams, effects, rigid: bool, split: Split, masks: dict, *,
               settle_s: float = 0.3, progress: bool = False) -> dict:
    """Re-run the plant of a model open loop with the logged commanded forces, block by block.

    Each block of ``split`` (they start in the middle of a hold) is re-simulated from rest at the
    camera pose of its first sample: an open-loop run has no feedback, so over a whole log small
    model errors (or none: a closed-loop log's forces need the loop) carry the neck away.  The
    plant starts with unstretched cables, so a pre-roll of ``settle_s`` ramps the block's first
    commanded forces up (all cables together: the light linkage must not see one cable pull
    alone) and holds them; then the logged forces drive it and the comparison runs: encoder
    increments from the block start against the logged ones (rad), simulated joint angles
    against the camera frames (deg).  Errors per mask, the series under ``"series"``; a block
    that diverges is reported and left out from there on.
    """
    import mujoco
    from tqdm.auto import tqdm

    from neck_sim.plant import Plant

    t_fast = data.t_fast
    force = data.force_fast
    theta_log = data.prep.fast.theta
    tc, ac = data.prep.camera
    T = t_fast.size
    theta_err = np.full((T, data.C), np.nan)
    alpha_sim = np.full((T, data.n), np.nan)
    plant = Plant(params, effects, seed=0, rigid_cables=rigid)
    bad_qacc = plant.data.warning[mujoco.mjtWarning.mjWARN_BADQACC]
    amax = 0.95 * params.geometry.alpha_max
    settle = int(round(settle_s / data.dt))
    diverged = []
    edges = [(a, b) for a, b, _ in split.blocks]
    for a, b in tqdm(edges, desc="re-simulation", unit="block", disable=not progress, leave=False):
        i0, i1 = np.searchsorted(t_fast, a), np.searchsorted(t_fast, b, side="right")
        if i1 - i0 <= 2:
            continue
        a0 = np.array([np.interp(a, data.t, data.alpha[:, j]) for j in range(data.n)])
        plant.reset(alpha0=np.clip(a0, -amax, amax))
        bad_qacc.number = 0
        ramp = 0.5 * (1 - np.cos(np.pi * np.minimum(np.arange(settle) / (0.7 * settle), 1.0)))
        pre = [force[i0] * w for w in ramp]
        th = np.full((i1 - i0, data.C), np.nan)
        for k in range(i0 - settle, i1):
            if k >= i0:
                th[k - i0] = plant.encoders()
                alpha_sim[k] = plant.truth().alpha
            try:
                plant.step(pre[k - i0 + settle] if k < i0 else force[k])
                bad = bad_qacc.number > 0 or not np.all(np.isfinite(plant.data.qpos))
            except RuntimeError:                 # neck_sim.plant.PlantDivergedError
                bad = True
            if bad:
                if k >= i0:
                    alpha_sim[k + 1:i1] = np.nan
                    th[k + 1 - i0:] = np.nan
                else:
                    th[:] = np.nan
                    alpha_sim[i0:i1] = np.nan
                diverged.append(f"{a:.1f}-{b:.1f} s at {t_fast[max(k, i0)]:.2f} s")
                break
        theta_err[i0:i1] = (th - th[0]) - (theta_log[i0:i1] - theta_log[i0])
    a_cam = np.stack([np.interp(tc, t_fast, alpha_sim[:, j], left=np.nan, right=np.nan) for j in range(data.n)], axis=1)
    e_alpha = np.degrees(a_cam - ac)
    status = "ok" if not diverged else (f"diverged in {len(diverged)} of {len(edges)} blocks (open loop the logged "
                                        f"forces drive this model out of its valid range): " + "; ".join(diverged))
    out = {"status": status, "series": {"t": t_fast, "theta_error": theta_err, "t_camera": tc,
                                        "alpha_error_deg": e_alpha}}
    for name, mask in masks.items():
        m_fast = np.interp(t_fast, data.t, mask.astype(float), left=0, right=0) > 0.5
        m_cam = np.interp(tc, data.t, mask.astype(float), left=0, right=0) > 0.5
        ok_f, ok_c = m_fast & np.isfinite(theta_err).all(1), m_cam & np.isfinite(e_alpha).all(1)
        out[name] = {"theta_rms_rad": rms(theta_err[ok_f]).tolist() if ok_f.any() else None,
                     "alpha_rms_deg": rms(e_alpha[ok_c]).tolist() if ok_c.any() else None,
                     "alpha_mean_abs_deg": float(np.mean(np.abs(e_alpha[ok_c]))) if ok_c.any() else None,
                     "covered_fraction": float(ok_f.sum() / max(m_fast.sum(), 1))}
    return out
