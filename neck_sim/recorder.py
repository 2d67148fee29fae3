"""One recorder for every loop that drives a plant, and the one path from its arrays to the log.

    from neck_sim.recorder import Recorder
    rec = Recorder(plant.params.n_joints, plant.params.n_cables, steps)
    for k in range(steps):
        rec.sample(k, k * plant.period, plant.encoders(), force, plant.truth())   # before the step
        plant.step(force)
        rec.frame(plant.camera_frame())
    rec.write_log(path, plant.params, mjcf_xml=plant.xml, run_info=PlantSpec.of(plant).to_record())

A :class:`Recorder` holds the arrays of K runs (``runs``) of T control periods: sample times
``t`` (K, T) s, encoders ``theta`` and commanded forces ``force`` (K, T, m), the simulation truth
``truth`` (K, T, 3m + 2N + 1) in the column layout of :func:`neck_sim.batch.truth_columns` (the
rows :attr:`neck_sim.batch.PlantBatch.out` holds, so a batch loop copies them whole), and, when
asked for, the reference ``alpha_d`` and the estimate ``alpha_hat`` (K, T, N) rad; camera frames
(t s, alpha (N,) rad) per run.  Rows not sampled stay NaN.  A loop that does not know its length
(an environment episode) appends; the arrays then grow (reallocated: hold no views across samples).

:meth:`Recorder.topics` says which arrays go to which contract topic, and :meth:`Recorder.write`
hands them, in bulk, to :meth:`neck_sim.logs.LogWriter.write_batch` (or to a
:class:`neck_sim.live.LiveView`, which takes the same call): the one way a simulated run reaches
the log topics.
"""

from __future__ import annotations

import os
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike

from neck_sim.batch import truth_columns
from neck_sim.params import NeckParams

__all__ = ["Recorder", "TOPIC_ORDER"]

TOPIC_ORDER = ("motors", "reference", "estimate", "truth", "camera")
"""The order in which :meth:`Recorder.write` hands topics to a writer."""

_TRUTH_FIELDS = ("alpha", "alpha_dot", "tension", "elongation")    # /neck/truth's fields, contract order


class _TopicSink(Protocol):
    """What :meth:`Recorder.write` hands topics to (a LogWriter, a LiveView)."""

    def write_batch(self, name: str, t: ArrayLike, *fields: ArrayLike) -> None: ...


class Recorder:
    """Arrays of ``runs`` runs of ``steps`` control periods of a neck with N = ``n_joints`` joints
    and m = ``n_cables`` cables (see the module docstring).

    ``truth``: record the simulation truth (``/neck/truth``); ``reference``, ``estimate``: record
    alpha_d and alpha_hat (``/neck/reference``, ``/neck/estimate``).  ``length`` is the number of
    rows of the record: ``steps``, or more once a sample lands beyond it.
    """

    def __init__(self, n_joints: int, n_cables: int, steps: int = 0, *, runs: int = 1, truth: bool = True,
                 reference: bool = False, estimate: bool = False) -> None:
        n, m, steps, runs = int(n_joints), int(n_cables), int(steps), int(runs)
        if n < 1 or m < 1 or steps < 0 or runs < 1:
            raise ValueError(f"Recorder: expected n_joints, n_cables, runs >= 1 and steps >= 0, got "
                             f"{n_joints}, {n_cables}, {runs} and {steps}")
        self.n_joints, self.n_cables, self.runs = n, m, runs
        self.columns = truth_columns(n, m)
        self._widths = {"t": (), "theta": (m,), "force": (m,)}
        if truth:
            self._widths["truth"] = (self.columns["loop_gap"].stop,)
        if reference:
            self._widths["alpha_d"] = (n,)
        if estimate:
            self._widths["alpha_hat"] = (n,)
        self.length = 0
        self._capacity = 0
        # t, theta and force always exist (empty until _grow); the others only when asked for
        self.t, self.theta, self.force = (np.empty((runs, 0, *self._widths[name])) for name in ("t", "theta", "force"))
        self.truth: np.ndarray | None = None
        self.alpha_d: np.ndarray | None = None
        self.alpha_hat: np.ndarray | None = None
        self._grow(steps)
        self.length = steps
        self.camera_t: list[list[float]] = [[] for _ in range(runs)]
        self.camera_alpha: list[list[np.ndarray]] = [[] for _ in range(runs)]

    # -- recording -----------------------------------------------------------------------------
    def sample(self, k: int, t: float, theta: ArrayLike, force: ArrayLike | None = None, truth: object | None = None,
               *, run: int = 0, alpha_d: ArrayLike | None = None, alpha_hat: ArrayLike | None = None) -> None:
        """Row k of run ``run``: time t (s), encoders theta (m,) rad, commanded force (m,) N, the
        truth (a :class:`neck_sim.plant.Truth`, or anything with its fields), alpha_d and
        alpha_hat (N,) rad.  Arguments left None leave their columns as they were; alpha_d or
        alpha_hat given to a record not asked for them is a ValueError."""
        if alpha_d is not None and self.alpha_d is None:
            raise ValueError("Recorder: alpha_d given but this record has no reference (Recorder(..., reference=True))")
        if alpha_hat is not None and self.alpha_hat is None:
            raise ValueError("Recorder: alpha_hat given but this record has no estimate (Recorder(..., estimate=True))")
        if k >= self._capacity:
            self._grow(max(k + 1, 2 * self._capacity))
        self.length = max(self.length, k + 1)
        self.t[run, k] = t
        self.theta[run, k] = theta
        if force is not None:
            self.force[run, k] = force
        if truth is not None and self.truth is not None:
            row = self.truth[run, k]
            for name, sl in self.columns.items():
                row[sl] = getattr(truth, name)
        if alpha_d is not None and self.alpha_d is not None:
            self.alpha_d[run, k] = alpha_d
        if alpha_hat is not None and self.alpha_hat is not None:
            self.alpha_hat[run, k] = alpha_hat

    def append(self, t: float, theta: ArrayLike, force: ArrayLike | None = None, truth: object | None = None, *,
               alpha_d: ArrayLike | None = None, alpha_hat: ArrayLike | None = None) -> int:
        """:meth:`sample` at the next row (``length``) of run 0; returns that row's index."""
        k = self.length
        self.sample(k, t, theta, force, truth, alpha_d=alpha_d, alpha_hat=alpha_hat)
        return k

    def frame(self, frame: tuple[float, ArrayLike] | None, *, run: int = 0, offset: float = 0.0) -> None:
        """A camera frame (t s, alpha (N,) rad), stamped ``offset + t``; None (no frame) is ignored."""
        if frame is not None:
            self.camera_t[run].append(offset + frame[0])
            self.camera_alpha[run].append(np.array(frame[1], dtype=float))

    # -- reading -------------------------------------------------------------------------------
    def truth_column(self, name: str, run: int = 0) -> np.ndarray:
        """Truth column(s) ``name`` of :func:`neck_sim.batch.truth_columns` over the record's rows:
        (T, width), or (T,) for ``loop_gap``; a view."""
        if self.truth is None:
            raise ValueError("Recorder: this record has no truth (Recorder(..., truth=False))")
        if name not in self.columns:
            raise ValueError(f"truth column {name!r}: expected one of {', '.join(self.columns)}")
        col = self.truth[run, :self.length, self.columns[name]]
        return col[:, 0] if name == "loop_gap" else col

    def camera(self, run: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Camera frames of run ``run``: times (F,) s and angles (F, N) rad."""
        return (np.asarray(self.camera_t[run], dtype=float).reshape(-1),
                np.asarray(self.camera_alpha[run], dtype=float).reshape(-1, self.n_joints))

    def topics(self, run: int = 0, *, rows: slice | None = None,
               frames: slice | None = None) -> dict[str, tuple[np.ndarray, ...]]:
        """Contract topic name -> (t, *fields) arrays of run ``run`` in contract field order, for
        the topics this record holds (order :data:`TOPIC_ORDER`); ``rows`` (default every row)
        and ``frames`` (default every camera frame) select a part."""
        rows = slice(0, self.length) if rows is None else rows
        t = self.t[run, rows]
        out: dict[str, tuple[np.ndarray, ...]] = {"motors": (t, self.theta[run, rows], self.force[run, rows])}
        if self.alpha_d is not None:
            out["reference"] = (t, self.alpha_d[run, rows])
        if self.alpha_hat is not None:
            out["estimate"] = (t, self.alpha_hat[run, rows])
        if self.truth is not None:
            truth = self.truth[run, rows]
            out["truth"] = (t, *(truth[:, self.columns[name]] for name in _TRUTH_FIELDS))
        frames = slice(None) if frames is None else frames
        out["camera"] = (np.asarray(self.camera_t[run][frames], dtype=float).reshape(-1),
                         np.asarray(self.camera_alpha[run][frames], dtype=float).reshape(-1, self.n_joints))
        return out

    # -- writing -------------------------------------------------------------------------------
    def write(self, sink: _TopicSink, run: int = 0, *, rows: slice | None = None, frames: slice | None = None) -> None:
        """Hand run ``run``'s topics (:meth:`topics`) to ``sink``'s ``write_batch`` (a
        :class:`neck_sim.logs.LogWriter` or a :class:`neck_sim.live.LiveView`)."""
        for name, arrays in self.topics(run, rows=rows, frames=frames).items():
            sink.write_batch(name, *arrays)

    def write_log(self, path: str | os.PathLike, params: NeckParams | None, *, run: int = 0,
                  mjcf_xml: str | None = None,
                  run_info: dict | None = None) -> str:
        """Write run ``run`` as the contract log ``path`` (atomic: nothing is left under ``path``
        if writing fails); ``params`` the nominal constants of the ``neck`` record, ``run_info``
        the ``run`` record's entries.  Returns ``path``."""
        from neck_sim.logs import LogWriter

        with LogWriter(path, params, mjcf_xml=mjcf_xml, run_info=run_info) as writer:
            self.write(writer, run)
        return os.fspath(path)

    # -- internals -----------------------------------------------------------------------------
    def _grow(self, capacity: int) -> None:
        """Room for ``capacity`` rows per run; new rows NaN, recorded rows kept."""
        for name, width in self._widths.items():
            new = np.full((self.runs, capacity, *width), np.nan)
            old = getattr(self, name)
            if old is not None:
                new[:, :self.length] = old[:, :self.length]
            setattr(self, name, new)
        self._capacity = capacity
