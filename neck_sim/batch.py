"""K plants advanced together one control period at a time: the plants' one stepping path.

A control period (1/``control.rate_hz``) is ``mj_step2`` + ``mj_step`` x (n-1) + ``mj_step1``, so
that after every period the position/velocity stages (tendon lengths, loop gaps, tensions)
describe the current state; ``ctrl`` is set before each sub-step to the command then in force
(actuation delay) and the joint angles are read where a camera frame is due.  On the native
backend one C call (``neck_step_batch``, which calls MuJoCo's ``mj_step*`` from C) runs the period
of all K plants; on the Python backend :func:`neck_sim.native.reference.step_period` does.
:meth:`neck_sim.plant.Plant.step` is the K = 1 case (the plant's own batch).

A batch takes plant-like objects: anything with a ``native`` attribute holding a
:class:`neck_sim.native.NativePlant` (or the records themselves), and reads nothing else of them.

Usage::

    import numpy as np
    from neck_sim.batch import PlantBatch, truth_columns
    from neck_sim.plant import Plant

    plants = [Plant(seed=s) for s in range(4)]          # N = 3 joints, m = 4 cables
    with PlantBatch(plants) as batch:
        for k in range(500):
            stopped = batch.step(np.full((4, 4), 20.0))     # (K, m) N; the plants stopped in it
            alpha = batch.out[:, truth_columns(3, 4)["alpha"]]   # (K, N) rad
"""

from __future__ import annotations

import ctypes
import math
from typing import Any, Iterable

import numpy as np
from numpy.typing import ArrayLike

from neck_sim.jit import kernel
from neck_sim.native import DISPATCH, FusedStep, NativePlant, last_warning
from neck_sim.native.reference import step_period

__all__ = ["PlantBatch", "PlantDivergedError", "truth_columns", "clip_forces", "delayed_controls", "quantise"]


class PlantDivergedError(RuntimeError):
    """The simulation blew up: MuJoCo saw a singular inertia or a NaN/huge state (and may have reset it)."""


def quantise(theta: np.ndarray, inv_res: float | np.ndarray, res: float | np.ndarray, out: np.ndarray) -> np.ndarray:
    """Encoder reading of motor angles theta (rad): the nearest count of resolution ``res`` (rad), into ``out``."""
    np.multiply(theta, inv_res, out=out)
    return np.multiply(np.rint(out, out=out), res, out=out)


@kernel
def clip_forces(requested: np.ndarray, fmax: np.ndarray, out: np.ndarray) -> None:
    """out (K, m) N: ``requested`` (K, m) N clipped to [0, f_max] with f_max (K, 1) N per plant, as
    ``np.minimum(np.maximum(requested, 0), fmax)`` (a -0.0 becomes 0.0); rows must be finite."""
    K, m = out.shape
    for r in range(K):
        for c in range(m):
            f = requested[r, c]
            f = f if f > 0.0 else 0.0
            out[r, c] = f if f < fmax[r, 0] else fmax[r, 0]


@kernel
def delayed_controls(k: np.ndarray, forces: np.ndarray, hist: np.ndarray, R: np.ndarray, delay: np.ndarray,
                     dt: float, period: float, ctrl: np.ndarray) -> None:
    """ctrl (K, n_sub, m) N: the command in force at each sub-step of the period that starts at
    sub-step k (K,), for commands ``forces`` (K, m) N issued now and actuation delays ``delay`` (K,)
    s (sub-step dt, control period ``period``, s).  The command of period p is issued at p T and
    acts from p T + delay; before the first one takes effect the delay line holds the first
    command.  hist (K, R_max, m): each plant's ring buffer of commands (period q's at q % R (K,),
    enough for every period a delay reaches back to); this period's forces are written into it.
    """
    K, nsub, m = ctrl.shape
    for r in range(K):
        cur = k[r] // nsub
        q = cur % R[r]
        for c in range(m):
            hist[r, q, c] = forces[r, c]
        for s in range(nsub):
            row = q
            if delay[r] > 0.0:
                p = math.floor(((k[r] + s) * dt - delay[r]) / period + 1e-9)
                row = min(cur, max(0, p)) % R[r]
            for c in range(m):
                ctrl[r, s, c] = hist[r, row, c]


def truth_columns(n: int, m: int) -> dict[str, slice]:
    """Columns of :attr:`PlantBatch.out` (width 3m + 2n + 1) for N = n joints and m cables; the C
    function ``neck_step_batch`` writes the same layout."""
    widths = (("theta", m), ("alpha", n), ("alpha_dot", n), ("tension", m), ("elongation", m), ("loop_gap", 1))
    out, start = {}, 0
    for name, width in widths:
        out[name] = slice(start, start + width)
        start += width
    return out


def _record(p: Any) -> NativePlant | None:
    return p if isinstance(p, NativePlant) else getattr(p, "native", None)


def _library() -> ctypes.CDLL:
    """The loaded native library (a batch on the native backend has one)."""
    lib = DISPATCH.lib
    if lib is None:
        raise RuntimeError("PlantBatch: the native backend is selected but its library is not loaded")
    return lib


class PlantBatch:
    """K plants advanced together one control period at a time.

    ``PlantBatch(plants)`` takes over the plants' stepping state (sub-step counter, camera
    schedule, actuation-delay line: :class:`neck_sim.native.StepState`) until :meth:`close` (or the
    end of a ``with`` block) hands it back; meanwhile the plants cannot step alone.  The plants are
    distinct plants with the same N, m, timestep and control period, on one backend.  With
    ``yields=True`` (a plant's own batch) another batch may take the plants over, closing this one.

    ``step(forces)`` runs one period, forces (K, m) N: each row is clipped to [0, f_max] (a row
    with NaN or infinity stops that plant with ValueError), the delayed commands in force at each
    sub-step and the camera frames due are worked out for all K, and each plant runs
    ``mj_step2`` + ``mj_step`` x (n_sub - 1) + ``mj_step1`` with ``ctrl`` set per sub-step and its
    joint angles copied where a frame is due.  Then

    * ``out`` (K, 3m + 2N + 1): theta (m,) rad, alpha, alpha_dot (N,), tension (m,) N, elongation
      (m,) m, loop_gap m of each plant (its ``truth()``); ``encoders()`` (K, m) rad;
    * ``frames[i]``: the last camera frame (t, alpha (N,)) of the period, or None;
    * a plant whose simulation diverged is stopped, its PlantDivergedError in ``errors[i]``.

    A compiled caller may step the batch itself through :mod:`neck_sim.native.fused`'s interface
    (:meth:`fused_step`, :meth:`quiet_periods`, :meth:`ran_periods`, :attr:`framed`).
    """

    def __init__(self, plants: Iterable[Any], *, yields: bool = False) -> None:
        found = [_record(p) for p in plants]
        records = [r for r in found if isinstance(r, NativePlant)]
        if not found or len(records) != len(found):
            raise ValueError("PlantBatch: expected one or more neck_sim.plant.Plant objects")
        if len({id(r) for r in records}) != len(records):
            raise ValueError("PlantBatch: the same plant twice (each run needs its own plant)")
        r0 = records[0]
        backends = [DISPATCH.backend_of(r.address) for r in records]
        for i, r in enumerate(records):
            if (r.substeps, r.timestep, r.n_joints, r.n_cables) != (r0.substeps, r0.timestep, r0.n_joints, r0.n_cables):
                raise ValueError(f"PlantBatch: plant {i} has (sub-steps, timestep, N, m) = "
                                 f"{(r.substeps, r.timestep, r.n_joints, r.n_cables)}, plant 0 "
                                 f"{(r0.substeps, r0.timestep, r0.n_joints, r0.n_cables)}")
            holder = r.state.holder()
            if holder is not None and not holder.yields:
                raise ValueError(f"PlantBatch: plant {i} is already in an open batch")
            if backends[i] != backends[0]:
                raise ValueError(f"PlantBatch: plant {i} runs on the {backends[i]} backend, plant 0 on the "
                                 f"{backends[0]} one; a batch steps with one callback")
        for r in records:
            holder = r.state.holder()
            if holder is not None:
                holder.close()
        K, n, m, nsub = len(records), r0.n_joints, r0.n_cables, r0.substeps
        self.records, self.yields = records, yields
        self.K, self.n, self.m, self.nsub = K, n, m, nsub
        self.dt, self.period = r0.timestep, r0.period
        self._fmax = np.array([r.f_max for r in records], dtype=float)[:, None]     # (K, 1) for broadcasting
        self._delay = np.array([r.delay for r in records], dtype=float)
        self._delayed = np.flatnonzero(self._delay > 0.0)
        # ring buffer of commands: period q's at q % R, enough for every period a delay reaches back to
        self._R = np.array([r.history_length for r in records])
        self.hist = np.zeros((K, int(self._R.max()), m))
        states = [r.state for r in records]
        self.k = np.array([s.k for s in states], dtype=np.int64)
        self.frame_index = np.array([s.frame_index for s in states], dtype=np.int64)
        self.next_cam = np.array([s.next_cam for s in states], dtype=np.int64)
        self.frames: list = [s.frame for s in states]
        for i, s in enumerate(states):
            self.hist[i, : self._R[i]] = s.hist
        self.framed = any(f is not None for f in self.frames)
        self.forces = np.zeros((K, m))
        self.ctrl = np.zeros((K, nsub, m))
        self.capture = np.zeros((K, nsub), dtype=np.int32)
        self.frame_alpha = np.zeros((K, nsub, n))
        self._cols = truth_columns(n, m)
        self.out = np.zeros((K, self._cols["loop_gap"].stop))
        self.fatal = np.zeros(K, dtype=np.int32)
        self._encoders = np.zeros((K, m))
        self.active = np.ones(K, dtype=np.uint8)
        self.errors: list = [None] * K
        for i in range(K):
            self._copy_outputs(i)
        ptrs = lambda values: (ctypes.c_void_p * K)(*values)   # noqa: E731
        self._c_args = (K, ptrs([ctypes.addressof(r.struct) for r in records]), ptrs([r.model._address for r in records]),
                        ptrs([r.data._address for r in records]), self.active.ctypes.data, nsub, m, n)
        self._c_out = (self.frame_alpha.ctypes.data, self.k.ctypes.data, self.out.ctypes.data,
                       self._encoders.ctypes.data, self.fatal.ctypes.data)
        self._c_forces, self._c_ctrl = self.forces.ctypes.data, self.ctrl.ctypes.data
        self._c_capture = self.capture.ctypes.data
        self._cam_lead = self._camera_lead()
        for i, r in enumerate(records):
            r.hold(self, i)
        self._open = True

    # -- state
    @property
    def time(self) -> np.ndarray:
        """(K,) s since each plant's reset."""
        return self.k * self.dt

    def encoders(self) -> np.ndarray:
        """Motor angles theta (K, m) rad, quantised to each plant's encoder resolution (nearest count);
        a buffer the next step overwrites."""
        return self._encoders

    def stop(self, i: int, error: BaseException) -> None:
        """Plant i steps no more; ``errors[i]`` says why."""
        self.errors[i] = error
        self.active[i] = 0
        self.fatal[i] = 0

    def close(self) -> None:
        """Hand the stepping state back to the plants (they can step alone again)."""
        if not self._open:
            return
        self._open = False
        for i, r in enumerate(self.records):
            s = r.state
            if s.holder() is not self:           # reset since (or taken over): its state is newer
                continue
            s.k, s.frame_index, s.next_cam = int(self.k[i]), int(self.frame_index[i]), int(self.next_cam[i])
            s.hist = self.hist[i, : self._R[i]].copy()
            s.frame, s.owner = self.frames[i], None

    def __del__(self) -> None:
        # a batch dropped open hands the state back too (the plants then go on from where it left them)
        if getattr(self, "_open", False):
            self.close()

    def __enter__(self) -> "PlantBatch":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- stepping
    def step(self, forces: ArrayLike) -> list[int]:
        """One control period for the active plants (forces (K, m) N); returns the indices of the
        plants stopped in it (bad forces, diverged simulation), whose errors are in ``errors``."""
        try:
            f = forces if type(forces) is np.ndarray and forces.dtype == np.float64 else np.asarray(forces, dtype=float)
        except (TypeError, ValueError):
            f = None
        if f is None or f.shape != (self.K, self.m):
            raise ValueError(f"forces: expected shape ({self.K}, {self.m}) (one row of cable forces per plant), "
                             f"got {np.shape(forces)}")
        stopped: list[int] = []
        if not math.isfinite(f.sum()):              # one reduction; the rows only when something is off
            ok = np.asarray(np.isfinite(f).all(axis=1))
            for i in np.flatnonzero(~ok & (self.active > 0)):
                self.stop(int(i), ValueError(f"forces: contains NaN or infinity: {f[i].tolist()}"))
                stopped.append(int(i))
            f = np.where(ok[:, None], f, 0.0)
        clip_forces(f, self._fmax, self.forces)
        if self.step_checked():
            stopped += self.stop_diverged()
        return stopped

    def stop_diverged(self) -> list[int]:
        """Stop the active plants whose ``fatal`` is set (their simulation diverged in the period
        just run); returns their indices."""
        stopped = [int(i) for i in np.flatnonzero(self.fatal * self.active)]
        for i in stopped:
            self.stop(i, self.diverged(i))
        return stopped

    # -- periods stepped by a compiled caller (neck_sim.native.fused describes the interface)
    def quiet_periods(self) -> int:
        """How many control periods from now need none of :meth:`step_checked`'s Python: native
        backend, no camera frame due (the delay line is :func:`delayed_controls`, a kernel)."""
        if not self._native:
            return 0
        return max(0, (self._cam_lead - 1) // self.nsub)     # periods whose _cam_lead stays > nsub

    def fused_step(self) -> FusedStep:
        """The C call of one period with no camera capture, for a compiled caller."""
        K, plants, models, datas, active, nsub, m, n = self._c_args
        i32, addr = np.int32, ctypes.addressof
        per_substep = self._delayed.size > 0
        args = (i32(K), addr(plants), addr(models), addr(datas), int(active), i32(nsub), i32(m), i32(n),
                int(self._c_ctrl if per_substep else self._c_forces), i32(per_substep), 0,
                *(int(a) for a in self._c_out))
        address = (ctypes.cast(_library().step_batch, ctypes.c_void_p).value or 0) if self._native else 0
        delay_line = (self.k, self.hist, self._R, self._delay, self.dt, self.period, self.ctrl)
        return FusedStep(address=address, args=args, f_max=self._fmax, forces=self.forces, delay_line=delay_line,
                         delayed=per_substep, encoders=self._encoders, out=self.out)

    def ran_periods(self, count: int) -> None:
        """Bookkeeping of :meth:`step_checked` after ``count`` periods stepped through
        :meth:`fused_step` (at most :meth:`quiet_periods`)."""
        if count > 0 and self.framed:
            self.frames = [None] * self.K
            self.framed = False
        self._cam_lead -= count * self.nsub

    def step_checked(self) -> int:
        """One control period with ``self.forces`` (K, m) already clipped; returns how many plants
        have ``fatal`` set (their simulation diverged)."""
        nsub, k0 = self.nsub, self.k
        per_substep = self._delayed.size > 0
        if per_substep:
            delayed_controls(k0, self.forces, self.hist, self._R, self._delay, self.dt, self.period, self.ctrl)
        if self.framed:
            self.frames = [None] * self.K
            self.framed = False
        due = None
        if self._cam_lead <= nsub:               # some plant may take a camera frame in this period
            due = np.flatnonzero((self.next_cam <= k0 + nsub) & (self.active > 0))
            start = k0.copy()
            self._schedule_frames(due, start)
        if self._native:
            previous = DISPATCH.enter("native")
            try:
                fatal = _library().step_batch(*self._c_args, self._c_ctrl if per_substep else self._c_forces,
                                                int(per_substep), self._c_capture if due is not None else None,
                                                *self._c_out)
            finally:
                DISPATCH.leave(previous)
            if fatal < 0:
                raise RuntimeError("PlantBatch: a plant's sizes changed (C struct disagrees with N, m)")
        else:
            fatal = self._step_python(per_substep, due is not None)
        if due is None:
            self._cam_lead -= nsub
        else:
            self._take_frames(due, start)
            self._cam_lead = self._camera_lead()
        return fatal

    @property
    def _native(self) -> bool:
        """The batch's plants step with the C callback (``set_backend`` may move them)."""
        return DISPATCH.backend_of(self.records[0].address) == "native"

    def _camera_lead(self) -> int:
        """Sub-steps until the first active plant's next camera frame."""
        lead = (self.next_cam - self.k)[self.active > 0]
        return int(lead.min()) if lead.size else 1 << 62

    def _schedule_frames(self, due: np.ndarray, k0: np.ndarray) -> None:
        """capture (K, n_sub): frames due at the end of each sub-step (a frame already late is taken
        at the end of the first one); advances the camera schedule of the plants in ``due``."""
        self.capture[:] = 0
        for i in due:
            record, start = self.records[i], int(k0[i])
            while self.next_cam[i] <= start + self.nsub:
                self.capture[i, max(int(self.next_cam[i]) - start, 1) - 1] += 1
                self.frame_index[i] += 1
                self.next_cam[i] = record.camera_step(int(self.frame_index[i]))

    def _take_frames(self, due: np.ndarray, start: np.ndarray) -> None:
        """Camera frames of this period, each with its own draw of the plant's seeded noise."""
        for i in due:
            record = self.records[i]
            rng, noise = record.state.rng, record.params.sensors.camera_noise
            frame = None
            for s in np.flatnonzero(self.capture[i]):
                t = (int(start[i]) + int(s) + 1) * self.dt + record.camera_delay
                alpha = self.frame_alpha[i, s]
                for _ in range(int(self.capture[i, s])):
                    frame = (t, alpha + rng.normal(0.0, noise, alpha.shape))
            self.frames[i] = frame
        self.framed = True

    def _step_python(self, per_substep: bool, capture: bool) -> int:
        """The C loop of ``neck_step_batch`` with the Python callback."""
        rows = np.flatnonzero(self.active)
        previous = DISPATCH.enter("python")
        try:
            step_period(self.records, rows, self.nsub, self.ctrl if per_substep else self.forces, per_substep,
                        self.capture if capture else None, self.frame_alpha)
        finally:
            DISPATCH.leave(previous)
        for i in rows:
            self.k[i] += self.nsub
            self._copy_outputs(int(i))
            self.fatal[i] = any(w.number for w in self.records[i].fatal_warnings)
        return int(self.fatal[self.active > 0].sum())

    def _copy_outputs(self, i: int) -> None:
        """Plant i's outputs (its struct's) into row i of ``out`` and its encoder reading (the C loop's own copy)."""
        r, o, c = self.records[i], self.out[i], self._cols
        out, struct = r.outputs, r.struct
        quantise(out.theta, struct.inv_res, struct.res, self._encoders[i])
        o[c["theta"]], o[c["alpha"]], o[c["alpha_dot"]] = out.theta, out.alpha, out.alpha_dot
        o[c["tension"]], o[c["elongation"]], o[c["loop_gap"]] = out.tension, out.elongation, struct.loop_gap

    def diverged(self, i: int) -> PlantDivergedError:
        """The error of plant i, whose simulation diverged in the period just run."""
        r = self.records[i]
        said = last_warning()
        return PlantDivergedError(
            f"plant: the simulation diverged during the control period ending at t = {self.k[i] * self.dt:.4f} s "
            f"(MuJoCo reported a singular inertia or a NaN/huge state or acceleration); the commanded "
            f"forces {np.array2string(self.forces[i], precision=1)} N or the parameters drive the neck out of its "
            f"valid range (|alpha| < {r.params.geometry.alpha_max:.3g} rad). Call reset() to go on."
            + (f" MuJoCo said: {said}" if said else ""))
