"""The experiment runner: a plant, a controller and a trajectory, closed loop at the control rate.

``run_lockstep`` is the one place where experiments happen (control tests, identification
data, reproductions); ``run_closed_loop`` is its single-run case.  Each control period k
(t_k = k / rate), for K independent runs at once:

    theta_k = the K plants' encoders;   one compiled controller step for all K runs;
    one PlantBatch step for all K plants (one native call);   their camera frames, if any

and everything is recorded -- the measured topics (motors, camera, reference, estimate) and the
simulation truth -- into one :class:`neck_sim.recorder.Recorder` and, if asked, to an MCAP log
written in bulk from its arrays when the run ends (:meth:`neck_sim.recorder.Recorder.write`).
The periods between events (camera frames, failures) run in one compiled call that steps the
native batch itself (:mod:`neck_sim.native.fused`).

Usage::

    from controllers.closed_loop import run_closed_loop
    from controllers.computed_torque import ComputedTorqueController
    from controllers.trajectories import make_trajectory
    from neck_sim.params import default_params
    from neck_sim.plant import Plant

    p = default_params(3)
    result = run_closed_loop(Plant(p), ComputedTorqueController(p, 2), make_trajectory("sine", p))
    print(result.metrics.tracking_error)       # deg

The metrics are the paper's (:mod:`controllers.run_result`).
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from controllers.computed_torque import (ComputedTorqueController, ControllerState, ControlStep, advance, control_rows,
                                        output_slices, reference_table, step_error)
from controllers.loop_protocols import LoopController, LoopTrajectory
from controllers.run_result import SLACK_TENSION, Metrics, RunResult, compute_metrics
from neck_sim.batch import PlantBatch, clip_forces, delayed_controls
from neck_sim.jit import kernel
from neck_sim.joint_range import JointRangeError, first_excursion
from neck_sim.live import active as active_live_view
from neck_sim.native import DISPATCH, call_c
from neck_sim.plant import Plant
from neck_sim.recorder import Recorder
from neck_sim.replay import plant_run_info

if TYPE_CHECKING:
    from neck_sim.live import LiveView
    from neck_sim.logs import LogWriter

__all__ = ["SLACK_TENSION", "FUSE_PERIODS", "LOCKSTEP_GROUP", "Metrics", "RunResult", "run_closed_loop", "run_lockstep",
           "compute_metrics", "LoopController", "LoopTrajectory"]


# Run the periods between events (camera frames, failures) in one compiled call (_run_periods) when
# every controller is compiled and every plant in a native PlantBatch.
# False: every period through the Python loop (the reference the compiled path must equal exactly).
FUSE_PERIODS = True
_MAX_FUSED = 500       # periods per compiled call at most: the progress bar moves at least every 1 s simulated


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


def _log_writer(log_path: str | os.PathLike | None, plant: Any, run_info: dict) -> LogWriter | None:
    if log_path is None:
        return None
    try:
        from neck_sim.logs import LogWriter
    except ImportError as exc:                      # logs not available in this installation
        raise RuntimeError(f"cannot write {log_path}: neck_sim.logs is not available ({exc})") from None
    return LogWriter(log_path, plant.params, mjcf_xml=getattr(plant, "xml", None), run_info=run_info)


def run_closed_loop(plant: Any, controller: LoopController, trajectory: LoopTrajectory, *,
                    log_path: str | os.PathLike | None = None, progress: bool = True, reset: bool = True,
                    run_info: dict | None = None, stop_outside_range: bool = False) -> RunResult:
    """Run ``trajectory`` closed loop on ``plant`` with ``controller`` at the control rate.

    The plant (``neck_sim.plant.Plant`` or anything with its interface) and the controller are
    reset to the trajectory's first pose unless ``reset=False``.  ``log_path`` writes an MCAP log
    (atomically: nothing is left if the run fails).  ``progress`` shows a tqdm bar.  A controller
    failure (estimate outside the workspace, infeasible tensions) stops the run with RuntimeError
    naming the time and the reason; so does, with ``stop_outside_range``, a neck that leaves its
    joint range (:func:`run_lockstep`).
    """
    return run_lockstep([plant], [controller], [trajectory], log_paths=[log_path], progress=progress, reset=reset,
                        run_infos=[run_info], stop_on_error=True, stop_outside_range=stop_outside_range)[0]


LOCKSTEP_GROUP = 16      # runs advanced together at most; larger batches go group after group


def run_lockstep(plants: Sequence[Any], controllers: Sequence[LoopController],
                 trajectories: Sequence[LoopTrajectory], *,
                 log_paths: Sequence[str | os.PathLike | None] | None = None,
                 progress: bool = True, reset: bool = True, run_infos: Sequence[dict | None] | None = None,
                 stop_on_error: bool = False, stop_outside_range: bool = False) -> list:
    """K independent closed-loop runs advanced together, period by period (lockstep batch).

    ``plants``, ``controllers``, ``trajectories`` (and ``log_paths``, ``run_infos``, default None)
    are K-long sequences: each run has its own plant (seed, parameters, effects), controller (law,
    model, gains) and trajectory; all trajectories have the same number of control periods and
    every controller the same N.  One compiled call advances the K controllers and one
    :class:`neck_sim.batch.PlantBatch` call steps the K plants (objects of other types, e.g. a
    wrapped plant, step alone through their ``step``); every run is recorded into one
    :class:`neck_sim.recorder.Recorder` of (K, T, ...) arrays.  Memory: about 8 (16 N + 11) K T
    bytes for T periods.  More than :data:`LOCKSTEP_GROUP` runs are advanced in groups of that
    size, one group after the other.

    Returns one entry per run: its :class:`RunResult`, or (``stop_on_error=False``) the
    RuntimeError that stopped it (controller failure, diverged plant) while the others go on.
    With ``stop_on_error=True`` the first failure is raised.

    ``stop_outside_range``: a run whose true joint angles leave |alpha| <= the plant's
    ``geometry.alpha_max`` fails like a diverged plant, with a
    :class:`neck_sim.joint_range.JointRangeError` naming the first such sample, and leaves no log
    (refused, not flagged: outside the range the paper's model no longer describes the neck and
    the log contract refuses the angles, so no later command could use the log).  The recorded
    truth is checked every :data:`_MAX_FUSED` periods as one array operation, not per physics step.
    """
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
                                stop_on_error=stop_on_error, stop_outside_range=stop_outside_range)
        return out
    run = _Lockstep(plants, controllers, trajectories, reset, stop_on_error, stop_outside_range)
    try:
        run.open(log_paths, run_infos)
        run.advance(progress)
        return run.results()
    except BaseException:
        run.abort()
        raise
    finally:
        run.close()


class _Lockstep:
    """One group of run_lockstep's runs, stage by stage: setup (``__init__``: checks, references,
    resets; :meth:`open`: records, batch, logs), stepping (:meth:`advance`: compiled chunks
    :meth:`fused` between events, else period by period :meth:`record`, :meth:`control`,
    :meth:`step`), and the results (:meth:`results`)."""

    def __init__(self, plants: list[Any], controllers: list[LoopController], trajectories: list[LoopTrajectory],
                 reset: bool, stop_on_error: bool, stop_outside_range: bool = False) -> None:
        self.plants, self.controllers, self.trajectories = plants, controllers, trajectories
        self.stop_on_error, self.K = stop_on_error, len(plants)
        self.n = n = controllers[0].params.n_joints
        self.rate = rate = controllers[0].params.control.rate_hz
        lengths: list[int] = []
        self.refs: list[Any] = []
        for i, (plant, ctrl, traj) in enumerate(zip(plants, controllers, trajectories)):
            p = ctrl.params
            traj.check_workspace(p)
            if abs(plant.params.control.rate_hz - p.control.rate_hz) > 1e-9:
                raise ValueError(f"control rate: plant steps at {plant.params.control.rate_hz} Hz, controller at "
                                 f"{p.control.rate_hz} Hz")
            if abs(p.control.rate_hz - rate) > 1e-9 or p.n_joints != n:
                raise ValueError(f"lockstep run {i}: every controller needs N = {n} and {rate} Hz")
            length = int(round(traj.duration * rate)) + 1
            if lengths and length != lengths[0]:
                raise ValueError(f"lockstep run {i}: {length} control periods, the first run has {lengths[0]}")
            lengths.append(length)
            self.refs.append(ctrl.motor_reference(traj.sample(np.arange(length) / rate)))
        self.steps = lengths[0]
        self.m = m = controllers[0].params.n_cables
        if any(c.params.n_cables != m for c in controllers):
            raise ValueError(f"lockstep: every controller needs the same number of cables ({m})")
        self.compiled = all(isinstance(c, ComputedTorqueController) for c in controllers)
        compiled = [c for c in controllers if isinstance(c, ComputedTorqueController)]
        for plant, ctrl, ref in zip(plants, controllers, self.refs):
            if reset:
                plant.reset(alpha0=ref.alpha[0])
            ctrl.reset(ref.alpha[0], plant.encoders())
        if self.compiled:
            self.tables = np.stack([reference_table(r) for r in self.refs])
            self.state = ControllerState.stack([c.state for c in compiled])
            self.status = self.state.status
        self.batch: PlantBatch | None = None
        self.writers: list[LogWriter | None] = [None] * self.K
        self.range_checked = 0 if stop_outside_range else None     # periods checked; None: no check

    def open(self, log_paths: list[str | os.PathLike | None], run_infos: list[dict | None]) -> None:
        """The records, the plants' batch, the logs and the live view."""
        K, n, m, steps, rate = self.K, self.n, self.m, self.steps, self.rate
        plants = self.plants
        # The plant's seed, effects and parameters make `neck-sim replay` of a log exact.
        self.infos = [{**plant_run_info(plant), "trajectory": traj.name, "duration_s": traj.duration,
                       "law": int(ctrl.law), "controller": ctrl.describe(), "rate_hz": rate, **(info or {})}
                      for plant, ctrl, traj, info in zip(plants, self.controllers, self.trajectories, run_infos)]
        self.rec = rec = Recorder(n, m, steps, runs=K, truth=True, reference=True, estimate=True)
        alpha_d = rec.alpha_d
        assert alpha_d is not None                  # recorded: reference=True
        for i, ref in enumerate(self.refs):
            alpha_d[i] = ref.alpha
        self.columns = output_slices(n, m)
        self.outs = np.zeros((K, steps, max(sl.stop for sl in self.columns.values())))   # rows of output_slices
        self.forces = self.outs[:, :, self.columns["forces"]]
        self.theta = np.empty((K, m))
        self.errors: list = [None] * K
        self.alive = np.ones(K, dtype=bool)
        # Plants step together in one PlantBatch; anything else with the plant's interface (a wrapped
        # plant, a stand-in) steps alone through its own step().
        self.batched = [i for i, p in enumerate(plants) if type(p) is Plant and not p.steps_alone]
        self.alone = [i for i in range(K) if i not in self.batched]
        self.rows = slice(None) if not self.alone else np.array(self.batched, dtype=np.intp)
        self.batch = batch = PlantBatch([plants[i] for i in self.batched]) if self.batched else None
        if batch is not None:
            rec.t[self.rows] = (batch.k[:, None] + batch.nsub * np.arange(steps)) * batch.dt
        self.position = {i: j for j, i in enumerate(self.batched)}         # run -> its row in the batch
        self.writers = [_log_writer(path, plant, info) for path, plant, info in zip(log_paths, plants, self.infos)]
        self.live: LiveView | None = active_live_view() if K == 1 else None
        self.shown = [0, 0]            # periods and camera frames of the run already sent to the live view
        if self.live is not None:
            self.live.new_run()
            self.live_every = max(1, int(rate / self.live.rate_hz))        # periods per scene frame

    # -- stepping
    def advance(self, progress: bool) -> None:
        """Every period of the runs: compiled chunks between events when every controller is
        compiled and every plant in the native batch, else (and at the events) period by period."""
        from tqdm.auto import tqdm

        desc = self.trajectories[0].name + (f" law {int(self.controllers[0].law)}" if self.K == 1 else f" x {self.K}")
        bar = tqdm(total=self.steps, desc=desc, unit="step", disable=not progress, mininterval=0.5)
        fused = FUSE_PERIODS and self.compiled and not self.alone and self.batch is not None
        if fused:
            self.kernel_args = self._kernel_args()
        k = 0
        while k < self.steps:
            if self.range_checked is not None and k - self.range_checked >= _MAX_FUSED:
                self.check_range(k)
            if self.live is not None and k - self.shown[0] >= self.live_every and self.alive[0]:
                self.show(k)
            # stage: how much of period k is done (0 nothing, 1 recorded and controlled, 2 also stepped)
            stage = 0
            if fused:
                k_end, stage = self.fused(k)
                bar.update(k_end - k)
                k = k_end
                if stage == 0:
                    continue
            if stage == 0:
                self.record(k)
                self.control(k)
            if stage == 2:                            # stepped by _run_periods: a plant diverged
                assert self.batch is not None         # stage 2 comes from the fused path only
                for j in self.batch.stop_diverged():
                    self.fail(self.batched[j], self.t_of(self.batched[j], k), self.batch.errors[j])
            else:
                self.step(k)
            k += 1
            bar.update(1)
        bar.close()
        self.check_range(self.steps)
        if self.live is not None and self.alive[0]:
            self.show(self.steps)

    def _kernel_args(self) -> tuple:
        assert self.batch is not None               # the fused path needs the batch
        step, state, rec = self.batch.fused_step(), self.state, self.rec
        return (step.encoders, step.out, self.theta, rec.theta, rec.truth, state.values, state.flags, state.const,
                state.cables, state.linkage, state.geometry, state.cases, state.Z, self.tables, self.outs,
                self.status, self.alive, self.columns["forces"].start, step.f_max, step.forces, step.delay_line,
                step.address, step.args)

    def fused(self, k: int) -> tuple[int, int]:
        """The quiet periods from k in one compiled call, and the next one (an event) recorded and
        controlled; returns (the period reached, its stage)."""
        batch = self.batch
        assert batch is not None                    # the fused path needs the batch
        quiet = min(batch.quiet_periods(), self.steps - k, _MAX_FUSED)
        previous = DISPATCH.enter("native") if quiet else None     # quiet periods: native only
        try:
            k_end, stage, fatal = _run_periods(k, k + quiet, int(k + quiet < self.steps), *self.kernel_args)
        finally:
            if quiet:
                DISPATCH.leave(previous)
        if fatal < 0:
            raise RuntimeError("PlantBatch: a plant's sizes changed (C struct disagrees with N, m)")
        batch.ran_periods(k_end - k + (stage == 2))
        return k_end, stage

    def record(self, k: int) -> None:
        """The encoders and the truth at the start of period k."""
        rec, batch, rows = self.rec, self.batch, self.rows
        if batch is not None:
            self.theta[rows] = rec.theta[rows, k] = batch.encoders()
            assert rec.truth is not None            # recorded: truth=True
            rec.truth[rows, k] = batch.out
        for i in self.alone:
            if self.alive[i]:
                plant = self.plants[i]
                rec.sample(k, plant.time, plant.encoders(), truth=plant.truth(), run=i)
                self.theta[i] = rec.theta[i, k]

    def control(self, k: int) -> None:
        """The controllers' step of period k, into ``outs``."""
        if self.compiled:
            advance(self.state, self.theta, k, self.tables, self.outs)
            return
        for i in np.flatnonzero(self.alive):
            try:
                # a copy: theta's row is overwritten next period and a controller may keep it
                _store(self.outs[i, k], self.controllers[i].step(self.theta[i].copy(), self.refs[i].at(k)),
                       self.columns)
            except (ValueError, RuntimeError) as exc:
                self.fail(int(i), self.t_of(int(i), k), exc)

    def step(self, k: int) -> None:
        """The controllers' failures of period k, then the plants' step with its forces."""
        batch, rec = self.batch, self.rec
        if self.compiled and np.count_nonzero(self.status):     # a quarter of status.any()'s call overhead
            for i in np.flatnonzero((self.status != 0) & self.alive).tolist():
                self.fail(i, self.t_of(i, k), step_error(int(self.status[i]), self.state.values[i, 0, :self.n],
                                                         self.controllers[i].params.geometry.alpha_max))
        if batch is not None:
            for j in batch.step(self.forces[self.rows, k]):
                self.fail(self.batched[j], self.t_of(self.batched[j], k), batch.errors[j])
            if batch.framed:
                for j, frame in enumerate(batch.frames):
                    rec.frame(frame, run=self.batched[j])
        for i in self.alone:
            if self.alive[i]:
                plant = self.plants[i]
                try:
                    plant.step(self.forces[i, k])
                except (ValueError, RuntimeError) as exc:
                    self.fail(i, rec.t[i, k], exc)
                    continue
                rec.frame(plant.camera_frame(), run=i)

    def fail(self, i: int, t: float, exc: Exception) -> None:
        """Run i stops at time t (s) because of ``exc`` (raised with ``stop_on_error``)."""
        err = RuntimeError(f"closed loop stopped at t = {t:.3f} s: {exc}")
        if self.stop_on_error:
            raise err from exc
        err.__cause__ = exc
        self.errors[i] = err
        self.alive[i] = False
        if self.compiled:
            self.status[i] = self.status[i] or -1       # the controller stops with its plant
        j = self.position.get(i)
        if j is not None and self.batch is not None and self.batch.active[j]:
            self.batch.stop(j, err)                     # the plant stops with its controller

    def check_range(self, k1: int) -> None:
        """Fail every live run whose true joint angles left the range in the periods recorded
        since the last check, up to k1 (one vectorised test per run and block)."""
        if self.range_checked is None:
            return
        rows, self.range_checked = slice(self.range_checked, k1), k1
        for i in np.flatnonzero(self.alive).tolist():
            out = first_excursion(self.rec.t[i, rows], self.rec.truth_column("alpha", i)[rows],
                                  self.plants[i].params.geometry.alpha_max)
            if out is not None:
                self.fail(i, out.t, JointRangeError(out))

    def t_of(self, i: int, k: int) -> float:
        """Time of period k of run i (s)."""
        return self.rec.t[i, k]

    # -- recording and results
    def _outputs(self, i: int, rows: slice) -> None:
        """The controller's commanded forces and estimate of run i over ``rows`` into the record."""
        cols = self.columns
        self.rec.force[i, rows] = self.outs[i, rows, cols["forces"]]
        assert self.rec.alpha_hat is not None       # recorded: estimate=True
        self.rec.alpha_hat[i, rows] = self.outs[i, rows, cols["alpha_hat"]]

    def show(self, k1: int) -> None:
        """Periods [shown, k1) of the (single) run to the live view: between compiled chunks."""
        k0, f0 = self.shown
        assert self.live is not None                # shown only to a live view
        self._outputs(0, slice(k0, k1))
        self.rec.write(self.live, 0, rows=slice(k0, k1), frames=slice(f0, None))
        self.shown[:] = [k1, len(self.rec.camera_t[0])]

    def results(self) -> list:
        """Each run's RunResult (its log written and closed), or the error that stopped it."""
        results = []
        for i in range(self.K):
            writer = self.writers[i]
            if self.errors[i] is not None:
                if writer is not None:
                    writer.abort()
                results.append(self.errors[i])
                continue
            results.append(self._result(i))
        return results

    def _result(self, i: int) -> RunResult:
        rec, writer = self.rec, self.writers[i]
        self._outputs(i, slice(None))
        if writer is not None:
            rec.write(writer, i)
            writer.close()
        cols = {name: self.outs[i][:, sl] for name, sl in self.columns.items()}
        camera_t, camera_alpha = rec.camera(i)
        arrays = dict(t=rec.t[i], theta=rec.theta[i], alpha_hat=cols["alpha_hat"], force=cols["forces"],
                      requested=cols["requested"], saturated=cols["saturated"] > 0.5,
                      elongation_hat=cols["elongation"], gamma=cols["gamma"],
                      **{name: rec.truth_column(name, i) for name in ("alpha", "alpha_dot", "tension", "elongation",
                                                                        "loop_gap")})
        alpha_d = self.refs[i].alpha
        metrics = compute_metrics(arrays["t"], alpha_d, arrays["alpha_hat"], arrays["alpha"], arrays["tension"],
                                  arrays["force"], arrays["saturated"], camera_t, camera_alpha)
        return RunResult(alpha_d=alpha_d, camera_t=camera_t, camera_alpha=camera_alpha, metrics=metrics,
                         info=self.infos[i], log_path=None if writer is None else writer.path, **arrays)

    def abort(self) -> None:
        """A failure outside the runs: no log is left."""
        for w in self.writers:
            if w is not None:
                w.abort()

    def close(self) -> None:
        """Hand the plants' stepping state back to them."""
        if self.batch is not None:
            self.batch.close()


def _store(row: np.ndarray, out: ControlStep, columns: dict) -> None:
    """A controller's ControlStep into its output row (columns of :func:`output_slices`)."""
    for name, sl in columns.items():
        row[sl] = getattr(out, name)
