"""Re-simulate a logged run open loop and measure how far the new run drifts (``neck-sim replay``).

The plant is rebuilt from the log's ``run`` record (plant parameters, effects, seed, timestep,
rigid cables: a :class:`neck_sim.plant_spec.PlantSpec`; nominal ``neck`` constants and no effects
when the record lacks them), reset to the logged initial pose (``/neck/truth`` alpha at the first
sample, else the first camera frame), and driven with the logged commanded forces, one control
period per ``/neck/motors`` sample.  Before each step the replayed encoders and true joint angles
are compared with the logged ones at the same time: an identical plant reproduces the run to
floating-point tolerance; a changed plant parameter shows up as a measured drift.
"""

from __future__ import annotations

import contextlib
import math
import os
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from neck_sim.effects import Effects
from neck_sim.logs import Log, LogWriter, read_log
from neck_sim.params import NeckParams, ParameterError
from neck_sim.plant_spec import PlantSpec
from neck_sim.recorder import Recorder

if TYPE_CHECKING:                     # the plant module loads MuJoCo: imported when a plant is built
    from neck_sim.plant import Plant

__all__ = ["plant_run_info", "plant_from_log", "plant_spec_from_log", "replay", "ReplayResult"]


def plant_run_info(plant: Plant) -> dict:
    """Run metadata that lets :func:`replay` rebuild ``plant`` exactly (pass it to LogWriter's
    ``run_info``): :meth:`PlantSpec.to_record` of the plant's spec."""
    return PlantSpec.of(plant).to_record()


def plant_from_log(log: Log, *, params: NeckParams | None = None, effects: Effects | None = None,
                   seed: int | None = None, changes: dict | None = None,
                   backend: str | None = None) -> tuple[Plant, list[str]]:
    """The plant that produced ``log`` (from its ``run`` record), optionally changed.

    ``params``/``effects``/``seed`` replace the recorded ones; ``changes`` are dotted parameter
    changes applied on top (``{"friction.c_s": 0.6}``).  Returns (plant, notes) where notes list
    what had to be assumed.
    """
    spec, notes = plant_spec_from_log(log, params=params, effects=effects, seed=seed, changes=changes,
                                      backend=backend)
    return spec.build(), notes


def plant_spec_from_log(log: Log, *, params: NeckParams | None = None, effects: Effects | None = None,
                        seed: int | None = None, changes: dict | None = None,
                        backend: str | None = None) -> tuple[PlantSpec, list[str]]:
    """(:class:`PlantSpec`, notes) of :func:`plant_from_log`, before the plant is built."""
    given = {name: value for name, value in (("params", params), ("effects", effects), ("seed", seed))
             if value is not None}
    # a replaced entry is not read from the record at all (a malformed one must not stop the replay)
    skip = {{"params": "plant_params"}.get(name, name) for name in given}
    record = {key: value for key, value in log.run_info.items() if key not in skip}
    spec, assumed = PlantSpec.read_record(record, nominal=log.params)
    spec = spec.replace(backend=backend, **given)
    p = spec.params
    if (p.n_joints, p.n_cables) != (log.params.n_joints, log.params.n_cables):
        raise ParameterError(f"params: the parameter file describes a neck of N = {p.n_joints} joints and "
                             f"{p.n_cables} cables but the log {log.path} was recorded with N = "
                             f"{log.params.n_joints} and {log.params.n_cables} cables")
    if changes:
        spec = spec.replace(params=p.replace(**changes))
    return spec, [text for name, text in assumed.items() if name not in given]


@dataclass(frozen=True)
class ReplayResult:
    """Replayed vs logged signals at the logged motor times (T samples).

    theta/theta_log (T, m) rad: encoders; alpha/alpha_log (T, N) rad: true joint angles
    (alpha_log is None when the log has no truth).  ``notes``: assumptions made.
    """

    t: np.ndarray
    theta: np.ndarray
    theta_log: np.ndarray
    alpha: np.ndarray
    alpha_log: np.ndarray | None
    encoder_resolution: float
    notes: tuple[str, ...]
    output: str | None

    @property
    def theta_drift(self) -> np.ndarray:
        return self.theta - self.theta_log

    @property
    def alpha_drift(self) -> np.ndarray | None:
        return None if self.alpha_log is None else self.alpha - self.alpha_log

    def max_theta_drift(self) -> np.ndarray:
        """Per motor, max |theta - theta_log| (rad)."""
        return np.abs(self.theta_drift).max(axis=0)

    def max_alpha_drift(self) -> np.ndarray | None:
        """Per joint, max |alpha - alpha_log| (rad), None without truth."""
        d = self.alpha_drift
        return None if d is None else np.abs(d).max(axis=0)

    def table(self) -> str:
        rows = [("quantity", "max |drift|", "rms", "at end", "max at t (s)")]
        d = self.theta_drift
        res = self.encoder_resolution
        for j in range(d.shape[1]):
            i = int(np.abs(d[:, j]).argmax())
            rows.append((f"theta{j + 1} (encoder counts)", f"{np.abs(d[:, j]).max() / res:.3g}",
                         f"{np.sqrt(np.mean(d[:, j] ** 2)) / res:.3g}", f"{d[-1, j] / res:.3g}", f"{self.t[i]:.3f}"))
        a = self.alpha_drift
        if a is not None:
            for j in range(a.shape[1]):
                i = int(np.abs(a[:, j]).argmax())
                rows.append((f"alpha{j + 1} (deg)", f"{math.degrees(np.abs(a[:, j]).max()):.3g}",
                             f"{math.degrees(np.sqrt(np.mean(a[:, j] ** 2))):.3g}",
                             f"{math.degrees(a[-1, j]):.3g}", f"{self.t[i]:.3f}"))
        widths = [max(len(r[c]) for r in rows) for c in range(len(rows[0]))]
        lines = ["  ".join(cell.rjust(w) if c else cell.ljust(w) for c, (cell, w) in enumerate(zip(r, widths)))
                 for r in rows]
        return "\n".join([lines[0], "-" * len(lines[0])] + lines[1:])


def replay(log: Log | str | os.PathLike, *, params: NeckParams | None = None, effects: Effects | None = None,
           seed: int | None = None, changes: dict | None = None, output: str | os.PathLike | None = None, progress: bool = False,
           backend: str | None = None, accept_out_of_range_forces: bool = False) -> ReplayResult:
    """Re-run the logged commanded forces open loop on the (possibly changed) plant.

    ``output``: path of an MCAP of the replay (motors with the replayed encoders and the logged
    forces, camera, truth).  Raises ValueError when the log cannot be replayed (no motors, motor
    samples not at the plant's control period, no initial pose).  A log path is read with
    :func:`read_log` (forces outside [0, f_max] refused unless ``accept_out_of_range_forces``);
    forces the plant clips are counted in ``notes``: never clipped silently.
    """
    if not isinstance(log, Log):
        log = read_log(log, topics=("motors", "truth", "camera"), accept_out_of_range_forces=accept_out_of_range_forces)
    plant, notes = plant_from_log(log, params=params, effects=effects, seed=seed, changes=changes, backend=backend)
    notes += list(log.warnings)
    m = log.motors
    if m is None:
        raise ValueError(f"{log.path}: no /neck/motors: nothing to replay")
    if len(m.t) < 2:
        raise ValueError(f"{log.path}: /neck/motors has {len(m.t)} sample(s): nothing to replay")
    period = plant.period
    steps = np.diff(m.t)
    bad = np.flatnonzero(np.abs(steps - period) > 1e-6 * period + 1e-9)
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"{log.path}: /neck/motors samples must be one control period ({period} s) apart to be "
                         f"replayed; t = {m.t[i]!r} -> {m.t[i + 1]!r} s")
    f_max = plant.params.actuation.f_max
    clipped = (m.force < 0) | (m.force > f_max)
    if clipped.any():
        notes.append(f"{int(clipped.any(axis=1).sum())} of {len(m.t)} logged force samples lie outside the plant's "
                     f"[0, f_max] = [0, {f_max:g}] N and were clipped to it (largest excess "
                     f"{float(np.max(np.maximum(-m.force, m.force - f_max))):.4g} N): the drift includes that change")
    if abs(m.t[0]) > 1e-9:
        notes.append(f"log starts at t = {m.t[0]:.6f} s: the replay starts there at plant time 0")
    if log.truth is not None and len(log.truth.t):
        alpha0 = log.truth.alpha[0]
        alpha_log = _at_times(log.truth.t, log.truth.alpha, m.t)
    elif log.camera is not None and len(log.camera.t):
        alpha0 = log.camera.alpha[0]
        alpha_log = None
        notes.append("no /neck/truth: initial pose from the first camera frame, alpha drift not measured")
    else:
        raise ValueError(f"{log.path}: no /neck/truth or /neck/camera to take the initial pose from")
    plant.reset(alpha0=alpha0)

    n_steps = len(m.t)
    rec = Recorder(plant.n_joints, plant.params.n_cables, n_steps)
    # opened before the run: a log that cannot be written fails before the simulation, not after it
    recording = contextlib.nullcontext() if output is None else LogWriter(
        output, log.params, mjcf_xml=plant.xml, run_info={"replay_of": os.path.abspath(log.path),
                                                          **plant_run_info(plant)})
    from tqdm.auto import tqdm
    with recording as writer:
        for k in tqdm(range(n_steps), desc="replay", unit="step", disable=not progress, mininterval=0.5):
            rec.sample(k, m.t[0] + plant.time, plant.encoders(), m.force[k], plant.truth())
            plant.step(m.force[k])
            rec.frame(plant.camera_frame(), offset=m.t[0])
        if writer is not None:
            rec.write(writer)
    theta, alpha = rec.theta[0], np.ascontiguousarray(rec.truth_column("alpha"))
    return ReplayResult(m.t, theta, m.theta, alpha, alpha_log, plant.params.sensors.encoder_resolution,
                        tuple(notes), None if output is None else os.fspath(output))


def _at_times(t_src: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray | None:
    """values at the times t (exact sample matches within 1 us), None when they do not all match."""
    idx = np.clip(np.searchsorted(t_src, t - 1e-6), 0, len(t_src) - 1)
    if not np.all(np.abs(t_src[idx] - t) <= 1e-6):
        return None
    return values[idx]
