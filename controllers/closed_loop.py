"""The experiment runner: a plant, a controller and a trajectory, closed loop at the control rate.

``run_closed_loop`` is the one place where experiments happen (control tests, identification
data, reproductions).  Each control period k (t_k = k / rate):

    theta_k = plant.encoders();   step = controller.step(theta_k, reference_k)
    plant.step(step.forces);      frame = plant.camera_frame()

and everything is recorded -- the measured topics (motors, camera, reference, estimate) and the
simulation truth -- to arrays and, if asked, to an MCAP log through :class:`neck_sim.logs.LogWriter`.

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
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from controllers.computed_torque import ComputedTorqueController, output_slices, reference_table
from controllers.trajectories import Trajectory
from neck_sim.replay import plant_run_info

__all__ = ["SLACK_TENSION", "Metrics", "RunResult", "run_closed_loop", "compute_metrics"]

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
    elongation_hat, tension, elongation (T, N+1); gamma (T, N) N m; loop_gap (T,) m;
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


def _log_writer(log_path, plant, run_info):
    if log_path is None:
        return None
    try:
        from neck_sim.logs import LogWriter
    except ImportError as exc:                      # logs not available in this installation
        raise RuntimeError(f"cannot write {log_path}: neck_sim.logs is not available ({exc})") from None
    return LogWriter(log_path, plant.params, mjcf_xml=getattr(plant, "xml", None), run_info=run_info)


def run_closed_loop(plant, controller: ComputedTorqueController, trajectory: Trajectory, *,
                    log_path: str | os.PathLike | None = None, progress: bool = True, reset: bool = True,
                    run_info: dict | None = None) -> RunResult:
    """Run ``trajectory`` closed loop on ``plant`` with ``controller`` at the control rate.

    The plant (``neck_sim.plant.Plant`` or anything with its interface) and the controller are
    reset to the trajectory's first pose unless ``reset=False``.  ``log_path`` writes an MCAP log
    (atomically: nothing is left if the run fails).  ``progress`` shows a tqdm bar.  A controller
    failure (estimate outside the workspace, infeasible tensions) stops the run with RuntimeError
    naming the time and the reason.
    """
    from tqdm.auto import tqdm

    p = controller.params
    n = p.n_joints
    trajectory.check_workspace(p)
    plant_rate = plant.params.control.rate_hz
    if abs(plant_rate - p.control.rate_hz) > 1e-9:
        raise ValueError(f"control rate: plant steps at {plant_rate} Hz, controller at {p.control.rate_hz} Hz")
    rate = p.control.rate_hz
    steps = int(round(trajectory.duration * rate)) + 1
    times = np.arange(steps) / rate
    ref = controller.motor_reference(trajectory.sample(times))
    table = reference_table(ref)

    alpha0 = ref.alpha[0]
    if reset:
        plant.reset(alpha0=alpha0)
    controller.reset(alpha0, plant.encoders())

    # The plant's seed, effects and parameters make `neck-sim replay` of this log exact.
    info = {**plant_run_info(plant), "trajectory": trajectory.name, "duration_s": trajectory.duration,
            "law": int(controller.law), "controller": controller.describe(), "rate_hz": rate, **(run_info or {})}
    rec = {name: np.empty((steps,) + shape) for name, shape in (
        ("t", ()), ("theta", (n + 1,)), ("alpha", (n,)), ("alpha_dot", (n,)), ("tension", (n + 1,)),
        ("elongation", (n + 1,)), ("loop_gap", ()))}
    out = np.zeros((steps, 7 * n + 4))              # the controller writes its rows (output_slices)
    cam_t, cam_a = [], []

    writer = _log_writer(log_path, plant, info)
    try:
        bar = tqdm(range(steps), desc=f"{trajectory.name} law {int(controller.law)}", unit="step",
                   disable=not progress, mininterval=0.5)
        forces = output_slices(n)["forces"]
        step_into, plant_step, encoders, plant_truth = controller.step_into, plant.step, plant.encoders, plant.truth
        r_t, r_theta, r_alpha, r_alpha_dot = rec["t"], rec["theta"], rec["alpha"], rec["alpha_dot"]
        r_tension, r_elong, r_gap = rec["tension"], rec["elongation"], rec["loop_gap"]
        for k in bar:
            r_t[k] = plant.time
            r_theta[k] = theta = encoders()
            truth = plant_truth()
            try:
                step_into(theta, k, table, out)
            except ValueError as exc:
                raise RuntimeError(f"closed loop stopped at t = {r_t[k]:.3f} s: {exc}") from exc
            plant_step(out[k, forces])
            frame = plant.camera_frame()
            r_alpha[k] = truth.alpha
            r_alpha_dot[k] = truth.alpha_dot
            r_tension[k] = truth.tension
            r_elong[k] = truth.elongation
            r_gap[k] = truth.loop_gap
            if frame is not None:
                cam_t.append(frame[0])
                cam_a.append(frame[1])
        bar.close()
        cols = {name: out[:, sl] for name, sl in output_slices(n).items()}
        camera_t = np.asarray(cam_t, dtype=float).reshape(-1)
        camera_alpha = np.asarray(cam_a, dtype=float).reshape(-1, n)
        if writer is not None:
            t = rec["t"]
            writer.write_batch("motors", t, rec["theta"], cols["forces"])
            writer.write_batch("reference", t, ref.alpha)
            writer.write_batch("estimate", t, cols["alpha_hat"])
            writer.write_batch("truth", t, rec["alpha"], rec["alpha_dot"], rec["tension"], rec["elongation"])
            writer.write_batch("camera", camera_t, camera_alpha)
    except BaseException:
        if writer is not None:
            writer.abort()
        raise
    if writer is not None:
        writer.close()
    rec.update(alpha_hat=cols["alpha_hat"], force=cols["forces"], requested=cols["requested"],
               saturated=cols["saturated"] > 0.5, elongation_hat=cols["elongation"], gamma=cols["gamma"])

    metrics = compute_metrics(rec["t"], ref.alpha, rec["alpha_hat"], rec["alpha"], rec["tension"], rec["force"],
                              rec["saturated"], camera_t, camera_alpha)
    return RunResult(alpha_d=ref.alpha, camera_t=camera_t, camera_alpha=camera_alpha, metrics=metrics, info=info,
                     log_path=None if log_path is None else os.fspath(log_path), **rec)
