"""The output-error problem: experiments, the parameter vector and the noise-weighted residuals.

A :class:`Measured` is one log's measured topics: the commanded forces that drive the
re-simulation, the encoders and the camera frames the simulation is compared with.  A
:class:`Layout` maps a parameter vector x to the plant: per cable f_s (eq 37), k, lambda, c_a
(eq 54), and the magnitudes of an extended model's effects.  :func:`residuals` stacks, per
experiment,

* encoder increments from the first sample, (theta_sim - theta_sim(0)) - (theta - theta(0)),
  divided by the quantisation noise res / sqrt(12) rad (res = 2 pi / counts per turn);
* camera angles, alpha_sim at the frame times - alpha_camera, divided by ``sensors.camera_noise``.

On the true plant each weighted residual has unit variance, so the cost per signal is about the
number of its samples: :mod:`identification.output_error.misfit` checks that.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from identification.diagnosis import columns as effect_columns
from identification.output_error.rollouts import Experiment
from neck_sim.params import NeckParams, to_dict

__all__ = ["Measured", "Layout", "noise_sigmas", "residuals", "residual_samples", "SIGNALS", "same_neck"]

#: The per-cable groups of the base model: (symbol, unit, NeckParams field, lower bound).
GROUPS = (("f_s", "N", ("friction", "f_s"), 0.0), ("k", "N/m", ("cables", "k"), 1.0),
          ("lambda", "1/m", ("cables", "lam"), 0.0), ("c_a", "N s/m", ("cables", "c_a"), 0.0))
SIGNALS = ("encoders", "camera")


def noise_sigmas(params: NeckParams) -> dict:
    """Measurement noise per signal (rad): encoder quantisation res / sqrt(12), camera noise."""
    return {"encoders": params.sensors.encoder_resolution / math.sqrt(12.0),
            "camera": float(params.sensors.camera_noise)}


@dataclass(frozen=True, eq=False)
class Measured:
    """One log: what the plant replays (``replay``, a :class:`rollouts.Experiment`: forces,
    control period, camera frame times since the first motor sample, start pose) and what it is
    compared with: ``theta`` (T, m) rad encoders and ``camera_alpha`` (F, N) rad frames;
    ``start_pose`` says where the start pose came from ("reference": the log's first
    /neck/reference pose, the closed loop starts there; "straight": no reference, and the first
    frames are consistent with the straight pose; "camera": their mean)."""

    replay: Experiment
    theta: np.ndarray
    camera_alpha: np.ndarray
    start_pose: str

    @property
    def name(self) -> str:
        return self.replay.name

    @classmethod
    def from_log(cls, log, params: NeckParams, *, name: str | None = None, start_window_s: float = 0.1):
        """From a :class:`neck_sim.logs.Log` with motors and camera; ValueError naming the problem."""
        name = name or str(getattr(log, "path", "log"))
        m, cam = log.motors, log.camera
        if cam is None or cam.t.size == 0:
            raise ValueError(f"{name}: no /neck/camera frames; output-error fits compare the camera angles")
        if m.theta.shape[1] != params.n_cables or cam.alpha.shape[1] != params.n_joints:
            raise ValueError(f"{name}: {m.theta.shape[1]} motors and {cam.alpha.shape[1]} joint angles, but the "
                             f"model has {params.n_cables} cables and {params.n_joints} joints")
        period = 1.0 / params.control.rate_hz
        dt = np.diff(m.t)
        if dt.size == 0 or np.max(np.abs(dt - period)) > 1e-3 * period:
            raise ValueError(f"{name}: motor samples every {np.median(dt) if dt.size else float('nan'):.6g} s "
                             f"(not uniformly), but re-simulation needs one per control period "
                             f"({period:.6g} s, control.rate_hz)")
        tc = cam.t - m.t[0]
        inside = (tc > 0) & (tc <= m.t.size * period)
        if not inside.any():
            raise ValueError(f"{name}: no camera frame inside the motor samples' time span")
        ref = getattr(log, "reference", None)
        if ref is not None and ref.t.size:
            alpha0, how = np.asarray(ref.alpha_d[0], float), "reference"
        else:
            first = tc[inside] <= start_window_s
            first[0] = True
            alpha0 = cam.alpha[inside][first].mean(axis=0)
            # an open-loop re-simulation is sensitive to its start pose (0.1 deg at the base joint:
            # 0.06 rad of encoder drift after 5 s); runs start straight (paper §6), so frames
            # consistent with that (within 3 standard errors) start it exactly there
            se = params.sensors.camera_noise / np.sqrt(first.sum())
            how = "straight" if np.all(np.abs(alpha0) <= 3.0 * se) else "camera"
            alpha0 = np.zeros_like(alpha0) if how == "straight" else alpha0
        replay = Experiment(np.asarray(m.force, float), period, tc[inside], alpha0, name=name)
        return cls(replay, np.asarray(m.theta, float), np.asarray(cam.alpha[inside], float), how)

    @property
    def n_samples(self) -> dict:
        return {"encoders": self.theta.size, "camera": self.camera_alpha.size}

    @property
    def duration_s(self) -> float:
        return self.replay.n_periods * self.replay.period



def same_neck(params: NeckParams, other: NeckParams, name: str, first: str) -> None:
    """ValueError naming the first field where ``other`` (log ``name``) differs from ``params``
    (log ``first``): one parameter set is fitted to logs of one neck."""
    a, b = to_dict(params), to_dict(other)
    for section in a:
        if a[section] != b.get(section):
            key = next((k for k in a[section] if a[section][k] != (b.get(section) or {}).get(k)), "")
            raise ValueError(f"{name}: a different neck from {first} ({section}.{key} differs); "
                             "fit one neck's logs together")


@dataclass(frozen=True, eq=False)
class Layout:
    """The fitted parameters: ``names`` like "k(2)" or "viscous_friction.c_v(1)", ``units``,
    box ``lower``/``upper``, over the nominal ``params`` and ``effects`` (an extended model)."""

    names: tuple
    units: tuple
    lower: np.ndarray
    upper: np.ndarray
    params: NeckParams
    effects: object = None
    _slots: tuple = ()         # (kind, key, index): kind "base" (section, field) or "effect" (name, field)

    @classmethod
    def of(cls, params: NeckParams, effects=None) -> "Layout":
        """f_s, k, lambda, c_a per cable, then every active effect's magnitude per affected cable."""
        m = params.n_cables
        names, units, lower, slots = [], [], [], []
        for sym, unit, key, lo in GROUPS:
            for j in range(m):
                names.append(f"{sym}({j + 1})"), units.append(unit), lower.append(lo), slots.append(("base", key, j))
        for e in (effects.active() if effects is not None else ()):
            fld = e.magnitude_field
            value = getattr(e, fld, None) if fld else None
            if value is None or e.baseline:
                continue
            fitted = effect_columns.get(e.name).columns if e.name in effect_columns.names() else ()
            col = next((c for c in fitted if c.symbol == fld), None)
            unit, lo = (col.unit, 0.0 if col.signed else -np.inf) if col is not None else ("", -np.inf)
            cables = getattr(e, "cables", None)
            if isinstance(value, tuple):
                idx = list(cables) if cables is not None else list(range(len(value)))
                for i, j in enumerate(idx):
                    names.append(f"{e.name}.{fld}({j + 1})"), slots.append(("effect", (e.name, fld), i))
                    units.append(unit), lower.append(lo)
            else:
                names.append(f"{e.name}.{fld}"), units.append(unit), lower.append(lo)
                slots.append(("effect", (e.name, fld), None))
        p = len(names)
        return cls(tuple(names), tuple(units), np.array(lower, float), np.full(p, np.inf), params, effects,
                   tuple(slots))

    def vector(self) -> np.ndarray:
        """x of the nominal params and effects."""
        x = np.empty(len(self.names))
        for i, (kind, key, j) in enumerate(self._slots):
            if kind == "base":
                x[i] = getattr(getattr(self.params, key[0]), key[1])[j]
            else:
                v = getattr(getattr(self.effects, key[0]), key[1])
                x[i] = v if j is None else v[j]
        return x

    def plant(self, x) -> tuple:
        """(NeckParams, Effects) of the vector x; ValueError if they are not valid plant constants."""
        x = np.asarray(x, dtype=float)
        base = {}
        effects = {}
        for v, (kind, key, j) in zip(x, self._slots):
            if kind == "base":
                base.setdefault(key, list(getattr(getattr(self.params, key[0]), key[1])))[j] = float(v)
            else:
                cur = effects.get(key, getattr(getattr(self.effects, key[0]), key[1]))
                effects[key] = float(v) if j is None else tuple(float(v) if i == j else c for i, c in enumerate(cur))
        sections = {}
        for (sec, fld), vals in base.items():
            sections.setdefault(sec, {})[fld] = tuple(vals)
        params = replace(self.params, **{sec: replace(getattr(self.params, sec), **f) for sec, f in sections.items()})
        effs = self.effects
        if effects:
            by_name = {}
            for (name, fld), v in effects.items():
                by_name.setdefault(name, {})[fld] = v
            effs = effs.replace(**{name: replace(getattr(effs, name), **f) for name, f in by_name.items()})
        return params, effs

    def group(self, x, symbol: str) -> np.ndarray:
        """Values of the parameters named ``symbol(i)``, in cable order."""
        return np.asarray(x)[[i for i, n in enumerate(self.names) if n.split("(")[0] == symbol]]


def residual_samples(measured) -> tuple[np.ndarray, int]:
    """(rows, n): the motor-sample index of every residual in :func:`residuals`' order (encoders
    of every log, then camera frames of every log, each frame at the sample it falls in), the
    logs' samples numbered one after the other; n their total."""
    enc, cam, offset = [], [], 0
    for meas in measured:
        T, m = meas.theta.shape
        enc.append(np.repeat(np.arange(T) + offset, m))
        k = np.minimum((meas.replay.camera_t / meas.replay.period).astype(int), T - 1)
        cam.append(np.repeat(k + offset, meas.camera_alpha.shape[1]))
        offset += T
    return np.concatenate(enc + cam), offset


def residuals(measured, runs, sigmas: dict) -> dict:
    """Weighted residuals per signal, {"encoders": (sum T m,), "camera": (sum F N,)}, of ``runs``
    (per log: simulated motor angles (T, m) and camera-frame angles (F, N)); NaN where a run
    diverged.  Encoders compare increments from the first sample (a log's encoders start at 0)."""
    enc_r, cam_r = [], []
    for meas, (theta, alpha) in zip(measured, runs):
        enc_r.append((((theta - theta[0]) - (meas.theta - meas.theta[0])) / sigmas["encoders"]).ravel())
        cam_r.append(((alpha - meas.camera_alpha) / sigmas["camera"]).ravel())
    return {"encoders": np.concatenate(enc_r), "camera": np.concatenate(cam_r)}
