"""Re-simulate one log's commanded forces through the MuJoCo plant for K parameter sets at once.

The output-error fit (eqs 44-57 fitted to the sensors instead of an inverse model) needs, per
candidate parameter set, the encoders and camera joint angles the plant would have produced under
the logged forces.  :func:`rollout` runs those open-loop re-simulations:

* each parameter set gets its own :class:`neck_sim.plant.Plant` (the plant the tests use: its
  MJCF, its native C callback for eq (54) tensions and eq (37) friction, the caller's integrator),
  reset to the experiment's initial pose;
* the K plants' models are stepped together by :class:`mujoco.batch.Batch` (``set_models``) on
  ``nthread`` threads: one ``mj_step`` per physics sub-step with the period's clipped force as
  ``ctrl``, which is the sub-step sequence :meth:`Plant.step` runs (bit for bit: the tests compare
  with K serial ``Plant`` runs);
* the encoders are read at every logged motor sample (the reading *before* the period's force acts,
  as ``/neck/motors`` logs it) and the true joint angles at the sub-step each camera frame shows
  (nearest sub-step to its stamp minus the camera lag);
* a parameter set whose simulation diverges (MuJoCo's singular-inertia or bad qpos/qvel/qacc
  warnings, as :class:`~neck_sim.plant.PlantDivergedError`) stops there: its outputs from that
  control period on are NaN, ``diverged[i]`` is True and ``reasons[i]`` says why; nothing raises.

Why threads over MuJoCo's batch and not a lockstep :class:`~neck_sim.batch.PlantBatch`: the batch
runs many sub-steps per call with no Python between them and uses every core; on the 85 s
identification log it costs less CPU per rollout even on one thread (``benchmarks/
bench_output_error.py`` measures both).  It needs the plant's C callback (MuJoCo's batch refuses a
Python one).

Usage::

    from neck_sim.logs import read_log
    from identification.output_error.rollouts import Experiment, cable_params, rollout

    log = read_log("identification.mcap", topics=("motors", "camera", "reference"))
    exp = Experiment.from_log(log)
    sets = cable_params(log.params, f_s=[[4.0] * 4, [4.1] * 4], k=2000.0, lam=20.0, c_a=50.0)
    out = rollout(exp, sets, integrator="implicitfast", nthread=2)
    out.encoders            # (2, T, m) rad at the logged motor samples
    out.camera_alpha        # (2, F, N) rad at the logged camera frames
    out.diverged            # (2,) bool
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field

import mujoco
import numpy as np
from mujoco import batch as mj_batch

from neck_sim.effects import Effects
from neck_sim.mjcf import model_index
from neck_sim.params import NeckParams

__all__ = ["Experiment", "Rollouts", "cable_params", "rollout", "rollout_logs", "default_threads", "MAX_GROUP",
           "THREADS_ENV"]

#: Environment variable that sets the threads of rollouts whose caller names none.
THREADS_ENV = "NECK_SIM_ROLLOUT_THREADS"

#: Parameter sets simulated together: their plants stay registered with the C callback (at most
#: 256 live plants per process) and their sub-step records in memory while the group runs.
MAX_GROUP = 64

#: Control periods per call into MuJoCo's batch: the qpos record of a call is
#: K x (periods x sub-steps) x nq doubles (64 sets x 2000 x 15: 15 MB).
_CHUNK_PERIODS = 500

# Warnings that mean the simulation diverged (the plant's PlantDivergedError); others stop a
# batch simulation too and are reported by name.
_FATAL = {int(getattr(mujoco.mjtWarning, w)): text for w, text in (
    ("mjWARN_INERTIA", "singular inertia"), ("mjWARN_BADQPOS", "bad qpos (NaN or huge)"),
    ("mjWARN_BADQVEL", "bad qvel (NaN or huge)"), ("mjWARN_BADQACC", "bad qacc (NaN or huge)"))}


@dataclass(frozen=True, eq=False)
class Experiment:
    """What a rollout replays: one log's commanded forces and its sensor sample times.

    ``force`` (T, m) N: the ``/neck/motors`` force of control period k (the plant clips it to
    [0, f_max] as the closed loop did); ``period`` s: the control period the motors are logged at;
    ``camera_t`` (F,) s: camera frame stamps since the first motor sample, in (0, T period];
    ``alpha0`` (N,) rad: the pose the plant starts from at rest.
    """

    force: np.ndarray = field(repr=False)
    period: float
    camera_t: np.ndarray = field(repr=False)
    alpha0: np.ndarray = field(repr=False)
    name: str = ""

    def __post_init__(self):
        f = np.array(self.force, dtype=float)
        if f.ndim != 2 or f.shape[0] < 2 or f.shape[1] < 1:
            raise ValueError(f"force: expected shape (T, m) with T >= 2 control periods, got {f.shape}")
        if not np.isfinite(f).all():
            row = int(np.flatnonzero(~np.isfinite(f).all(axis=1))[0])
            raise ValueError(f"force: NaN or infinity in control period {row}: {f[row].tolist()}")
        if not (isinstance(self.period, (int, float)) and math.isfinite(self.period) and self.period > 0):
            raise ValueError(f"period: expected a positive number of seconds, got {self.period!r}")
        cam = np.array(self.camera_t, dtype=float)
        end = f.shape[0] * float(self.period)
        if cam.ndim != 1:
            raise ValueError(f"camera_t: expected shape (F,), got {cam.shape}")
        outside = np.flatnonzero(~((cam > 0) & (cam <= end * (1 + 1e-12))))
        if outside.size:
            raise ValueError(f"camera_t: frame {int(outside[0])} at {cam[outside[0]]!r} s lies outside the motor log "
                             f"(0, {end:g}] s")
        a0 = np.array(self.alpha0, dtype=float)
        if a0.ndim != 1 or not np.isfinite(a0).all():
            raise ValueError(f"alpha0: expected N finite joint angles (rad), got {np.shape(self.alpha0)} {a0.tolist()}")
        for name, value in (("force", f), ("camera_t", cam), ("alpha0", a0)):
            value.flags.writeable = False
            object.__setattr__(self, name, value)
        object.__setattr__(self, "period", float(self.period))

    @property
    def n_periods(self) -> int:
        return self.force.shape[0]

    @classmethod
    def from_log(cls, log, alpha0=None) -> "Experiment":
        """The experiment of a :class:`neck_sim.logs.Log` read with its motors and camera.

        Times count from the first motor sample.  ``alpha0`` (N,) rad defaults to the first
        ``/neck/reference`` pose (the closed loop starts the neck there), else the first camera
        frame.  Camera frames outside the motor log are left out.
        """
        m = log.motors
        if m is None or len(m.t) < 2:
            count = 0 if m is None else len(m.t)
            raise ValueError(f"{log.path}: /neck/motors has {count} sample(s): nothing to replay")
        if log.camera is None:
            raise ValueError(f"{log.path}: no /neck/camera frames to compare joint angles with")
        steps = np.diff(m.t)
        period = float(np.median(steps))
        bad = np.flatnonzero(np.abs(steps - period) > 1e-6 * period + 1e-9)
        if bad.size:
            i = int(bad[0])
            raise ValueError(f"{log.path}: /neck/motors samples must be one control period ({period:g} s) apart to "
                             f"be re-simulated; t = {m.t[i]!r} -> {m.t[i + 1]!r} s")
        if alpha0 is None:
            if log.reference is not None and len(log.reference.t):
                alpha0 = log.reference.alpha_d[0]
            else:
                alpha0 = log.camera.alpha[0]
        cam = log.camera.t - m.t[0]
        end = len(m.t) * period
        keep = (cam > 0) & (cam <= end)
        return cls(m.force, period, cam[keep], alpha0, name=str(log.path))


@dataclass(frozen=True, eq=False)
class Rollouts:
    """Simulated sensors of K parameter sets on one experiment.

    ``encoders`` (K, T, m) rad at the logged motor samples (quantised as the plant's encoders, or
    the motor angles theta with ``quantise=False``); ``camera_alpha`` (K, F, N) rad true
    joint angles at the logged camera frames; both NaN from a diverged set's divergence on.
    ``diverged`` (K,) bool; ``diverged_at`` (K,) s (NaN if not); ``reasons`` K strings ("" if not).
    """

    encoders: np.ndarray
    camera_alpha: np.ndarray
    diverged: np.ndarray
    diverged_at: np.ndarray
    reasons: tuple[str, ...]

    @property
    def count(self) -> int:
        """Rollouts run (K)."""
        return self.diverged.size


def cable_params(base: NeckParams, *, f_s, k, lam, c_a) -> list[NeckParams]:
    """K parameter sets: ``base`` with friction f_s (N, eq 37) and the eq (54) cable stiffness k
    (N/m), lambda (1/m) and damping c_a (N s/m) replaced; each argument broadcasts to (K, m)."""
    m = base.n_cables
    values = [np.atleast_2d(np.asarray(v, dtype=float)) for v in (f_s, k, lam, c_a)]
    K = max(v.shape[0] for v in values)
    try:
        arrays = [np.broadcast_to(v, (K, m)) for v in values]
    except ValueError:
        raise ValueError(f"cable_params: f_s, k, lam and c_a must broadcast to (K, {m}) (one value per cable), got "
                         f"shapes {[np.shape(v) for v in (f_s, k, lam, c_a)]}") from None
    return [base.replace(**{"friction.f_s": tuple(map(float, a)), "cables.k": tuple(map(float, b)),
                            "cables.lam": tuple(map(float, c)), "cables.c_a": tuple(map(float, d))})
            for a, b, c, d in zip(*arrays)]


def rollout(experiment: Experiment, params: Sequence[NeckParams], effects: Effects | Sequence[Effects] | None = None,
            *, integrator: str, timestep: float | None = None, nthread: int | None = None,
            quantise: bool = True) -> Rollouts:
    """Re-simulate ``experiment`` for each of the K parameter sets ``params`` (NeckParams).

    ``effects``: the extended model's effects, one for all sets or one per set (default none);
    ``integrator``: MuJoCo's integrator for every set (one of
    :data:`neck_sim.plant.INTEGRATORS`), fixed by the caller so that the response is continuous
    in c_a; ``timestep``: physics step, s (default the plant's); ``nthread``: threads (default
    :func:`default_threads`); ``quantise``: encoders read as the plant's (nearest count), or
    False for the motor angles theta themselves (rad, ``Plant.truth().theta``), which a
    finite-difference Jacobian needs (a small parameter step rarely moves a count).  Bad input
    raises ValueError in one line; a diverging set does not
    raise (see :class:`Rollouts`).
    """
    from neck_sim.plant import Plant

    if not isinstance(experiment, Experiment):
        raise ValueError(f"experiment: expected an Experiment, got {type(experiment).__name__}")
    params = list(params) if not isinstance(params, NeckParams) else [params]
    if not params or not all(isinstance(p, NeckParams) for p in params):
        raise ValueError("params: expected one or more NeckParams (one per parameter set)")
    K = len(params)
    if effects is None or isinstance(effects, Effects):
        effects = [effects] * K
    else:
        effects = list(effects)
        if len(effects) != K or not all(e is None or isinstance(e, Effects) for e in effects):
            raise ValueError(f"effects: expected one Effects or one per parameter set ({K}), got {len(effects)} items")
    shape = (params[0].n_joints, params[0].n_cables)
    for i, p in enumerate(params):
        if (p.n_joints, p.n_cables) != shape:
            raise ValueError(f"params: set {i} describes N = {p.n_joints} joints and {p.n_cables} cables, set 0 "
                             f"N = {shape[0]} and {shape[1]}")
    if experiment.force.shape[1] != shape[1] or experiment.alpha0.size != shape[0]:
        raise ValueError(f"experiment {experiment.name!r}: forces for {experiment.force.shape[1]} cables and "
                         f"{experiment.alpha0.size} joint angles, the parameter sets describe {shape[1]} cables and "
                         f"{shape[0]} joints")
    nthread = default_threads() if nthread is None else nthread
    if not isinstance(nthread, int) or isinstance(nthread, bool) or nthread < 1:
        raise ValueError(f"nthread: expected a positive integer, got {nthread!r}")

    n, m = shape
    T, F = experiment.n_periods, experiment.camera_t.size
    enc = np.full((K, T, m), np.nan)
    cam = np.full((K, F, n), np.nan)
    diverged = np.zeros(K, dtype=bool)
    at = np.full(K, np.nan)
    reasons = [""] * K
    for g0 in range(0, K, MAX_GROUP):
        ids = range(g0, min(K, g0 + MAX_GROUP))
        plants = [Plant(params[i], effects[i], seed=0, timestep=timestep, integrator=integrator, backend="native")
                  for i in ids]
        _run_group(experiment, plants, nthread, quantise, enc[g0:ids.stop], cam[g0:ids.stop],
                   diverged[g0:ids.stop], at[g0:ids.stop], reasons, g0)
    return Rollouts(enc, cam, diverged, at, tuple(reasons))


def rollout_logs(experiments: Sequence[Experiment], params: Sequence[NeckParams],
                 effects: Effects | Sequence[Effects] | None = None, *, integrator: str, executor=None,
                 nthread: int | None = None, quantise: bool = True) -> list[Rollouts]:
    """:func:`rollout` of the same K parameter sets on each experiment (a multi-log fit): here one
    after the other (``executor`` None), or one job per log on the project's campaign executor
    (:func:`neck_sim.campaign.run_campaign`: an ``ExecutorSpec`` of local processes or a Dask
    cluster, or an executor already open).  Each job runs its K rollouts on ``nthread`` threads
    of its worker (default there: :func:`default_threads`)."""
    from neck_sim.campaign import run_campaign

    experiments = list(experiments)
    job = functools.partial(rollout, params=list(params), effects=effects, integrator=integrator, nthread=nthread,
                            quantise=quantise)
    return run_campaign(job, experiments, executor, labels=[e.name or str(i) for i, e in enumerate(experiments)],
                        progress=False, desc="rollouts")


def default_threads() -> int:
    """Threads of a rollout when the caller names none: ``$NECK_SIM_ROLLOUT_THREADS`` if set (a
    Dask worker or a benchmark pins it), else the CPUs this process may run on."""
    raw = os.environ.get(THREADS_ENV)
    if raw is not None:
        try:
            value = int(raw)
        except ValueError:
            value = 0
        if value < 1:
            raise ValueError(f"${THREADS_ENV}: expected a positive integer, got {raw!r}")
        return value
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def _sub_steps(experiment: Experiment, plant) -> np.ndarray:
    """(F,) sub-step counts after which each camera frame is taken: the nearest to its stamp
    minus the camera lag (a frame stamped t shows the neck at t - lag)."""
    lag = plant.effects.camera_lag()
    s = np.rint((experiment.camera_t - lag) / plant.timestep).astype(np.int64)
    return np.clip(s, 0, experiment.n_periods * plant.substeps)


def _run_group(exp: Experiment, plants: list, nthread: int, quantise: bool, enc, cam, diverged, at, reasons: list,
               g0: int) -> None:
    """Roll out one group of plants into the given rows of the outputs."""
    p0 = plants[0]
    if abs(p0.period - exp.period) > 1e-9 * exp.period:
        raise ValueError(f"experiment {exp.name!r}: motors logged every {exp.period:g} s, the plant's control period "
                         f"is {p0.period:g} s")
    for p in plants:
        if p.steps_alone or p.effects.command_delay() > 0:
            raise ValueError(f"effects {p.effects.names()}: a dead band or an actuation delay keeps state outside "
                             "MuJoCo's, which the batch rollout does not step")
    K, nsub, T = len(plants), p0.substeps, exp.n_periods
    ix = model_index(p0.model)
    ratio = p0.params.actuation.R / p0.params.actuation.r_d      # theta = ratio * s, as the plant reads it
    res = p0.params.sensors.encoder_resolution
    inv_res = 1.0 / res
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    b = mj_batch.Batch(p0.model, nsim=K, nthread=min(nthread, K))
    b.set_models([p.model for p in plants])
    for i, p in enumerate(plants):
        p.reset(alpha0=exp.alpha0)
        mujoco.mj_getState(p.model, p.data, b.state[i], spec)
        enc[i, 0] = p.encoders() if quantise else p.truth().theta
    if mujoco.get_mjcb_control() is None:
        raise RuntimeError("rollout: the plant's C callback is not installed as mjcb_control")
    frame_step = _sub_steps(exp, p0)
    at0 = frame_step == 0
    if at0.any():
        cam[:, at0] = np.stack([p.truth().alpha for p in plants])[:, None]
    last = max(T - 1, -(-int(frame_step.max(initial=0)) // nsub))   # periods to step
    alive = np.ones(K, dtype=bool)
    drive, nu, nq = ix.drive_actuator, p0.model.nu, p0.model.nq
    for k0 in range(0, last, _CHUNK_PERIODS):
        k1 = min(last, k0 + _CHUNK_PERIODS)
        rows = np.flatnonzero(alive)
        if not rows.size:
            break
        # the drive actuators' ctrlrange [0, f_max] clips the forces as the plant does
        ctrl = np.zeros((rows.size, (k1 - k0) * nsub, nu))
        ctrl[:, :, drive] = np.repeat(exp.force[k0:k1], nsub, axis=0)
        q = np.empty((rows.size, (k1 - k0) * nsub, nq))
        errors = {}
        try:
            b.rollout((k1 - k0) * nsub, ctrl, record=("qpos",), ids=rows.astype(np.int32), out={"qpos": q})
        except mj_batch.SimulationError as exc:      # those kept their state; the others ran the chunk
            errors = {int(i): b.error(int(i)) for i in exc.ids}
        warned = b.warning[rows, :, 0]
        for j, i in enumerate(rows):
            if int(i) in errors:
                first_bad, reason = 0, f"MuJoCo error: {errors[int(i)]}"
            elif warned[j].any():
                # MuJoCo's batch stops a simulation at the sub-step that warned; the records repeat it
                moved = np.flatnonzero(np.any(q[j, 1:] != q[j, :-1], axis=1))
                first_bad = int(moved[-1]) + 1 if moved.size else 0
                reason = "diverged: MuJoCo reported " + ", ".join(
                    _FATAL.get(int(w), mujoco.mjtWarning(int(w)).name) for w in np.flatnonzero(warned[j]))
            else:
                continue
            bad_period = first_bad // nsub            # within the chunk; earlier periods were sound
            alive[i], diverged[i], at[i] = False, True, (k0 + bad_period) * exp.period
            reasons[g0 + i] = reason
            q[j, bad_period * nsub:] = np.nan
        # encoders of periods k0+1 .. k1 (the reading after each period's last sub-step)
        e = ratio * q[:, nsub - 1::nsub][:, :, ix.qpos_motor]
        if quantise:
            e = np.rint(e * inv_res) * res
        hi = min(k1 + 1, T)
        enc[rows, k0 + 1:hi] = e[:, : hi - k0 - 1]
        sel = np.flatnonzero((frame_step > k0 * nsub) & (frame_step <= k1 * nsub))
        if sel.size:
            s = frame_step[sel] - k0 * nsub - 1
            cam[rows[:, None], sel[None, :]] = q[:, s][:, :, ix.qpos_A] + q[:, s][:, :, ix.qpos_D]
