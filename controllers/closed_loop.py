"""The experiment runner: a plant, a controller and a trajectory, closed loop at the control rate.

``run_lockstep`` is the one place where experiments happen (control tests, identification
data, reproductions); ``run_closed_loop`` is its single-run case.  Each control period k
(t_k = k / rate), for K independent runs at once:

    theta_k = the K plants' encoders;   one compiled controller step for all K runs;
    one PlantBatch step for all K plants (one native call);   their camera frames, if any

and everything is recorded -- the measured topics (motors, camera, reference, estimate) and the
simulation truth -- to arrays and, if asked, to an MCAP log written in bulk from those arrays
when the run ends (:meth:`neck_sim.logs.LogWriter.write_batch`).

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

from controllers.computed_torque import (ComputedTorqueController, ControllerState, advance, control_rows,
                                        output_slices, reference_table, step_error)
from controllers.trajectories import Trajectory
from neck_sim.jit import kernel
from neck_sim.live import active as active_live_view
from neck_sim.batch import PlantBatch, clip_forces, delayed_controls, truth_columns
from neck_sim.native import DISPATCH, call_c
from neck_sim.plant import Plant
from neck_sim.replay import plant_run_info

__all__ = ["SLACK_TENSION", "FUSE_PERIODS", "LOCKSTEP_GROUP", "Metrics", "RunResult", "run_closed_loop", "run_lockstep",
           "compute_metrics"]

SLACK_TENSION = 1e-6   # N: a cable carrying less than this is slack (the plant's tension is exactly 0 then)

# Run the periods between events (camera frames, failures) in one compiled call (_run_periods) when
# every controller is compiled and every plant in a native PlantBatch.
# False: every period through the Python loop (the reference the compiled path must equal exactly).
FUSE_PERIODS = True
_MAX_FUSED = 500       # periods per compiled call at most: the progress bar moves at least every 1 s simulated


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


@kernel
def _run_periods(k0, k1, control_k1, enc, plant_out, theta, rec_theta, rec_truth, values, flags, const, cables,
                 linkage, geometry, cases, Z, tables, outs, status, alive, fcol, fmax, forces, delay_line, step_fn,
                 step_args):
    """Periods k0 .. k1-1 of run_lockstep's loop for a PlantBatch and compiled controllers, and the
    first half of period k1 if ``control_k1``.

    Per period: record the encoders and the truth row, ``control_rows``, clip the forces to
    [0, f_max] into ``forces`` (``clip_forces``, as PlantBatch.step does), the commands of each
    sub-step if some plant has an actuation delay (``delay_line``: the arguments of
    ``delayed_controls`` but the forces),
    one ``neck_step_batch`` call at ``step_fn`` (native backend only: k1 = k0 otherwise).

    Returns (k, stage, fatal): periods before k are done; period k is untouched (stage 0, k = k1),
    recorded and controlled but not stepped (stage 1: period k1, a controller failed or a force is
    not finite), or also stepped with ``fatal`` plants diverged (stage 2).  The caller does the
    rest of period k.  The kernel runs without the GIL: MuJoCo's Python warning handler, which
    mj_step may call, takes it itself (the mujoco bindings' trampoline acquires it).
    """
    K, m = enc.shape
    delayed = False
    for r in range(K):
        delayed = delayed or delay_line[3][r] > 0.0
    for k in range(k0, k1 + control_k1):
        for r in range(K):
            for c in range(m):
                theta[r, c] = enc[r, c]
                rec_theta[r, k, c] = enc[r, c]
            for c in range(plant_out.shape[1]):
                rec_truth[r, k, c] = plant_out[r, c]
        control_rows(theta, k, values, flags, const, cables, linkage, geometry, cases, Z, tables, outs, status)
        for r in range(K):
            if status[r] != 0 and alive[r]:
                return k, 1, 0
            for c in range(m):
                if not np.isfinite(outs[r, k, fcol + c]):
                    return k, 1, 0
        if k == k1:
            return k, 1, 0
        clip_forces(outs[:, k, fcol:fcol + m], fmax, forces)
        if delayed:
            delayed_controls(delay_line[0], forces, *delay_line[1:])
        fatal = call_c(step_fn, step_args)
        if fatal != 0:
            return k, 2, fatal
    return k1, 0, 0


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
    return run_lockstep([plant], [controller], [trajectory], log_paths=[log_path], progress=progress, reset=reset,
                        run_infos=[run_info], stop_on_error=True)[0]


LOCKSTEP_GROUP = 16      # runs advanced together at most; larger batches go group after group


def run_lockstep(plants, controllers, trajectories, *, log_paths=None, progress: bool = True, reset: bool = True,
                 run_infos=None, stop_on_error: bool = False) -> list:
    """K independent closed-loop runs advanced together, period by period (lockstep batch).

    ``plants``, ``controllers``, ``trajectories`` (and ``log_paths``, ``run_infos``, default None)
    are K-long sequences: each run has its own plant (seed, parameters, effects), controller (law,
    model, gains) and trajectory; all trajectories have the same number of control periods and
    every controller the same N.  One compiled call advances the K controllers and one
    :class:`neck_sim.plant.PlantBatch` call steps the K plants (objects of other types, e.g. a
    wrapped plant, step alone through their ``step``); every run is recorded into (K, T, ...)
    arrays.  Memory: about 8 (13 N + 10) K T bytes for T periods.  More than :data:`LOCKSTEP_GROUP`
    runs are advanced in groups of that size, one group after the other.

    Returns one entry per run: its :class:`RunResult`, or (``stop_on_error=False``) the
    RuntimeError that stopped it (controller failure, diverged plant) while the others go on.
    With ``stop_on_error=True`` the first failure is raised.
    """
    from tqdm.auto import tqdm

    plants, controllers, trajectories = list(plants), list(controllers), list(trajectories)
    K = len(plants)
    log_paths = [None] * K if log_paths is None else list(log_paths)
    run_infos = [None] * K if run_infos is None else list(run_infos)
    if K == 0 or not (len(controllers) == len(trajectories) == len(log_paths) == len(run_infos) == K):
        sizes = [K, len(controllers), len(trajectories), len(log_paths), len(run_infos)]
        raise ValueError(f"lockstep: need as many controllers, trajectories, log paths and run infos as plants "
                         f"(>= 1), got {sizes}")
    if K > LOCKSTEP_GROUP:
        # Past a few dozen plants their MuJoCo models and data no longer fit the core's cache and
        # every plant's physics slows (47 -> 60 us per period at K = 64): advance cache-sized groups.
        out = []
        for g in range(0, K, LOCKSTEP_GROUP):
            part = slice(g, g + LOCKSTEP_GROUP)
            out += run_lockstep(plants[part], controllers[part], trajectories[part], log_paths=log_paths[part],
                                progress=progress, reset=reset, run_infos=run_infos[part],
                                stop_on_error=stop_on_error)
        return out
    n = controllers[0].params.n_joints
    rate = controllers[0].params.control.rate_hz
    steps = None
    refs = []
    for i, (plant, ctrl, traj) in enumerate(zip(plants, controllers, trajectories)):
        p = ctrl.params
        traj.check_workspace(p)
        if abs(plant.params.control.rate_hz - p.control.rate_hz) > 1e-9:
            raise ValueError(f"control rate: plant steps at {plant.params.control.rate_hz} Hz, controller at "
                             f"{p.control.rate_hz} Hz")
        if abs(p.control.rate_hz - rate) > 1e-9 or p.n_joints != n:
            raise ValueError(f"lockstep run {i}: every controller needs N = {n} and {rate} Hz")
        length = int(round(traj.duration * rate)) + 1
        if steps is not None and length != steps:
            raise ValueError(f"lockstep run {i}: {length} control periods, the first run has {steps}")
        steps = length
        refs.append(ctrl.motor_reference(traj.sample(np.arange(steps) / rate)))
    m = controllers[0].params.n_cables
    if any(c.params.n_cables != m for c in controllers):
        raise ValueError(f"lockstep: every controller needs the same number of cables ({m})")
    compiled = all(isinstance(c, ComputedTorqueController) for c in controllers)
    for plant, ctrl, ref in zip(plants, controllers, refs):
        if reset:
            plant.reset(alpha0=ref.alpha[0])
        ctrl.reset(ref.alpha[0], plant.encoders())
    if compiled:
        tables = np.stack([reference_table(r) for r in refs])
        state = ControllerState.stack([c.state for c in controllers])
        status = state.status

    # The plant's seed, effects and parameters make `neck-sim replay` of a log exact.
    infos = [{**plant_run_info(plant), "trajectory": traj.name, "duration_s": traj.duration, "law": int(ctrl.law),
              "controller": ctrl.describe(), "rate_hz": rate, **(info or {})}
             for plant, ctrl, traj, info in zip(plants, controllers, trajectories, run_infos)]
    truth_cols = truth_columns(n, m)
    rec_t = np.empty((K, steps))
    rec_theta = np.empty((K, steps, m))
    rec_truth = np.empty((K, steps, truth_cols["loop_gap"].stop))     # rows of PlantBatch.out
    columns = output_slices(n, m)
    outs = np.zeros((K, steps, max(sl.stop for sl in columns.values())))   # rows of output_slices
    forces = outs[:, :, columns["forces"]]
    theta = np.empty((K, m))
    cameras = [([], []) for _ in range(K)]
    errors: list = [None] * K
    alive = np.ones(K, dtype=bool)
    # Plants step together in one PlantBatch; anything else with the plant's interface (a wrapped
    # plant, a stand-in) steps alone through its own step().
    batched = [i for i, p in enumerate(plants) if type(p) is Plant and not p.steps_alone]
    alone = [i for i in range(K) if i not in batched]
    rows = slice(None) if not alone else np.array(batched, dtype=np.intp)
    batch = PlantBatch([plants[i] for i in batched]) if batched else None
    start = None if batch is None else batch.k.copy()
    position = {i: j for j, i in enumerate(batched)}         # run -> its row in the batch
    writers = [_log_writer(path, plant, info) for path, plant, info in zip(log_paths, plants, infos)]
    live = active_live_view() if K == 1 else None
    shown = [0, 0]            # periods and camera frames of the run already sent to the live view
    if live is not None:
        live.new_run()
        live_every = max(1, int(rate / live.rate_hz))        # periods per scene frame

    def show(k1: int) -> None:
        """Periods [shown, k1) of the (single) run to the live view: between compiled chunks."""
        k0, f0 = shown
        j = position.get(0)
        t = rec_t[0, k0:k1] if j is None else (start[j] + np.arange(k0, k1) * batch.nsub) * batch.dt
        rec = {name: rec_truth[0, k0:k1, sl] for name, sl in truth_cols.items()}
        rec["theta"] = rec_theta[0, k0:k1]
        cols = {name: outs[0, k0:k1, sl] for name, sl in columns.items()}
        cam_t, cam_alpha = cameras[0]
        _write_topics(live, t, rec, cols, refs[0].alpha[k0:k1], np.asarray(cam_t[f0:], dtype=float),
                      np.asarray(cam_alpha[f0:], dtype=float).reshape(-1, n))
        shown[:] = [k1, len(cam_t)]

    def fail(i: int, t: float, exc: Exception) -> None:
        err = RuntimeError(f"closed loop stopped at t = {t:.3f} s: {exc}")
        if stop_on_error:
            raise err from exc
        err.__cause__ = exc
        errors[i] = err
        alive[i] = False
        if compiled:
            status[i] = status[i] or -1       # the controller stops with its plant
        if i in position and batch.active[position[i]]:
            batch.stop(position[i], err)      # the plant stops with its controller

    def t_of(i: int, k: int) -> float:
        """Time of period k of run i (s)."""
        j = position.get(i)
        return rec_t[i, k] if j is None else (start[j] + k * batch.nsub) * batch.dt

    try:
        desc = trajectories[0].name + (f" law {int(controllers[0].law)}" if K == 1 else f" x {K}")
        bar = tqdm(total=steps, desc=desc, unit="step", disable=not progress, mininterval=0.5)
        fused = FUSE_PERIODS and compiled and not alone and batch is not None
        if fused:
            step = batch.fused_step()
            kernel_args = (step.encoders, step.out, theta, rec_theta, rec_truth, state.values, state.flags,
                           state.const, state.cables, state.linkage, state.geometry, state.cases, state.Z, tables,
                           outs, status, alive, columns["forces"].start, step.f_max, step.forces,
                           step.delay_line, step.address, step.args)
        k = 0
        while k < steps:
            if live is not None and k - shown[0] >= live_every and alive[0]:
                show(k)
            # stage: how much of period k is done (0 nothing, 1 recorded and controlled, 2 also stepped)
            stage = 0
            if fused:
                # the quiet periods in one call, and the next one (an event) recorded and controlled
                quiet = min(batch.quiet_periods(), steps - k, _MAX_FUSED)
                previous = DISPATCH.enter("native") if quiet else None     # quiet periods: native only
                try:
                    k_end, stage, fatal = _run_periods(k, k + quiet, int(k + quiet < steps), *kernel_args)
                finally:
                    if quiet:
                        DISPATCH.leave(previous)
                if fatal < 0:
                    raise RuntimeError("PlantBatch: a plant's sizes changed (C struct disagrees with N, m)")
                batch.ran_periods(k_end - k + (stage == 2))
                bar.update(k_end - k)
                k = k_end
                if stage == 0:
                    continue
            if stage == 0:
                if batch is not None:
                    theta[rows] = rec_theta[rows, k] = batch.encoders()
                    rec_truth[rows, k] = batch.out
                for i in alone:
                    if alive[i]:
                        plant = plants[i]
                        rec_t[i, k] = plant.time
                        rec_theta[i, k] = theta[i] = plant.encoders()
                        truth = plant.truth()
                        for name, sl in truth_cols.items():
                            rec_truth[i, k, sl] = getattr(truth, name)
                if compiled:
                    advance(state, theta, k, tables, outs)
                else:
                    for i in np.flatnonzero(alive):
                        try:
                            # a copy: theta's row is overwritten next period and a controller may keep it
                            _store(outs[i, k], controllers[i].step(theta[i].copy(), refs[i].at(k)), columns)
                        except (ValueError, RuntimeError) as exc:
                            fail(i, t_of(i, k), exc)
            if stage == 2:                            # stepped by _run_periods: a plant diverged
                for j in batch.stop_diverged():
                    fail(batched[j], t_of(batched[j], k), batch.errors[j])
            else:
                if compiled and np.count_nonzero(status):     # a quarter of status.any()'s call overhead
                    for i in np.flatnonzero((status != 0) & alive):
                        fail(i, t_of(i, k), step_error(int(status[i]), state.values[i, 0, :n],
                                                       controllers[i].params.geometry.alpha_max))
                if batch is not None:
                    for j in batch.step(forces[rows, k]):
                        fail(batched[j], t_of(batched[j], k), batch.errors[j])
                    if batch.framed:
                        for j, frame in enumerate(batch.frames):
                            if frame is not None:
                                cameras[batched[j]][0].append(frame[0])
                                cameras[batched[j]][1].append(frame[1])
                for i in alone:
                    if alive[i]:
                        plant = plants[i]
                        try:
                            plant.step(forces[i, k])
                        except (ValueError, RuntimeError) as exc:
                            fail(i, rec_t[i, k], exc)
                            continue
                        frame = plant.camera_frame()
                        if frame is not None:
                            cameras[i][0].append(frame[0])
                            cameras[i][1].append(frame[1])
            k += 1
            bar.update(1)
        bar.close()
        if live is not None and alive[0]:
            show(steps)
        if batch is not None:
            rec_t[rows] = (start[:, None] + batch.nsub * np.arange(steps)) * batch.dt
        results = []
        for i in range(K):
            if errors[i] is not None:
                if writers[i] is not None:
                    writers[i].abort()
                results.append(errors[i])
                continue
            rec = {"t": rec_t[i], "theta": rec_theta[i],
                   **{name: rec_truth[i, :, sl] for name, sl in truth_cols.items() if name != "theta"}}
            rec["loop_gap"] = rec["loop_gap"][:, 0]
            results.append(_result(rec, outs[i], refs[i], cameras[i], infos[i], writers[i], columns))
    except BaseException:
        for w in writers:
            if w is not None:
                w.abort()
        raise
    finally:
        if batch is not None:
            batch.close()
    return results


def _store(row: np.ndarray, out, columns: dict) -> None:
    """A controller's ControlStep into its output row (columns of :func:`output_slices`)."""
    for name, sl in columns.items():
        row[sl] = getattr(out, name)


def _write_topics(writer, t, rec: dict, cols: dict, alpha_d, camera_t, camera_alpha) -> None:
    """Periods t (T,) s of a run to the contract topics of ``writer`` (a LogWriter or a LiveView):
    ``rec`` theta and the truth's columns, ``cols`` the controller's outputs, each (T, ...)."""
    writer.write_batch("motors", t, rec["theta"], cols["forces"])
    writer.write_batch("reference", t, alpha_d)
    writer.write_batch("estimate", t, cols["alpha_hat"])
    writer.write_batch("truth", t, rec["alpha"], rec["alpha_dot"], rec["tension"], rec["elongation"])
    writer.write_batch("camera", camera_t, camera_alpha)


def _result(rec: dict, out: np.ndarray, ref, camera, info: dict, writer, columns: dict) -> RunResult:
    """The RunResult of one finished run; its log (if any) written and closed."""
    cols = {name: out[:, sl] for name, sl in columns.items()}
    n = cols["alpha_hat"].shape[1]
    camera_t = np.asarray(camera[0], dtype=float).reshape(-1)
    camera_alpha = np.asarray(camera[1], dtype=float).reshape(-1, n)
    if writer is not None:
        _write_topics(writer, rec["t"], rec, cols, ref.alpha, camera_t, camera_alpha)
        writer.close()
    rec = dict(rec, alpha_hat=cols["alpha_hat"], force=cols["forces"], requested=cols["requested"],
               saturated=cols["saturated"] > 0.5, elongation_hat=cols["elongation"], gamma=cols["gamma"])
    metrics = compute_metrics(rec["t"], ref.alpha, rec["alpha_hat"], rec["alpha"], rec["tension"], rec["force"],
                              rec["saturated"], camera_t, camera_alpha)
    return RunResult(alpha_d=ref.alpha, camera_t=camera_t, camera_alpha=camera_alpha, metrics=metrics, info=info,
                     log_path=None if writer is None else writer.path, **rec)
