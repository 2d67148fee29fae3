"""Open-loop re-simulation of a model's plant driven by the logged forces, block by block."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from identification.diagnosis.candidates import MeasuredData
from identification.diagnosis.gains import rms
from identification.diagnosis.split import Split
from neck_sim.params import NeckParams


@dataclass(frozen=True)
class ResimulationErrors:
    """Re-simulation errors over some samples: encoder increments (C,) rad RMS, joint angles
    against the camera (N,) deg RMS and mean |error| (None where every block diverged), and
    the fraction of the samples the blocks that did not diverge cover."""

    theta_rms_rad: tuple | None
    alpha_rms_deg: tuple | None
    alpha_mean_abs_deg: float | None
    covered_fraction: float

    def to_dict(self) -> dict:
        return {"theta_rms_rad": None if self.theta_rms_rad is None else list(self.theta_rms_rad),
                "alpha_rms_deg": None if self.alpha_rms_deg is None else list(self.alpha_rms_deg),
                "alpha_mean_abs_deg": self.alpha_mean_abs_deg, "covered_fraction": self.covered_fraction}


@dataclass(frozen=True, eq=False)
class Resimulation:
    """Re-simulation of one model: ``status`` ("ok" or which blocks diverged), errors on the
    primary held-out fold and on every sample, and the series for plots (encoder times ``t``
    (T,) s, ``theta_error`` (T, C) rad, camera times ``t_camera`` (F,) s, ``alpha_error_deg`` (F, N))."""

    status: str
    holdout: ResimulationErrors
    all: ResimulationErrors
    t: np.ndarray = field(repr=False)
    theta_error: np.ndarray = field(repr=False)
    t_camera: np.ndarray = field(repr=False)
    alpha_error_deg: np.ndarray = field(repr=False)
    n_blocks: int = 0
    n_diverged: int = 0

    @property
    def diverged_everywhere(self) -> bool:
        """Every block diverged: the errors cover only each block's run-up to its divergence."""
        return self.n_blocks > 0 and self.n_diverged == self.n_blocks

    def to_dict(self) -> dict:
        return {"status": self.status, "holdout": self.holdout.to_dict(), "all": self.all.to_dict(),
                "blocks": self.n_blocks, "diverged_blocks": self.n_diverged}


def resimulate(data: MeasuredData, params: NeckParams, effects, rigid: bool, split: Split, *,
               settle_s: float = 0.3, progress: bool = False) -> Resimulation:
    """Re-run the plant of a model open loop with the logged commanded forces, block by block.

    Each block of ``split`` (they start in the middle of a hold) is re-simulated from rest at the
    camera pose of its first sample: an open-loop run has no feedback, so over a whole log small
    model errors (or none: a closed-loop log's forces need the loop) carry the neck away.  The
    plant starts with unstretched cables, so a pre-roll of ``settle_s`` ramps the block's first
    commanded forces up (all cables together: the light linkage must not see one cable pull
    alone) and holds them; then the logged forces drive it and the comparison runs: encoder
    increments from the block start against the logged ones (rad), simulated joint angles
    against the camera frames (deg), on the primary held-out fold of ``split`` and on every
    sample.  A block that diverges is reported and left out from there on.
    """
    import mujoco
    from tqdm.auto import tqdm

    from neck_sim.plant_spec import PlantSpec
    from neck_sim.recorder import Recorder

    t_fast = data.t_fast
    force = data.force_fast
    theta_log = data.prep.fast.theta
    tc, ac = data.prep.camera
    T = t_fast.size
    theta_err = np.full((T, data.C), np.nan)
    alpha_sim = np.full((T, data.n), np.nan)
    plant = PlantSpec(params, effects, seed=0, rigid_cables=rigid).build()
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
        # rows from the first diverged step on are never sampled: they stay NaN
        rec = Recorder(data.n, data.C, i1 - i0)
        for k in range(i0 - settle, i1):
            f = pre[k - i0 + settle] if k < i0 else force[k]
            if k >= i0:
                rec.sample(k - i0, t_fast[k], plant.encoders(), f, plant.truth())
            try:
                plant.step(f)
                bad = bad_qacc.number > 0 or not np.all(np.isfinite(plant.data.qpos))
            except RuntimeError:                 # neck_sim.plant.PlantDivergedError
                bad = True
            if bad:
                diverged.append(f"{a:.1f}-{b:.1f} s at {t_fast[max(k, i0)]:.2f} s")
                break
        th = rec.theta[0]
        alpha_sim[i0:i1] = rec.truth_column("alpha")
        theta_err[i0:i1] = (th - th[0]) - (theta_log[i0:i1] - theta_log[i0])
    a_cam = np.stack([np.interp(tc, t_fast, alpha_sim[:, j], left=np.nan, right=np.nan) for j in range(data.n)], axis=1)
    e_alpha = np.degrees(a_cam - ac)
    status = "ok" if not diverged else (f"diverged in {len(diverged)} of {len(edges)} blocks (open loop the logged "
                                        f"forces drive this model out of its valid range): " + "; ".join(diverged))

    def errors(mask: np.ndarray) -> ResimulationErrors:
        m_fast = np.interp(t_fast, data.t, mask.astype(float), left=0, right=0) > 0.5
        m_cam = np.interp(tc, data.t, mask.astype(float), left=0, right=0) > 0.5
        ok_f, ok_c = m_fast & np.isfinite(theta_err).all(1), m_cam & np.isfinite(e_alpha).all(1)
        return ResimulationErrors(tuple(rms(theta_err[ok_f]).tolist()) if ok_f.any() else None,
                                  tuple(rms(e_alpha[ok_c]).tolist()) if ok_c.any() else None,
                                  float(np.mean(np.abs(e_alpha[ok_c]))) if ok_c.any() else None,
                                  float(ok_f.sum() / max(m_fast.sum(), 1)))

    return Resimulation(status, errors(split.holdout), errors(np.ones(data.S, bool)), t_fast, theta_err, tc, e_alpha,
                        n_blocks=len(edges), n_diverged=len(diverged))
