"""The paper's §5.6 pulley indicators, recomputed: how much the pulleys change joint torques and
the eq (35) joint increments.

Indicator 1: mean over random poses alpha_i ~ U(-pi/2, pi/2) and forces f_i ~ U(f_min, f_max) of
||Z f - Z_0 f|| / ||Z f||, where Z_0 is the transmission matrix with pulley radius r = 0 (paper: 16 %).

Indicator 2: mean over random poses and random motor increments d_theta of
||d_alpha - d_alpha_0|| / ||d_alpha|| with d_alpha = (Z^T)^+ (r_d/R) d_theta (eq 35 corrected,
rigid cables) (paper: 13 %).  The increments are motor motions the neck can actually make:
d_theta = (R/r_d) Z^T d_alpha_true for a random joint motion, plus a small random elongation-like
part, since an arbitrary 4-vector of increments is not a motion of the rigid neck.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from neck_sim.analytic.cables import transmission_matrix
from neck_sim.analytic.estimation import pinv_increment
from neck_sim.params import NeckParams


class PulleyEffect(NamedTuple):
    torque_rel_diff: float          # mean ||(Z - Z0) f|| / ||Z f||
    torque_rel_diff_median: float
    increment_rel_diff: float       # mean ||d_alpha - d_alpha0|| / ||d_alpha||
    increment_rel_diff_median: float
    samples: int


def pulley_effect(params: NeckParams, samples: int = 100_000, seed: int = 0,
                  alpha_range: float = np.pi / 2) -> PulleyEffect:
    """Both indicators over ``samples`` random draws (seeded)."""
    if samples < 1:
        raise ValueError(f"samples: must be >= 1, got {samples}")
    rng = np.random.default_rng(seed)
    n = params.n_joints
    act = params.actuation
    # Stay strictly inside the open interval of the paper.
    alpha = rng.uniform(-alpha_range, alpha_range, (samples, n)) * (1 - 1e-9)
    wide = params.replace(**{"geometry.alpha_max": max(params.geometry.alpha_max, alpha_range)})
    bare = wide.replace(**{"geometry.r": 0.0})
    Z = transmission_matrix(alpha, wide)
    Z0 = transmission_matrix(alpha, bare)
    f = rng.uniform(act.f_min, act.f_max, (samples, n + 1))
    tau = np.einsum("bij,bj->bi", Z, f)
    tau0 = np.einsum("bij,bj->bi", Z0, f)
    rel_tau = np.linalg.norm(tau - tau0, axis=1) / np.linalg.norm(tau, axis=1)

    d_alpha_true = rng.normal(scale=np.radians(1.0), size=(samples, n))
    d_theta = (act.R / act.r_d) * np.einsum("bij,bi->bj", Z, d_alpha_true)
    d_theta = d_theta + rng.normal(scale=0.05 * np.abs(d_theta).mean(), size=d_theta.shape)
    da = pinv_increment(alpha, d_theta, wide)
    da0 = pinv_increment(alpha, d_theta, bare)
    rel_da = np.linalg.norm(da - da0, axis=1) / np.linalg.norm(da, axis=1)
    return PulleyEffect(float(rel_tau.mean()), float(np.median(rel_tau)), float(rel_da.mean()),
                        float(np.median(rel_da)), samples)
