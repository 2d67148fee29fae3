"""What a closed-loop run returns: its arrays (:class:`RunResult`) and the paper's measures of it
(:class:`Metrics`, :func:`compute_metrics`).

The metrics are the paper's (§7, Table 3), in degrees, averaged over every sample and joint:

* tracking e = mean |alpha_hat - alpha_d| (what the controller sees; Fig. 16) and, from the truth,
  mean |alpha - alpha_d|;
* estimation e_alpha = mean |alpha_hat - alpha_camera| at the camera frames (what the paper
  measures, Fig. 15; includes the camera's 1 deg noise) and mean |alpha_hat - alpha| (truth);
* force range, samples with a slack cable (a true tension <= ``SLACK_TENSION``; the take-up of the
  unstretched cables at the start, before every cable is first taut, is not counted: ``take_up``),
  samples with a force clipped at f_max.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["SLACK_TENSION", "Metrics", "RunResult", "compute_metrics"]

SLACK_TENSION = 1e-6   # N: a cable carrying less than this is slack (the plant's tension is exactly 0 then)


@dataclass(frozen=True)
class Metrics:
    """The paper's closed-loop measures (angles in degrees, forces in N)."""

    tracking_error: float             # mean |alpha_hat - alpha_d|, e of §7
    tracking_error_true: float        # mean |alpha - alpha_d|
    estimation_error_camera: float    # mean |alpha_hat - alpha_camera|, e_alpha of §7
    estimation_error_true: float      # mean |alpha_hat - alpha|, e_alpha of Table 3
    max_tracking_error: float         # max |alpha_hat - alpha_d|
    max_estimation_error_true: float  # max |alpha_hat - alpha|
    tracking_error_per_joint: tuple
    estimation_error_true_per_joint: tuple
    force_min: float
    force_max: float
    force_mean: float
    slack_samples: int                # samples with at least one slack cable
    slack_per_cable: tuple
    take_up: float                    # s, time until every cable was first taut (not counted as slack)
    saturated_samples: int            # samples with at least one force clipped at f_max
    samples: int
    camera_frames: int
    duration: float                   # s

    def as_dict(self) -> dict[str, Any]:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(self).items()}


@dataclass(frozen=True, eq=False)
class RunResult:
    """Arrays of one closed-loop run (T control samples, C camera frames) and its metrics.

    t (T,) s; alpha_d, alpha_hat, alpha, alpha_dot (T, N); theta, force, requested, saturated,
    elongation_hat, tension, elongation (T, m) (m cables); gamma (T, N) N m; loop_gap (T,) m;
    camera_t (C,), camera_alpha (C, N).
    """

    t: np.ndarray
    alpha_d: np.ndarray
    alpha_hat: np.ndarray
    theta: np.ndarray
    force: np.ndarray
    requested: np.ndarray
    saturated: np.ndarray
    elongation_hat: np.ndarray
    gamma: np.ndarray
    alpha: np.ndarray
    alpha_dot: np.ndarray
    tension: np.ndarray
    elongation: np.ndarray
    loop_gap: np.ndarray
    camera_t: np.ndarray
    camera_alpha: np.ndarray
    metrics: Metrics
    info: dict = field(default_factory=dict)
    log_path: str | None = None

    def summary(self) -> dict[str, Any]:
        """Metrics and run information as plain JSON-able values."""
        return {"info": self.info, "metrics": self.metrics.as_dict(), "log": self.log_path}

    def write_json(self, path) -> None:
        from neck_sim.atomic import atomic_write_json
        atomic_write_json(path, self.summary())


def compute_metrics(t, alpha_d, alpha_hat, alpha, tension, force, saturated, camera_t, camera_alpha) -> Metrics:
    """Metrics of :class:`Metrics` from the recorded arrays (shapes as in :class:`RunResult`)."""
    deg = np.degrees
    track = np.abs(alpha_hat - alpha_d)
    est = np.abs(alpha_hat - alpha)
    if len(camera_t):
        # alpha_hat at the frame instants, linearly between control samples
        hat_at_cam = np.stack([np.interp(camera_t, t, alpha_hat[:, j]) for j in range(alpha_hat.shape[1])], -1)
        cam_err = float(deg(np.abs(hat_at_cam - camera_alpha).mean()))
    else:
        cam_err = float("nan")
    slack = tension <= SLACK_TENSION
    # The plant starts with unstretched cables: the first milliseconds take the slack up.  Count
    # slack samples only once every cable has been taut (from sample 1 if that never happens).
    taut = np.flatnonzero(~slack.any(-1))
    take_up = int(taut[0]) if taut.size else 1
    slack[:take_up] = False
    return Metrics(
        tracking_error=float(deg(track.mean())),
        tracking_error_true=float(deg(np.abs(alpha - alpha_d).mean())),
        estimation_error_camera=cam_err,
        estimation_error_true=float(deg(est.mean())),
        max_tracking_error=float(deg(track.max())),
        max_estimation_error_true=float(deg(est.max())),
        tracking_error_per_joint=tuple(float(x) for x in deg(track.mean(0))),
        estimation_error_true_per_joint=tuple(float(x) for x in deg(est.mean(0))),
        force_min=float(force.min()), force_max=float(force.max()), force_mean=float(force.mean()),
        slack_samples=int(slack.any(-1).sum()),
        slack_per_cable=tuple(int(x) for x in slack.sum(0)),
        take_up=float(t[take_up] - t[0]) if len(t) > take_up else float("nan"),
        saturated_samples=int(saturated.any(-1).sum()),
        samples=int(len(t)), camera_frames=int(len(camera_t)),
        duration=float(t[-1] - t[0]) if len(t) else 0.0)
